// Decoding cost and determinism of the frame sources: in one
// tracker run every frame is decoded exactly once, whatever samples the background
// and the polarity guess take; sampled frames equal the frames the main pass reads;
// tracks.csv is byte-identical for one and several threads. Unit tier: small
// synthetic videos (image folder, multi-page TIFF, MJPG video), well under 10 s.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <sys/resource.h>
#include <unistd.h>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/Background.hpp"
#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Frames.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/Synth.hpp"
#include "PngReader.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / ("frame-decode-" + std::to_string(::getpid())) / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

/// A small flow scene as a PNG folder, a multi-page 16-bit TIFF and an MJPG video of
/// the same frames.
struct Inputs {
  fs::path folder, tiff, video;
  int frames = 0;
};

Inputs makeInputs(const std::string& name) {
  const fs::path dir = scratch(name);
  SynthOptions o;
  o.width = 160;
  o.height = 120;
  o.frames = 36;
  o.particles = 12;
  o.immobile = 2;
  o.grains = 3;
  o.grain_radius = 10;
  o.speed = 2;
  o.seed = 7;
  writeSyntheticVideo(o, dir);
  Inputs in{dir / "frames", dir / "stack.tif", dir / "video.avi", o.frames};
  std::vector<cv::Mat> pages;
  cv::VideoWriter w(in.video.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10, cv::Size(o.width, o.height), false);
  for (int k = 0; k < o.frames; ++k) {
    char file[32];
    std::snprintf(file, sizeof file, "frame_%05d.png", k);
    const cv::Mat g = cv::imread((in.folder / file).string(), cv::IMREAD_GRAYSCALE);
    cv::Mat g16;
    g.convertTo(g16, CV_16U, 64.0);  // a 14-bit camera's range, stretched back by FrameSource
    pages.push_back(g16);
    w.write(g);
  }
  w.release();
  cv::imwritemulti(in.tiff.string(), pages);
  return in;
}

const Inputs& inputs() {
  static const Inputs in = makeInputs("scene");
  return in;
}

/// Background (one median and a rolling one) and polarity sampled, stuck particles on:
/// every sampler of runTracker is in use.
TrackConfig everySampler(int threads) {
  TrackConfig c;
  c.detect.subtract_background = true;
  c.detect.polarity = Polarity::automatic;
  c.detect.background_samples = 10;
  c.background_window = 12;
  c.threads = threads;
  c.pixel_size = 1e-6;
  c.fps = 10;
  return c;
}

