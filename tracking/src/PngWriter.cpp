// The PNG format: W3C / ISO/IEC 15948:2004, "Portable Network Graphics (PNG)
// Specification (Second Edition)": chunks sec. 5, IHDR sec. 11.2.2, filters sec. 9,
// filter choice sec. 12.8. Deflated with libdeflate.
#include "PngWriter.hpp"

#include <array>
#include <cstdint>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <vector>

#include <libdeflate.h>

namespace mmval::tracking::detail {

namespace {

void putBigEndian32(std::string& out, std::uint32_t v) {
  out.push_back(static_cast<char>((v >> 24) & 0xff));
  out.push_back(static_cast<char>((v >> 16) & 0xff));
  out.push_back(static_cast<char>((v >> 8) & 0xff));
  out.push_back(static_cast<char>(v & 0xff));
}

/// Length, type, data and the CRC of type and data (sec. 5.3).
void putChunk(std::string& out, const char* type, const unsigned char* data, std::size_t length) {
  putBigEndian32(out, static_cast<std::uint32_t>(length));
  const std::size_t start = out.size();
  out.append(type, 4);
  if (length > 0) out.append(reinterpret_cast<const char*>(data), length);
  putBigEndian32(out, libdeflate_crc32(0, out.data() + start, length + 4));
}

int paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
}

/// Row `row` (n bytes, `bpp` per pixel) filtered with `type` into out[0] = type, out[1..n].
/// Returns the sum of the filtered bytes taken as signed (the choice heuristic).
long filterRow(int type, const unsigned char* row, const unsigned char* prior, std::size_t n, int bpp, unsigned char* out) {
  out[0] = static_cast<unsigned char>(type);
  long cost = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const int a = i >= static_cast<std::size_t>(bpp) ? row[i - bpp] : 0, b = prior[i], c = i >= static_cast<std::size_t>(bpp) ? prior[i - bpp] : 0;
    const int predictor = type == 0 ? 0 : type == 1 ? a : type == 2 ? b : type == 3 ? (a + b) / 2 : paeth(a, b, c);
    const auto v = static_cast<unsigned char>(row[i] - predictor);
    out[i + 1] = v;
    cost += std::abs(static_cast<int>(static_cast<signed char>(v)));
  }
  return cost;
}

struct CompressorDeleter {
  void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
};

}  // namespace

std::string encodePng(const cv::Mat& image) {
  if (image.empty() || image.depth() != CV_8U || image.channels() == 2 || image.channels() > 4)
    throw std::invalid_argument("encodePng: an 8-bit image of 1, 3 or 4 channels");
  const int channels = image.channels();
  const std::size_t width = static_cast<std::size_t>(image.cols), height = static_cast<std::size_t>(image.rows);
  const std::size_t stride = width * static_cast<std::size_t>(channels);
  // Rows in PNG order (RGB / RGBA), each with its filter byte.
  std::vector<unsigned char> raw(height * (stride + 1));
  std::vector<unsigned char> row(stride), prior(stride, 0), trial(stride + 1);
  for (std::size_t y = 0; y < height; ++y) {
    const unsigned char* src = image.ptr<unsigned char>(static_cast<int>(y));
    if (channels == 1) {
      std::copy(src, src + stride, row.begin());
    } else {
      for (std::size_t x = 0; x < width; ++x) {
        const unsigned char* p = src + x * static_cast<std::size_t>(channels);
        unsigned char* q = &row[x * static_cast<std::size_t>(channels)];
        q[0] = p[2];
        q[1] = p[1];
        q[2] = p[0];
        if (channels == 4) q[3] = p[3];
      }
    }
    unsigned char* out = &raw[y * (stride + 1)];
    long best = filterRow(0, row.data(), prior.data(), stride, channels, out);
    for (int type = 1; type <= 4; ++type) {
      const long cost = filterRow(type, row.data(), prior.data(), stride, channels, trial.data());
      if (cost < best) {
        best = cost;
        std::copy(trial.begin(), trial.end(), out);
      }
    }
    prior.swap(row);
  }
  constexpr int kLevel = 6;
  const std::unique_ptr<libdeflate_compressor, CompressorDeleter> deflater(libdeflate_alloc_compressor(kLevel));
  if (!deflater) throw std::bad_alloc();
  std::vector<unsigned char> compressed(libdeflate_zlib_compress_bound(deflater.get(), raw.size()));
  const std::size_t size = libdeflate_zlib_compress(deflater.get(), raw.data(), raw.size(), compressed.data(), compressed.size());
  if (size == 0) throw std::runtime_error("encodePng: deflate failed");
  std::string png("\x89PNG\r\n\x1a\n", 8);
  std::array<unsigned char, 13> header{};
  for (int k = 0; k < 4; ++k) {
    header[static_cast<std::size_t>(k)] = static_cast<unsigned char>((width >> (24 - 8 * k)) & 0xff);
    header[static_cast<std::size_t>(4 + k)] = static_cast<unsigned char>((height >> (24 - 8 * k)) & 0xff);
  }
  header[8] = 8;                                                       // bit depth
  header[9] = channels == 1 ? 0 : channels == 3 ? 2 : 6;               // grey, RGB, RGBA
  header[10] = header[11] = header[12] = 0;                            // deflate, filter method 0, no interlace
  putChunk(png, "IHDR", header.data(), header.size());
  putChunk(png, "IDAT", compressed.data(), size);
  putChunk(png, "IEND", nullptr, 0);
  return png;
}

}  // namespace mmval::tracking::detail
