// The PNG format: W3C / ISO/IEC 15948:2004, "Portable Network Graphics (PNG)
// Specification (Second Edition)" (chunks sec. 5, IHDR sec. 11.2.2, filters sec. 9). Inflated with libdeflate.
#include "PngReader.hpp"

#include <bit>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <span>
#include <vector>

#include <libdeflate.h>
#include <opencv2/core/hal/intrin.hpp>

namespace mmval::tracking::detail {

namespace {

std::uint32_t bigEndian32(const unsigned char* p) {
  return (static_cast<std::uint32_t>(p[0]) << 24) | (static_cast<std::uint32_t>(p[1]) << 16) | (static_cast<std::uint32_t>(p[2]) << 8) | p[3];
}

/// Whole file into `bytes`; false when it cannot be read.
bool readFile(const std::string& file, std::vector<unsigned char>& bytes) {
  std::unique_ptr<std::FILE, int (*)(std::FILE*)> f(std::fopen(file.c_str(), "rb"), &std::fclose);
  if (!f || std::fseek(f.get(), 0, SEEK_END) != 0) return false;
  const long size = std::ftell(f.get());
  if (size <= 0 || std::fseek(f.get(), 0, SEEK_SET) != 0) return false;
  bytes.resize(static_cast<std::size_t>(size));
  return std::fread(bytes.data(), 1, bytes.size(), f.get()) == bytes.size();
}

/// Undoes the row's filter (sec. 9.2) in place; `prior` is the previous row unfiltered
/// (zeros for the first), `bpp` bytes per pixel. False for an unknown filter type.
bool unfilter(int type, unsigned char* __restrict row, const unsigned char* __restrict prior, std::size_t n, int bpp) {
  switch (type) {
    case 0:
      return true;
    case 1:
      if (bpp == 4) {
        // Four pixels at a time: a prefix sum of 32-bit lanes with bytewise (wrapping)
        // additions, the last pixel carried to the next four.
        std::size_t i = 0;
        std::uint32_t left = 0;
        if constexpr (std::endian::native == std::endian::little) {
          cv::v_uint8x16 carry = cv::v_setzero_u8();
          for (; i + 16 <= n; i += 16) {
            cv::v_uint8x16 x = cv::v_load(row + i);
            x = cv::v_add_wrap(x, cv::v_reinterpret_as_u8(cv::v_rotate_left<1>(cv::v_reinterpret_as_u32(x))));  // + the pixel before
            x = cv::v_add_wrap(x, cv::v_reinterpret_as_u8(cv::v_rotate_left<2>(cv::v_reinterpret_as_u32(x))));  // + the two before those
            x = cv::v_add_wrap(x, carry);
            cv::v_store(row + i, x);
            carry = cv::v_reinterpret_as_u8(cv::v_setall_u32(cv::v_extract_n<3>(cv::v_reinterpret_as_u32(x))));
          }
          if (i > 0) std::memcpy(&left, row + i - 4, 4);
        }
        // Four bytes at a time, bytewise sums without carries between them (SWAR).
        for (; i + 4 <= n; i += 4) {
          std::uint32_t v;
          std::memcpy(&v, row + i, 4);
          v = ((v & 0x7f7f7f7fu) + (left & 0x7f7f7f7fu)) ^ ((v ^ left) & 0x80808080u);
          std::memcpy(row + i, &v, 4);
          left = v;
        }
        return true;
      }
      for (std::size_t i = static_cast<std::size_t>(bpp); i < n; ++i) row[i] = static_cast<unsigned char>(row[i] + row[i - bpp]);
      return true;
    case 2:
      for (std::size_t i = 0; i < n; ++i) row[i] = static_cast<unsigned char>(row[i] + prior[i]);  // vectorised (restrict)
      return true;
    case 3:
      for (std::size_t i = 0; i < n; ++i) {
        const int left = i >= static_cast<std::size_t>(bpp) ? row[i - bpp] : 0;
        row[i] = static_cast<unsigned char>(row[i] + ((left + prior[i]) >> 1));
      }
      return true;
    case 4:
      for (std::size_t i = 0; i < n; ++i) {
        const bool has_left = i >= static_cast<std::size_t>(bpp);
        const int a = has_left ? row[i - bpp] : 0, b = prior[i], c = has_left ? prior[i - bpp] : 0;
        const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
        const int predictor = pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
        row[i] = static_cast<unsigned char>(row[i] + predictor);
      }
      return true;
    default:
      return false;
  }
}

/// g[x] = the grey of the RGBA pixel px[4x..4x+3] (readPngGrey8's weights), 16 pixels at
/// a time in 32-bit lanes (the same integer arithmetic as the scalar tail).
void greyOfRgba(const unsigned char* __restrict px, unsigned char* __restrict g, std::uint32_t width) {
  std::uint32_t x = 0;
  if constexpr (std::endian::native == std::endian::little) {
    const cv::v_uint32x4 byte = cv::v_setall_u32(0xffu), wr = cv::v_setall_u32(9798u), wg = cv::v_setall_u32(19235u), wb = cv::v_setall_u32(3735u),
                         half = cv::v_setall_u32(1u << 14);
    auto grey4 = [&](const unsigned char* p) {
      const cv::v_uint32x4 v = cv::v_reinterpret_as_u32(cv::v_load(p));
      return ((v & byte) * wr + ((v >> 8) & byte) * wg + ((v >> 16) & byte) * wb + half) >> 15;
    };
    for (; x + 16 <= width; x += 16) {
      const unsigned char* p = px + 4 * static_cast<std::size_t>(x);
      const cv::v_uint16x8 lo = cv::v_pack(grey4(p), grey4(p + 16)), hi = cv::v_pack(grey4(p + 32), grey4(p + 48));
      cv::v_store(g + x, cv::v_pack(lo, hi));
    }
  }
  for (; x < width; ++x) {
    const unsigned char* p = px + 4 * static_cast<std::size_t>(x);
    g[x] = static_cast<unsigned char>((9798u * p[0] + 19235u * p[1] + 3735u * p[2] + (1u << 14)) >> 15);
  }
}

struct DecompressorDeleter {
  void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
};

}  // namespace

bool readPngGrey8(const std::string& file, cv::Mat& grey) {
  thread_local std::vector<unsigned char> bytes;
  return readFile(file, bytes) && decodePngGrey8(bytes.data(), bytes.size(), grey, true);
}

bool decodePngGrey8(const unsigned char* data_begin, std::size_t size, cv::Mat& grey, bool check_crc) {
  thread_local std::vector<unsigned char> compressed, pixels;
  const std::span<const unsigned char> bytes(data_begin, size);
  if (bytes.size() < 8 + 25) return false;
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (std::memcmp(bytes.data(), kSignature, 8) != 0) return false;
  std::uint32_t width = 0, height = 0;
  int channels = 0;
  compressed.clear();
  bool ended = false;
  for (std::size_t p = 8; !ended;) {
    if (p + 12 > bytes.size()) return false;
    const std::uint32_t length = bigEndian32(&bytes[p]);
    if (length > bytes.size() - p - 12) return false;
    const unsigned char* type = &bytes[p + 4];
    const unsigned char* data = type + 4;
    if (check_crc && libdeflate_crc32(0, type, length + 4) != bigEndian32(data + length)) return false;
    if (std::memcmp(type, "IHDR", 4) == 0) {
      if (p != 8 || length != 13) return false;
      width = bigEndian32(data);
      height = bigEndian32(data + 4);
      const int depth = data[8], colour = data[9];
      // Compression 0, filter method 0, no interlace; 8 bits of grey (0), RGB (2) or RGBA (6).
      if (depth != 8 || data[10] != 0 || data[11] != 0 || data[12] != 0) return false;
      channels = colour == 0 ? 1 : colour == 2 ? 3 : colour == 6 ? 4 : 0;
      if (channels == 0) return false;
    } else if (std::memcmp(type, "IDAT", 4) == 0) {
      compressed.insert(compressed.end(), data, data + length);
    } else if (std::memcmp(type, "IEND", 4) == 0) {
      ended = true;
    } else if (std::memcmp(type, "tRNS", 4) == 0 || !(type[0] & 0x20)) {
      return false;  // transparency (imread adds an alpha channel) or another critical chunk
    }
    p += 12 + length;
  }
  if (channels == 0 || width == 0 || height == 0 || compressed.empty()) return false;
  const std::size_t stride = static_cast<std::size_t>(width) * static_cast<std::size_t>(channels);
  const std::size_t expected = static_cast<std::size_t>(height) * (stride + 1);
  if (width > (1u << 20) || height > (1u << 20) || expected > (std::size_t{1} << 31)) return false;
  // DEFLATE cannot expand by more than 1032:1 (a 258-byte match costs at least 2 bits),
  // so a header whose size the image data could never fill is refused here, before the
  // buffer is allocated: a 60-byte file must not make the reader take gigabytes (found by
  // fuzz_png, which ran out of its 4 GB on such headers).
  if (expected / 1032 > compressed.size() + 1) return false;
  if (pixels.size() < expected) pixels.resize(expected);
  thread_local std::unique_ptr<libdeflate_decompressor, DecompressorDeleter> inflater(libdeflate_alloc_decompressor());
  if (!inflater) return false;
  std::size_t produced = 0;
  if (libdeflate_zlib_decompress(inflater.get(), compressed.data(), compressed.size(), pixels.data(), expected, &produced) != LIBDEFLATE_SUCCESS ||
      produced != expected)
    return false;
  cv::Mat out(static_cast<int>(height), static_cast<int>(width), CV_8UC1);
  thread_local std::vector<unsigned char> zeros;
  zeros.assign(stride, 0);
  const unsigned char* prior = zeros.data();
  for (std::uint32_t y = 0; y < height; ++y) {
    unsigned char* row = &pixels[y * (stride + 1)];
    if (!unfilter(row[0], row + 1, prior, stride, channels)) return false;
    const unsigned char* px = row + 1;
    unsigned char* g = out.ptr<unsigned char>(static_cast<int>(y));
    if (channels == 1) {
      std::memcpy(g, px, width);
    } else if (channels == 4) {
      greyOfRgba(px, g, width);
    } else {
      for (std::uint32_t x = 0; x < width; ++x, px += channels)
        g[x] = static_cast<unsigned char>((9798u * px[0] + 19235u * px[1] + 3735u * px[2] + (1u << 14)) >> 15);
    }
    prior = row + 1;
  }
  grey = out;
  return true;
}

}  // namespace mmval::tracking::detail

