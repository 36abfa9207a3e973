// Small inputs that ask for a huge run fail fast (seconds, little
// memory) with exit 2 naming the key or option, and bad command-line values
// are reported as bad, not as missing. Each test runs build/bin/mmval under
// /usr/bin/time to check the refused run's peak memory.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "RunMmval.hpp"

#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

using mmval::test::Outcome;

/// Runs `mmval ARGS` under /usr/bin/time (peak memory in Outcome::peak_bytes).
Outcome mmval(const std::string& args) { return mmval::test::runMmval(args, "", true); }

fs::path scratch(const std::string& name) { return mmval::test::freshTestFolder("limits", name); }

/// Refused quickly and cheaply: exit 2, within 5 s, under 1 GB.
void expectFastRefusal(const Outcome& o) {
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_LT(o.seconds, 5.0) << o.output;
  EXPECT_GT(o.peak_bytes, 0.0) << "no peak memory from /usr/bin/time: " << o.output;
  EXPECT_LT(o.peak_bytes, 1e9) << o.output;
  EXPECT_THAT(o.output, Not(HasSubstr("bad_alloc")));
  EXPECT_THAT(o.output, Not(HasSubstr("internal error")));
}

std::string readFile(const fs::path& f) {
  std::ifstream in(f);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// ---- PNG by hand (stored deflate blocks: no zlib needed) ----
std::uint32_t crc32(const std::string& bytes) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (unsigned char b : bytes) {
    c ^= b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
  }
  return c ^ 0xFFFFFFFFu;
}
std::string be32(std::uint32_t v) {
  return {static_cast<char>(v >> 24), static_cast<char>(v >> 16), static_cast<char>(v >> 8), static_cast<char>(v)};
}
std::string chunk(const std::string& type, const std::string& data) {
  return be32(static_cast<std::uint32_t>(data.size())) + type + data + be32(crc32(type + data));
}
std::string ihdr(std::uint32_t w, std::uint32_t h) { return be32(w) + be32(h) + std::string{8, 0, 0, 0, 0}; }
const std::string kSignature = "\x89PNG\r\n\x1a\n";

/// A 30000 x 30000 grey PNG header followed by a garbage IDAT: ~100 bytes that a
/// decoder would turn into 900 MB before finding the garbage.
fs::path hugePng(const fs::path& dir) {
  const fs::path f = dir / "huge.png";
  std::ofstream(f, std::ios::binary) << kSignature << chunk("IHDR", ihdr(30000, 30000)) << chunk("IDAT", std::string(64, 'x'))
                                     << chunk("IEND", "");
  return f;
}

/// A valid w x h grey PNG: white pores with a dark square grain in the middle.
fs::path smallPng(const fs::path& dir, int w, int h) {
  std::string raw;
  for (int y = 0; y < h; ++y) {
    raw += '\0';  // filter: none
    for (int x = 0; x < w; ++x) raw += (std::abs(x - w / 2) < w / 6 && std::abs(y - h / 2) < h / 6) ? '\0' : '\xff';
  }
  std::uint32_t a = 1, b = 0;  // Adler-32 of the raw data
  for (unsigned char ch : raw) {
    a = (a + ch) % 65521;
    b = (b + a) % 65521;
  }
  std::string z = "\x78\x01";
  for (std::size_t pos = 0; pos < raw.size() || pos == 0; pos += 65535) {
    const std::size_t n = std::min<std::size_t>(65535, raw.size() - pos);
    const bool last = pos + n >= raw.size();
    z += static_cast<char>(last ? 1 : 0);
    z += static_cast<char>(n & 0xFF);
    z += static_cast<char>(n >> 8);
    z += static_cast<char>(~n & 0xFF);
    z += static_cast<char>((~n >> 8) & 0xFF);
    z += raw.substr(pos, n);
    if (last) break;
  }
  z += be32((b << 16) | a);
  const fs::path f = dir / "small.png";
  std::ofstream(f, std::ios::binary) << kSignature << chunk("IHDR", ihdr(static_cast<std::uint32_t>(w), static_cast<std::uint32_t>(h)))
                                     << chunk("IDAT", z) << chunk("IEND", "");
  return f;
}

fs::path imageCase(const fs::path& dir, const fs::path& mask, const std::string& extra) {
  const fs::path f = dir / "image.toml";
  std::ofstream(f) << "[case]\nname = \"image\"\nkind = \"image-permeability\"\n\n[geometry]\nmask = \"" << mask.string()
                   << "\"\npixel_size = \"10 um\"\n\n[numerics]\ndepth_model = \"2d\"\ncells_per_pixel = 1\n" << extra;
  return f;
}

