// Image sizes from headers, without decoding: a 1 MB file that declares 30000 x
// 30000 pixels is refused before any pixel buffer exists.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "mmval/core/ImageHeader.hpp"

namespace {

namespace fs = std::filesystem;
using Bytes = std::vector<unsigned char>;
using ::testing::HasSubstr;

fs::path write(const std::string& name, const Bytes& b) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / "image-header";
  fs::create_directories(d);
  const fs::path f = d / name;
  std::ofstream(f, std::ios::binary).write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  return f;
}

void putBe(Bytes& b, std::uint64_t v, int n) {
  for (int k = n - 1; k >= 0; --k) b.push_back(static_cast<unsigned char>(v >> (8 * k)));
}
void putLe(Bytes& b, std::uint64_t v, int n) {
  for (int k = 0; k < n; ++k) b.push_back(static_cast<unsigned char>(v >> (8 * k)));
}

/// A PNG signature and IHDR of the given size, then a garbage IDAT: what the
/// header check must refuse before any decoder touches it.
Bytes pngHeader(std::uint32_t w, std::uint32_t h, int colour_type) {
  Bytes b{0x89, 'P', 'N', 'G', 0x0D, 0x0A, 0x1A, 0x0A};
  putBe(b, 13, 4);
  for (char c : std::string("IHDR")) b.push_back(static_cast<unsigned char>(c));
  putBe(b, w, 4);
  putBe(b, h, 4);
  b.insert(b.end(), {8, static_cast<unsigned char>(colour_type), 0, 0, 0});
  putBe(b, 0, 4);  // CRC (not checked by the header reader)
  putBe(b, 16, 4);
  for (char c : std::string("IDATgarbagegarbage")) b.push_back(static_cast<unsigned char>(c));
  return b;
}

/// A one-IFD TIFF: width (LONG), height (SHORT), BitsPerSample, SamplesPerPixel.
Bytes tiffHeader(bool little, bool big, std::uint32_t w, std::uint32_t h, int bits, int spp) {
  Bytes b;
  auto put = [&](std::uint64_t v, int n) { little ? putLe(b, v, n) : putBe(b, v, n); };
  b.push_back(little ? 'I' : 'M');
  b.push_back(little ? 'I' : 'M');
  put(big ? 43 : 42, 2);
  if (big) {
    put(8, 2);
    put(0, 2);
    put(16, 8);
  } else {
    put(8, 4);
  }
  put(4, big ? 8 : 2);
  auto entry = [&](int tag, int type, std::uint64_t value) {
    put(static_cast<std::uint64_t>(tag), 2);
    put(static_cast<std::uint64_t>(type), 2);
    put(1, big ? 8 : 4);
    const int size = type == 3 ? 2 : 4;
    put(value, size);  // left-justified in the value field
    for (int k = size; k < (big ? 8 : 4); ++k) b.push_back(0);
  };
  entry(256, 4, w);
  entry(257, 3, h);
  entry(258, 3, static_cast<std::uint64_t>(bits));
  entry(277, 3, static_cast<std::uint64_t>(spp));
  put(0, big ? 8 : 4);
  return b;
}

TEST(ImageHeader, PngSizeFromIhdrWithoutDecoding) {
  const auto h = mmval::readImageHeader(write("huge.png", pngHeader(30000, 30000, 0)));
  ASSERT_TRUE(h.has_value());
  EXPECT_EQ(h->format, "PNG");
  EXPECT_EQ(h->width, 30000);
  EXPECT_EQ(h->height, 30000);
  EXPECT_EQ(h->channels, 1);
  EXPECT_EQ(h->bit_depth, 8);
  const auto rgba = mmval::readImageHeader(write("rgba.png", pngHeader(7, 5, 6)));
  ASSERT_TRUE(rgba.has_value());
  EXPECT_EQ(rgba->channels, 4);
  EXPECT_NEAR(rgba->decodedBytes(), 7 * 5 * 4, 1e-9);
}

TEST(ImageHeader, RealPngFilesOfTheSharedData) {
  const fs::path data(MMVAL_SHARED_DATA_DIR);
  const auto grains = mmval::readImageHeader(data / "pore2chip" / "grain_network.png");  // `file`: 500 x 500, 8-bit/color RGBA
  ASSERT_TRUE(grains.has_value());
  EXPECT_EQ(grains->width, 500);
  EXPECT_EQ(grains->height, 500);
  EXPECT_EQ(grains->channels, 4);
  const auto frame = mmval::readImageHeader(data / "trackpy-tests" / "frames" / "T76S3F00001.png");  // 640 x 424 grey
  ASSERT_TRUE(frame.has_value());
  EXPECT_EQ(frame->width, 640);
  EXPECT_EQ(frame->height, 424);
  EXPECT_EQ(frame->channels, 1);
}

