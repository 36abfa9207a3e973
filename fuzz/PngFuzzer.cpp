// The tracker's own PNG decoder (tracking/src/PngReader.cpp), which reads users' frame
// files before cv::imread does. Run with the chunk CRC check off, so that mutated inputs
// reach the chunk walk, the inflate and the row filters instead of stopping at the first
// CRC. Expected outcome of bad input: false (the caller then asks cv::imread). An image
// that decodes must have the size its IHDR states.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include <opencv2/core.hpp>

#include "PngReader.hpp"

namespace {

std::uint32_t bigEndian32(const std::uint8_t* p) {
  return (static_cast<std::uint32_t>(p[0]) << 24) | (static_cast<std::uint32_t>(p[1]) << 16) | (static_cast<std::uint32_t>(p[2]) << 8) | p[3];
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  for (const bool check_crc : {false, true}) {
    cv::Mat grey;
    if (!mmval::tracking::detail::decodePngGrey8(data, size, grey, check_crc)) continue;
    // Decoded: the IHDR (first chunk, at byte 8) gave width and height.
    const std::uint32_t width = bigEndian32(data + 16), height = bigEndian32(data + 20);
    if (grey.type() != CV_8UC1 || static_cast<std::uint32_t>(grey.cols) != width || static_cast<std::uint32_t>(grey.rows) != height) {
      std::fprintf(stderr, "decoded %d x %d (type %d), IHDR says %u x %u\n", grey.cols, grey.rows, grey.type(), width, height);
      std::abort();
    }
  }
  return 0;
}
