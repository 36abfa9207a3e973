// Internal to mmval::tracking: a fast reader for the common microscope PNG (8-bit grey,
// RGB or RGBA, not interlaced) straight to the 8-bit grey image that cv::imread +
// toFloatGrey would make of it. zlib's inflate is most of cv::imread's time on such
// frames; libdeflate (https://github.com/ebiggers/libdeflate) inflates the whole image
// data in one call about twice as fast. Anything else (16 bit, palette, transparency
// chunk, interlace, damage) is left to cv::imread.
#pragma once
#include <cstddef>
#include <string>

#include <opencv2/core.hpp>

namespace mmval::tracking::detail {

/// The PNG `file` as CV_8UC1 grey: colour pixels weighted as cv::cvtColor's
/// COLOR_RGB(A)2GRAY does for 8-bit images (OpenCV 4.6), (9798 R + 19235 G + 3735 B +
/// 2^14) >> 15 (ITU-R BT.601 luma in 15-bit fixed point; checked equal on all 2^24
/// colours), so the result equals cv::imread(IMREAD_UNCHANGED) followed by that
/// conversion, pixel for pixel.
/// Returns false, `grey` untouched, when the file is not such a PNG or cannot be read
/// whole (bad CRC, truncated data): the caller reads it with cv::imread, which reports
/// the error. Thread-safe.
bool readPngGrey8(const std::string& file, cv::Mat& grey);

/// The same from the file's bytes in memory. `check_crc` false skips the chunks' CRC
/// check (only for fuzzing, so that mutated inputs reach the decoder; fuzz/PngFuzzer.cpp).
bool decodePngGrey8(const unsigned char* bytes, std::size_t size, cv::Mat& grey, bool check_crc);

}  // namespace mmval::tracking::detail
