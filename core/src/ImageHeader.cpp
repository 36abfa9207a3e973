#include "mmval/core/ImageHeader.hpp"

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdlib>
#include <fstream>
#include <vector>

#include <fmt/format.h>

#include "mmval/core/Resources.hpp"

namespace mmval {

namespace {

/// Reads `n` bytes at `offset`; false when the file is shorter.
bool readAt(std::ifstream& in, std::uint64_t offset, unsigned char* out, std::size_t n) {
  in.clear();
  in.seekg(static_cast<std::streamoff>(offset));
  if (!in) return false;
  in.read(reinterpret_cast<char*>(out), static_cast<std::streamsize>(n));
  return static_cast<std::size_t>(in.gcount()) == n;
}

std::uint64_t be(const unsigned char* p, int n) {
  std::uint64_t v = 0;
  for (int k = 0; k < n; ++k) v = (v << 8) | p[k];
  return v;
}

std::uint64_t le(const unsigned char* p, int n) {
  std::uint64_t v = 0;
  for (int k = n - 1; k >= 0; --k) v = (v << 8) | p[k];
  return v;
}

int bytesPerSample(int bits) { return bits <= 8 ? 1 : bits <= 16 ? 2 : bits <= 32 ? 4 : 8; }

std::optional<ImageHeader> png(std::ifstream& in) {
  // Signature (8), IHDR length (4) and type (4), then width, height (4 each, big-endian), bit depth, colour type.
  std::array<unsigned char, 26> b{};
  if (!readAt(in, 0, b.data(), b.size()) || std::string(reinterpret_cast<const char*>(b.data()) + 12, 4) != "IHDR") return std::nullopt;
  ImageHeader h;
  h.format = "PNG";
  h.width = static_cast<std::int64_t>(be(b.data() + 16, 4));
  h.height = static_cast<std::int64_t>(be(b.data() + 20, 4));
  h.bit_depth = b[24];
  switch (b[25]) {
    case 2: h.channels = 3; break;  // RGB
    case 3: h.channels = 3; break;  // palette: decoded to RGB
    case 4: h.channels = 2; break;  // grey + alpha
    case 6: h.channels = 4; break;  // RGBA
    default: h.channels = 1;        // grey
  }
  if (b[25] == 3) h.bit_depth = 8;
  return h;
}

std::optional<ImageHeader> tiff(std::ifstream& in) {
  std::array<unsigned char, 16> b{};
  if (!readAt(in, 0, b.data(), 16)) return std::nullopt;
  const bool little = b[0] == 'I';
  auto num = [little](const unsigned char* p, int n) { return little ? le(p, n) : be(p, n); };
  const std::uint64_t version = num(b.data() + 2, 2);
  const bool big = version == 43;
  if (version != 42 && !big) return std::nullopt;
  const std::uint64_t ifd = big ? num(b.data() + 8, 8) : num(b.data() + 4, 4);
  const int count_size = big ? 8 : 2, entry_size = big ? 20 : 12, value_size = big ? 8 : 4;
  std::array<unsigned char, 8> cb{};
  if (!readAt(in, ifd, cb.data(), static_cast<std::size_t>(count_size))) return std::nullopt;
  const std::uint64_t entries = num(cb.data(), count_size);
  if (entries == 0 || entries > 4096) return std::nullopt;
  std::vector<unsigned char> e(static_cast<std::size_t>(entries * entry_size));
  if (!readAt(in, ifd + count_size, e.data(), e.size())) return std::nullopt;
  ImageHeader h;
  h.format = big ? "BigTIFF" : "TIFF";
  h.width = h.height = -1;
  for (std::uint64_t k = 0; k < entries; ++k) {
    const unsigned char* p = e.data() + k * entry_size;
    const auto tag = num(p, 2), type = num(p + 2, 2);
    const int size = type == 3 ? 2 : type == 4 ? 4 : type == 16 ? 8 : 0;  // SHORT, LONG, LONG8
    if (size == 0) continue;
    const std::uint64_t n = big ? num(p + 4, 8) : num(p + 4, 4);
    const unsigned char* v = p + 4 + value_size;
    std::array<unsigned char, 8> far{};
    if (n * size > static_cast<std::uint64_t>(value_size)) {
      // The values live elsewhere: the first of them is enough (BitsPerSample is the same for every sample in practice).
      if (!readAt(in, num(v, value_size), far.data(), static_cast<std::size_t>(size))) return std::nullopt;
      v = far.data();
    }
    const auto value = static_cast<std::int64_t>(num(v, size));
    if (tag == 256) h.width = value;
    if (tag == 257) h.height = value;
    if (tag == 258) h.bit_depth = static_cast<int>(value);
    if (tag == 277) h.channels = static_cast<int>(value);
  }
  if (h.width < 0 || h.height < 0) return std::nullopt;
  return h;
}

std::optional<ImageHeader> jpeg(std::ifstream& in) {
  std::uint64_t pos = 2;
  for (int segment = 0; segment < 10000; ++segment) {
    std::array<unsigned char, 2> m{};
    if (!readAt(in, pos, m.data(), 2)) return std::nullopt;
    if (m[0] != 0xFF) return std::nullopt;
    if (m[1] == 0xFF) {  // fill byte
      ++pos;
      continue;
    }
    const unsigned marker = m[1];
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD8)) {  // no length
      pos += 2;
      continue;
    }
    if (marker == 0xD9 || marker == 0xDA) return std::nullopt;  // end of image, or the scan before any frame header
    std::array<unsigned char, 8> s{};
    if (!readAt(in, pos + 2, s.data(), 8)) return std::nullopt;
    const bool sof = marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC;
    if (sof) {
      ImageHeader h;
      h.format = "JPEG";
      h.bit_depth = s[2];
      h.height = static_cast<std::int64_t>(be(s.data() + 3, 2));
      h.width = static_cast<std::int64_t>(be(s.data() + 5, 2));
      h.channels = s[7];
      return h;
    }
    pos += 2 + be(s.data(), 2);
  }
  return std::nullopt;
}