TEST(ImageHeader, TiffBothByteOrdersAndBigTiff) {
  for (const bool little : {true, false})
    for (const bool big : {false, true}) {
      SCOPED_TRACE(std::string(little ? "II" : "MM") + (big ? " BigTIFF" : " TIFF"));
      const auto h = mmval::readImageHeader(write("t.tif", tiffHeader(little, big, 70000, 1234, 16, 3)));
      ASSERT_TRUE(h.has_value());
      EXPECT_EQ(h->format, big ? "BigTIFF" : "TIFF");
      EXPECT_EQ(h->width, 70000);
      EXPECT_EQ(h->height, 1234);
      EXPECT_EQ(h->bit_depth, 16);
      EXPECT_EQ(h->channels, 3);
    }
}

TEST(ImageHeader, JpegSofAfterOtherSegments) {
  Bytes b{0xFF, 0xD8, 0xFF, 0xE0};
  putBe(b, 16, 2);
  for (int k = 0; k < 14; ++k) b.push_back('J');  // APP0 payload
  b.insert(b.end(), {0xFF, 0xC2});                // progressive SOF
  putBe(b, 17, 2);
  b.push_back(8);
  putBe(b, 480, 2);  // height
  putBe(b, 640, 2);  // width
  b.push_back(3);
  const auto h = mmval::readImageHeader(write("j.jpg", b));
  ASSERT_TRUE(h.has_value());
  EXPECT_EQ(h->format, "JPEG");
  EXPECT_EQ(h->width, 640);
  EXPECT_EQ(h->height, 480);
  EXPECT_EQ(h->channels, 3);
}

TEST(ImageHeader, BmpTopDownAndNetpbmWithComments) {
  Bytes b{'B', 'M'};
  putLe(b, 0, 4 + 4 + 4);  // file size, reserved, pixel offset
  putLe(b, 40, 4);
  putLe(b, 300, 4);
  putLe(b, static_cast<std::uint32_t>(-200), 4);  // top-down rows
  putLe(b, 1, 2);
  putLe(b, 24, 2);
  const auto h = mmval::readImageHeader(write("b.bmp", b));
  ASSERT_TRUE(h.has_value());
  EXPECT_EQ(h->width, 300);
  EXPECT_EQ(h->height, 200);
  EXPECT_EQ(h->channels, 3);
  const std::string pgm = "P5\n# a comment\n 4000 3000\n65535\n";
  const auto p = mmval::readImageHeader(write("p.pgm", Bytes(pgm.begin(), pgm.end())));
  ASSERT_TRUE(p.has_value());
  EXPECT_EQ(p->width, 4000);
  EXPECT_EQ(p->height, 3000);
  EXPECT_EQ(p->bit_depth, 16);
}

TEST(ImageHeader, UnknownOrTruncatedGivesNoHeader) {
  EXPECT_FALSE(mmval::readImageHeader(write("x.txt", Bytes{'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd'})).has_value());
  Bytes cut = pngHeader(10, 10, 0);
  cut.resize(14);
  EXPECT_FALSE(mmval::readImageHeader(write("cut.png", cut)).has_value());
  EXPECT_FALSE(mmval::readImageHeader("/no/such/file.png").has_value());
  EXPECT_FALSE(mmval::readImageHeader("/dev/zero").has_value());
}

TEST(ImageHeader, RequireWithinRefusesNamingKeyAndSizeAndPassesSmallImages) {
  const fs::path huge = write("huge.png", pngHeader(30000, 30000, 0));
  try {
    mmval::requireImageWithin(huge, {"case.toml", 7, 0, "geometry.mask"}, 1e9, 12, "crop the image");
    FAIL() << "a 30000 x 30000 image at 12 B/px is not within 1 GB";
  } catch (const mmval::InputError& e) {
    const std::string m = e.what();
    EXPECT_THAT(m, HasSubstr("case.toml:7"));
    EXPECT_THAT(m, HasSubstr("geometry.mask"));
    EXPECT_THAT(m, HasSubstr("30000 x 30000 px"));
    EXPECT_THAT(m, HasSubstr("10.8 GB"));
    EXPECT_THAT(m, HasSubstr("run.max_memory"));
    EXPECT_THAT(m, HasSubstr("crop the image"));
  }
  const auto small = mmval::requireImageWithin(write("small.png", pngHeader(640, 480, 2)), {"case.toml", 7, 0, "geometry.mask"}, 1e9, 12, {});
  ASSERT_TRUE(small.has_value());
  EXPECT_EQ(small->width, 640);
}

}  // namespace
