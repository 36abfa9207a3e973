// Internal to mmval::tracking: the tracker's pictures (streamlines.png, the speed map,
// the D histogram) written as PNG with libdeflate, the library that already reads its
// frames (PngReader.hpp), so that `mmval track` on an image folder never loads OpenCV's
// codec module (with its ~120 shared libraries, ~0.07 s of the process' start when linked).
#pragma once
#include <string>

#include <opencv2/core.hpp>

namespace mmval::tracking::detail {

/// The PNG file of an 8-bit image: CV_8UC1 as grey, CV_8UC3 (BGR, OpenCV's order) as RGB,
/// CV_8UC4 (BGRA) as RGBA; cv::imread gives the same pixels back. Each row is filtered
/// with the PNG filter (none, sub, up, average, Paeth) of smallest sum of absolute values (the
/// heuristic of the PNG specification, sec. 12.8), deflated at level 6. Throws
/// std::invalid_argument for other types or an empty image.
std::string encodePng(const cv::Mat& image);

}  // namespace mmval::tracking::detail