/// cases/NAME.toml with `from` replaced by `to` (regex), written into `dir`.
fs::path editedCase(const std::string& name, const std::string& from, const std::string& to, const fs::path& dir) {
  const std::string text = std::regex_replace(readFile(fs::path(MMVAL_SOURCE_DIR) / "cases" / (name + ".toml")), std::regex(from), to);
  const fs::path f = dir / "cases" / (name + ".toml");
  fs::create_directories(f.parent_path());
  std::ofstream(f) << text;
  // Reference files and shared data are found relative to the case file.
  std::error_code ec;
  fs::create_directory_symlink(fs::path(MMVAL_SOURCE_DIR) / "reference-data", dir / "reference-data", ec);
  return f;
}

TEST(Limits, HugePngMaskIsRefusedFromItsHeaderBeforeDecoding) {
  const fs::path d = scratch("huge-mask");
  const fs::path png = hugePng(d);
  // With a 1 GB budget the image itself does not fit: refused naming geometry.mask and its size.
  const Outcome o = mmval("run " + imageCase(d, png, "\n[run]\nmax_memory = \"1 GB\"\n").string() + " --out " + (d / "out").string());
  expectFastRefusal(o);
  EXPECT_THAT(o.output, HasSubstr("key 'geometry.mask'"));
  EXPECT_THAT(o.output, HasSubstr("30000 x 30000 px"));
  EXPECT_THAT(o.output, HasSubstr("run.max_memory (1 GB)"));
  // With the default budget (half this machine's memory) the grid built from it is refused.
  const Outcome dflt = mmval("run " + imageCase(d, png, "").string() + " --out " + (d / "out").string());
  expectFastRefusal(dflt);
  EXPECT_THAT(dflt.output, HasSubstr("30000 x 30000"));
  EXPECT_THAT(dflt.output, HasSubstr("needs about"));
  EXPECT_FALSE(fs::exists(d / "out"));
}

TEST(Limits, SmallPngMaskStillRuns) {
  const fs::path d = scratch("small-mask");
  const Outcome o = mmval("run " + imageCase(d, smallPng(d, 48, 24), "").string() + " --out " + (d / "out").string() + " --quiet");
  EXPECT_EQ(o.status, 0) << o.output;
  EXPECT_TRUE(fs::exists(d / "out" / "result.json"));
}

TEST(Limits, SynthGeometryHugePngIsRefusedNamingTheOption) {
  const fs::path d = scratch("synth-huge");
  const Outcome o = mmval("synth --out " + (d / "out").string() + " --geometry " + hugePng(d).string());
  expectFastRefusal(o);
  EXPECT_THAT(o.output, HasSubstr("--geometry"));
  EXPECT_THAT(o.output, HasSubstr("30000 x 30000 px"));
  EXPECT_FALSE(fs::exists(d / "out"));
}

TEST(Limits, PicosecondOutputIntervalIsRefusedNamingTheKey) {
  const fs::path d = scratch("output-interval");
  const fs::path c = editedCase("particles-channel", "output_interval = \"[^\"]*\"", "output_interval = \"1e-12 s\"", d);
  const Outcome o = mmval("run " + c.string() + " --out " + (d / "out").string());
  expectFastRefusal(o);
  EXPECT_THAT(o.output, HasSubstr("key 'run.output_interval'"));
  EXPECT_THAT(o.output, HasSubstr("output frames"));
}

TEST(Limits, BillionSecondRunIsRefusedNamingTheKey) {
  const fs::path d = scratch("duration");
  const fs::path c = editedCase("particles-channel", "duration = \"[^\"]*\"", "duration = \"1e9 s\"", d);
  const Outcome o = mmval("run " + c.string() + " --out " + (d / "out").string());
  expectFastRefusal(o);
  EXPECT_THAT(o.output, HasSubstr("key 'run.duration'"));
}

TEST(Limits, SquareArrayAt4096SquaredCellsIsRefusedWithTheEstimate) {
  const fs::path d = scratch("array-4096");
  const fs::path c = editedCase("fluid-square-array-phi020", "cells_per_side = [0-9]+\nlevels = \\[[^\\]]*\\]", "cells_per_side = 4096", d);
  const Outcome o = mmval("run " + c.string() + " --out " + (d / "out").string());
  expectFastRefusal(o);
  EXPECT_THAT(o.output, HasSubstr("key 'numerics.cells_per_side'"));
  EXPECT_THAT(o.output, HasSubstr("4096 x 4096"));
  EXPECT_THAT(o.output, HasSubstr("needs about"));
  EXPECT_THAT(o.output, Not(HasSubstr("PETSC ERROR")));
}

TEST(Limits, PeerLevelsAboveTheCaseFileCapAreRefusedBeforeBlockMesh) {
  const fs::path d = scratch("peer-levels");
  const fs::path c = fs::path(MMVAL_SOURCE_DIR) / "cases" / "fluid-square-array-phi020.toml";
  const Outcome o = mmval("peer openfoam " + c.string() + " --out " + (d / "out").string() + " --levels 1000000000");
  expectFastRefusal(o);
  EXPECT_THAT(o.output, HasSubstr("--levels 1000000000"));
  EXPECT_THAT(o.output, HasSubstr("4096"));
  EXPECT_FALSE(fs::exists(d / "out"));
  EXPECT_FALSE(fs::exists(d / "out.partial"));
}