std::string tracksCsv(const TrackRun& run, const fs::path& file) {
  writeTracksCsv(file, run.tracks, 1e-6);
  std::ifstream in(file, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

TEST(FrameDecode, EveryFrameDecodedOnceInARun) {
  const Inputs& in = inputs();
  for (const fs::path& input : {in.folder, in.tiff, in.video})
    for (int threads : {1, 3}) {
      FrameSource src(input.string());
      ASSERT_EQ(src.count(), in.frames) << input;
      const TrackRun run = runTracker(src, everySampler(threads), true);
      EXPECT_EQ(run.frame_index.size(), static_cast<std::size_t>(in.frames)) << input;
      // The old samplers read the whole video twice more (~2.9 decodes per frame).
      EXPECT_EQ(src.decoded(), in.frames) << input << " with " << threads << " thread(s)";
      // A video's codec runs once more for the frames the samplers skipped up to their
      // last sample and for the cached frames the main pass skips: never a third time.
      EXPECT_LE(src.decoded() + src.grabbed(), 2L * in.frames) << input;
    }
}

TEST(FrameDecode, SampledFramesEqualTheFramesReadInOrder) {
  const Inputs& in = inputs();
  for (const fs::path& input : {in.folder, in.tiff, in.video}) {
    // A range that starts late and steps: positions, input indices and the 16-bit
    // stretch (fixed by the first selected frame) must not depend on the reading order.
    const FrameRange range{3, -1, 2};
    FrameSource sampled(input.string(), std::nullopt, range), ordered(input.string(), std::nullopt, range);
    const std::vector<int> positions = samplePositions(sampled.count(), 5);
    ASSERT_EQ(positions, (std::vector<int>{0, 3, 6, 9, 12})) << "count " << sampled.count();
    const std::vector<cv::Mat> frames = sampleFrames(sampled, 5);
    ASSERT_EQ(frames.size(), positions.size());
    cv::Mat f;
    int index = 0;
    std::size_t k = 0;
    for (int pos = 0; ordered.next(f, index); ++pos) {
      EXPECT_EQ(index, 3 + 2 * pos);
      if (k < positions.size() && pos == positions[k]) {
        EXPECT_EQ(cv::norm(f, frames[k], cv::NORM_INF), 0.0) << input << " position " << pos;
        ++k;
      }
    }
    EXPECT_EQ(k, positions.size());
    // The sampled source's own main pass: the same frames, each decoded once.
    for (int pos = 0; sampled.next(f, index); ++pos) {
      cv::Mat g;
      int at = 0;
      FrameSource again(input.string(), std::nullopt, range);
      again.sample(pos, g, at);
      EXPECT_EQ(at, index);
      EXPECT_EQ(cv::norm(f, g, cv::NORM_INF), 0.0) << input << " position " << pos;
    }
    EXPECT_EQ(sampled.decoded(), sampled.count()) << input;
  }
}

TEST(FrameDecode, TracksIdenticalForOneAndSeveralThreads) {
  const Inputs& in = inputs();
  const fs::path out = scratch("csv");
  for (const fs::path& input : {in.folder, in.tiff, in.video}) {
    std::string one;
    for (int threads : {1, 2, 3}) {
      FrameSource src(input.string());
      const std::string csv = tracksCsv(runTracker(src, everySampler(threads), true), out / ("tracks-" + std::to_string(threads) + ".csv"));
      if (threads == 1) {
        one = csv;
        EXPECT_GT(std::count(csv.begin(), csv.end(), '\n'), 100) << input << ": too few tracked points to compare";
      } else {
        EXPECT_TRUE(csv == one) << input << ": tracks.csv differs between 1 and " << threads << " threads";
      }
    }
  }
}

TEST(FrameDecode, WithoutTheCacheTheSameTracksAndTheSampledFramesTwice) {
  const Inputs& in = inputs();
  const fs::path out = scratch("nocache");
  FrameSource cached(in.folder.string()), uncached(in.folder.string());
  uncached.setCacheLimit(0);
  const TrackConfig c = everySampler(2);
  const std::string a = tracksCsv(runTracker(cached, c, true), out / "a.csv");
  const std::string b = tracksCsv(runTracker(uncached, c, true), out / "b.csv");
  EXPECT_TRUE(a == b);
  // Without the cache: the union of the sampled positions once for the samplers (the
  // median's 10, the rolling blocks', the polarity's 24, all distinct frames counted once
  // per sampler that reads them) plus every frame in the main pass.
  std::size_t sampler_reads = samplePositions(in.frames, 10).size() + samplePositions(in.frames, 24).size();
  for (const auto& block : rollingSamplePositions(in.frames, 12, 10)) sampler_reads += block.size();
  EXPECT_EQ(uncached.decoded(), static_cast<long>(in.frames + sampler_reads));
  EXPECT_EQ(cached.decoded(), in.frames);
}

TEST(FrameDecode, PngFramesEqualImreadForEveryColourTypeAndFilter) {
  // FrameSource reads common 8-bit PNGs with its own reader when built with libdeflate
  // (tracking/src/PngReader.hpp), the others with cv::imread: either way a frame must
  // equal the reference exactly, cv::imread(IMREAD_UNCHANGED) then the conversion to
  // float grey (16 bit: stretched by the frame's own range, as the first frame's).
  // Grey, RGB, RGBA, 16-bit grey and RGB; compression levels 0-9; noisy
  // images (every row filter gets chosen) and smooth ramps (Sub / Up / Paeth rows).
  const fs::path dir = scratch("png-kinds");
  cv::RNG rng(11);
  int compared = 0;
  for (const int type : {CV_8UC1, CV_8UC3, CV_8UC4, CV_16UC1, CV_16UC3})
    for (const int level : {0, 1, 6, 9})
      for (const double noise : {0.3, 0.02}) {
        const bool wide = CV_MAT_DEPTH(type) == CV_16U;
        cv::Mat img(37, 53, type), ramp(37, 53, type);
        rng.fill(img, cv::RNG::UNIFORM, 0, wide ? 65536 : 256);
        for (int y = 0; y < ramp.rows; ++y)
          for (int x = 0; x < ramp.cols * ramp.channels(); ++x) {
            const int v = (3 * x + 5 * y) % 256;
            if (wide) ramp.ptr<std::uint16_t>(y)[x] = static_cast<std::uint16_t>(v * 257);
            else ramp.ptr<unsigned char>(y)[x] = static_cast<unsigned char>(v);
          }
        cv::addWeighted(img, noise, ramp, 1 - noise, 0, img);
        // One file per folder: the frames of a folder share their size and 16-bit range.
        const std::string name = "t" + std::to_string(type) + "_l" + std::to_string(level) + "_n" + std::to_string(noise);
        fs::create_directories(dir / name);
        const fs::path file = dir / name / "frame.png";
        ASSERT_TRUE(cv::imwrite(file.string(), img, {cv::IMWRITE_PNG_COMPRESSION, level}));
        const cv::Mat raw = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
        cv::Mat grey = raw, expected;
        if (raw.channels() != 1) {
          cv::cvtColor(raw, grey, raw.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
        }
        if (wide) {
          double lo = 0, hi = 0;
          cv::minMaxLoc(grey, &lo, &hi);
          grey.convertTo(expected, CV_32F, 1.0 / (hi - lo), -lo / (hi - lo));
        } else {
          expected = toFloatGrey(grey);
        }
        FrameSource src((dir / name).string());
        cv::Mat f;
        int index = -1;
        ASSERT_TRUE(src.next(f, index)) << name;
        ASSERT_EQ(f.size(), expected.size()) << name;
        EXPECT_EQ(cv::norm(f, expected, cv::NORM_INF), 0.0) << name << ": the frame differs from imread + the grey conversion";
        ++compared;
      }
  EXPECT_EQ(compared, 5 * 4 * 2);
}

TEST(FrameDecode, PngHeaderLargerThanItsDataIsRefusedWithoutAllocatingIt) {
  // A 70-byte PNG whose header says 40000 x 40000 grey (1.6 GB of pixels) with a few
  // bytes of image data: DEFLATE cannot expand more than 1032:1, so the reader must
  // refuse it before allocating the image (fuzz_png ran out of 4 GB on such files).
  // Independent check: the process's peak resident memory (getrusage) grows by far less
  // than the image the header claims.
  std::vector<unsigned char> png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  const auto chunk = [&png](const char* type, const std::vector<unsigned char>& data) {
    for (const int shift : {24, 16, 8, 0}) png.push_back(static_cast<unsigned char>(data.size() >> shift));
    png.insert(png.end(), type, type + 4);
    png.insert(png.end(), data.begin(), data.end());
    for (int i = 0; i < 4; ++i) png.push_back(0);  // CRC (not checked below)
  };
  const unsigned side = 40000;
  std::vector<unsigned char> ihdr;
  for (const unsigned v : {side, side})
    for (const int shift : {24, 16, 8, 0}) ihdr.push_back(static_cast<unsigned char>(v >> shift));
  ihdr.insert(ihdr.end(), {8, 0, 0, 0, 0});                            // 8-bit grey, no interlace
  chunk("IHDR", ihdr);
  chunk("IDAT", {0x78, 0x9c, 0x63, 0x60, 0x00, 0x00, 0x00, 0x02, 0x00, 0x01});  // zlib of two zero bytes
  chunk("IEND", {});
  rusage before{}, after{};
  getrusage(RUSAGE_SELF, &before);
  cv::Mat grey;
  EXPECT_FALSE(detail::decodePngGrey8(png.data(), png.size(), grey, false));
  getrusage(RUSAGE_SELF, &after);
  EXPECT_TRUE(grey.empty());
  const double grown_mb = static_cast<double>(after.ru_maxrss - before.ru_maxrss) / 1024.0;  // ru_maxrss in KiB
  EXPECT_LT(grown_mb, 200.0) << "peak memory grew by " << grown_mb << " MB for a header claiming " << side * side / 1e6 << " MB";
}

}  // namespace
}  // namespace mmval::tracking