std::optional<ImageHeader> bmp(std::ifstream& in) {
  std::array<unsigned char, 30> b{};
  if (!readAt(in, 0, b.data(), b.size())) return std::nullopt;
  const auto info = le(b.data() + 14, 4);
  ImageHeader h;
  h.format = "BMP";
  int bits = 0;
  if (info == 12) {  // OS/2 BITMAPCOREHEADER: 16-bit sizes
    h.width = static_cast<std::int64_t>(le(b.data() + 18, 2));
    h.height = static_cast<std::int64_t>(le(b.data() + 20, 2));
    bits = static_cast<int>(le(b.data() + 24, 2));
  } else if (info >= 40) {
    h.width = static_cast<std::int32_t>(le(b.data() + 18, 4));
    h.height = std::llabs(static_cast<std::int32_t>(le(b.data() + 22, 4)));  // negative: rows stored top-down
    bits = static_cast<int>(le(b.data() + 28, 2));
  } else {
    return std::nullopt;
  }
  h.channels = bits == 32 ? 4 : 3;  // palettes decode to colour
  h.bit_depth = 8;
  return h;
}

std::optional<ImageHeader> pnm(std::ifstream& in, char type) {
  in.clear();
  in.seekg(2);
  std::array<std::int64_t, 3> v{0, 0, 1};
  const int needed = type == '1' || type == '4' ? 2 : 3;
  for (int k = 0; k < needed; ++k) {
    int ch = in.get();
    for (int guard = 0; guard < 4096 && (std::isspace(ch) || ch == '#'); ++guard) {
      if (ch == '#')
        while (ch != '\n' && ch != EOF) ch = in.get();
      ch = in.get();
    }
    if (!std::isdigit(ch)) return std::nullopt;
    std::int64_t x = 0;
    for (int digits = 0; std::isdigit(ch) && digits < 12; ++digits, ch = in.get()) x = 10 * x + (ch - '0');
    v[static_cast<std::size_t>(k)] = x;
  }
  ImageHeader h;
  h.format = "PNM";
  h.width = v[0];
  h.height = v[1];
  h.channels = type == '3' || type == '6' ? 3 : 1;
  h.bit_depth = v[2] > 255 ? 16 : 8;
  return h;
}

}  // namespace

double ImageHeader::decodedBytes() const { return pixels() * channels * bytesPerSample(bit_depth); }

std::optional<ImageHeader> readImageHeader(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return std::nullopt;
  std::ifstream in(file, std::ios::binary);
  std::array<unsigned char, 8> sig{};
  if (!in || !readAt(in, 0, sig.data(), sig.size())) return std::nullopt;
  static constexpr std::array<unsigned char, 8> kPng{0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  if (sig == kPng) return png(in);
  if ((sig[0] == 'I' && sig[1] == 'I') || (sig[0] == 'M' && sig[1] == 'M')) return tiff(in);
  if (sig[0] == 0xFF && sig[1] == 0xD8) return jpeg(in);
  if (sig[0] == 'B' && sig[1] == 'M') return bmp(in);
  if (sig[0] == 'P' && sig[1] >= '1' && sig[1] <= '6' && std::isspace(sig[2])) return pnm(in, static_cast<char>(sig[1]));
  return std::nullopt;
}

std::optional<ImageHeader> requireImageWithin(const std::filesystem::path& file, const InputLocation& where, double limit_bytes,
                                              double bytes_per_pixel, const std::string& advice) {
  const std::optional<ImageHeader> h = readImageHeader(file);
  if (!h) return h;
  const double estimate = std::max(h->pixels() * bytes_per_pixel, h->decodedBytes());
  requireMemory(estimate, limit_bytes,
                fmt::format("the image '{}' ({} x {} px, {} {}-bit channel{}, {})", file.string(), h->width, h->height, h->channels,
                            h->bit_depth, h->channels == 1 ? "" : "s", h->format),
                where, advice);
  return h;
}

}  // namespace mmval