TEST(Limits, TrackReportsBadFpsAndPixelSizeAsBadNotMissing) {
  const fs::path d = scratch("track-flags");
  const std::string frames = (fs::path(MMVAL_SHARED_DATA_DIR) / "trackpy-tests" / "frames").string();
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"--fps -10 --pixel-size-um 1", "--fps -10"},        {"--fps 0 --pixel-size-um 1", "--fps 0"},
      {"--fps nan --pixel-size-um 1", "--fps nan"},        {"--fps 10 --pixel-size-um -1", "--pixel-size-um -1"},
      {"--fps 10 --pixel-size-um inf", "--pixel-size-um inf"}};
  for (const auto& [args, shown] : bad) {
    SCOPED_TRACE(args);
    const Outcome o = mmval("track " + frames + " --out " + (d / "out").string() + " --quiet " + args);
    expectFastRefusal(o);
    EXPECT_THAT(o.output, HasSubstr(shown));
    EXPECT_THAT(o.output, HasSubstr("finite and > 0"));
    EXPECT_THAT(o.output, Not(HasSubstr("missing")));
    EXPECT_FALSE(fs::exists(d / "out"));
  }
}

TEST(Limits, TrackEmptyFrameRangeSaysSo) {
  const fs::path d = scratch("track-range");
  const std::string frames = (fs::path(MMVAL_SHARED_DATA_DIR) / "trackpy-tests" / "frames").string();
  const Outcome o = mmval("track " + frames + " --out " + (d / "out").string() + " --quiet --fps 10 --pixel-size-um 1 --first 100");
  expectFastRefusal(o);
  EXPECT_THAT(o.output, HasSubstr("selects no frame"));
  EXPECT_THAT(o.output, HasSubstr("inputs.first_frame"));
  EXPECT_THAT(o.output, Not(HasSubstr("polarity")));
  const Outcome back = mmval("track " + frames + " --out " + (d / "out").string() + " --quiet --fps 10 --pixel-size-um 1 --first 3 --last 1");
  expectFastRefusal(back);
  EXPECT_THAT(back.output, HasSubstr("--first 3 --last 1"));
}

TEST(Limits, TrackTruthFromADeviceIsRefusedNotReadForever) {
  const fs::path d = scratch("track-truth");
  const std::string frames = (fs::path(MMVAL_SHARED_DATA_DIR) / "trackpy-tests" / "frames").string();
  const Outcome o = mmval("track " + frames + " --out " + (d / "out").string() + " --quiet --fps 10 --pixel-size-um 1 --truth /dev/zero");
  expectFastRefusal(o);
  EXPECT_THAT(o.output, HasSubstr("inputs.truth"));
  EXPECT_THAT(o.output, HasSubstr("not a regular file"));
}

TEST(Limits, SynthRefusesNanAndHugeTruth) {
  const fs::path d = scratch("synth-flags");
  const Outcome nan = mmval("synth --out " + (d / "out").string() + " --fps nan");
  expectFastRefusal(nan);
  EXPECT_THAT(nan.output, HasSubstr("--fps nan"));
  EXPECT_FALSE(fs::exists(d / "out"));
  const Outcome huge = mmval("synth --out " + (d / "out").string() + " --frames 1000000 --particles 1000000");
  expectFastRefusal(huge);
  EXPECT_THAT(huge.output, HasSubstr("--frames"));
  EXPECT_THAT(huge.output, HasSubstr("needs about"));
  EXPECT_FALSE(fs::exists(d / "out"));
}

TEST(Limits, UnconfinedCylinderStartsAtASmallCourantNumberWithoutAFalseDivergence) {
  // The projection step's pressure solve, started from the last step's pressure increment, was
  // stopped at step 4 of this start-up at Courant <= 1 (DIVERGED_DTOL at iteration 0: the guess
  // left a residual ~50x the right-hand side) and the run exited 5 telling the user to lower the
  // Courant limit, which only made it worse. 0.01 s here is ~20 steps at Courant 0.5; the
  // shedding statistics need 12 s, so the run ends with failing metrics (exit 3), not a failure.
  const fs::path d = scratch("unconfined-start");
  const fs::path c = fs::path(MMVAL_SOURCE_DIR) / "cases" / "fluid-cylinder-unconfined-re100.toml";
  const Outcome o = mmval("run " + c.string() + " --quiet --set numerics.cells_around=32 --set numerics.max_courant=0.5 --set numerics.end_time=0.01s" +
                          " --set numerics.statistics_from=0s --out " + (d / "out").string());
  EXPECT_EQ(o.status, 3) << o.output;
  EXPECT_THAT(o.output, Not(HasSubstr("numerical failure"))) << o.output;
  EXPECT_TRUE(fs::exists(d / "out" / "result.json")) << o.output;
}

}  // namespace
