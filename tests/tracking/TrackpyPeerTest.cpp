// Our tracker next to trackpy's outputs on real microscope frames
// (../shared/data/trackpy-tests, see its PROVENANCE.md). Agreement with a peer
// within a stated tolerance, not ground truth.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>

#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Frames.hpp"
#include "mmval/tracking/Link.hpp"
#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;
const fs::path kData = fs::path(MMVAL_SHARED_DATA_DIR) / "trackpy-tests";

std::vector<std::vector<double>> readCsv(const fs::path& p) {
  std::ifstream in(p);
  std::string line;
  std::getline(in, line);
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string cell;
    std::vector<double> r;
    while (std::getline(ss, cell, ',')) r.push_back(std::stod(cell));
    rows.push_back(r);
  }
  return rows;
}

TEST(TrackpyPeer, DetectionsOnTheFirstFrame) {
  ASSERT_TRUE(fs::exists(kData)) << "shared data missing: " << kData;
  const auto ref = readCsv(kData / "reference" / "locate_first_frame_d9_minmass140.csv");  // (y, x)
  ASSERT_EQ(ref.size(), 344u);
  FrameSource src((kData / "frames" / "T76S3F00001.png").string());
  cv::Mat frame;
  int index = 0;
  ASSERT_TRUE(src.next(frame, index));
  DetectOptions o;  // no video to take a median from: a flat background
  o.subtract_background = false;
  o.blur_sigma = 1.0;
  o.threshold = ThresholdMode::otsu;
  o.min_area = 4;
  o.min_snr = 0;  // a crowded frame without a median background: its MAD is texture, not noise
  const auto found = detect(frame, {}, Polarity::dark, o);
  // Pair each trackpy feature with our nearest detection within 2 px.
  int matched = 0;
  double se = 0;
  for (const auto& r : ref) {
    double best = 1e9;
    for (const auto& d : found) best = std::min(best, std::hypot(d.x - r[1], d.y - r[0]));
    if (best < 2) {
      ++matched;
      se += best * best;
    }
  }
  const double recall = static_cast<double>(matched) / ref.size();
  const double rms = std::sqrt(se / std::max(1, matched));
  std::printf("trackpy peer: %zu ours, %zu trackpy, matched %d (%.1f %%), RMS offset %.3f px\n", found.size(), ref.size(), matched,
              100 * recall, rms);
  // Tolerances: trackpy's minmass 140 keeps faint features a global threshold drops, so
  // we ask for 80 % of its features; where both see a particle they agree to 0.5 px.
  EXPECT_GT(recall, 0.8);
  EXPECT_LT(rms, 0.5);
}

TEST(TrackpyPeer, LinkingPartitionsMatch) {
  const auto input = readCsv(kData / "reference" / "link_input.csv");  // y, x, frame
  for (const auto& [file, memory] : std::vector<std::pair<std::string, int>>{{"link_sr5_mem0_ids.csv", 0}, {"link_sr5_mem2_ids.csv", 2}}) {
    const auto ids = readCsv(kData / "reference" / file);
    ASSERT_EQ(ids.size(), input.size());
    TrackLinker linker({Linker::global, 5.0, memory, false});
    std::map<int, std::vector<Detection>> frames;
    std::map<std::pair<int, std::pair<double, double>>, std::size_t> row_of;
    for (std::size_t i = 0; i < input.size(); ++i) {
      frames[static_cast<int>(input[i][2])].push_back({input[i][1], input[i][0], 1, 1, 1});
      row_of[{static_cast<int>(input[i][2]), {input[i][1], input[i][0]}}] = i;
    }
    for (const auto& [f, d] : frames) linker.push(f, d);
    // Compare the partitions of rows into tracks.
    std::map<std::int64_t, std::set<std::size_t>> ours, theirs;
    for (const auto& p : linker.points()) ours[p.particle].insert(row_of.at({p.frame, {p.x, p.y}}));
    for (std::size_t i = 0; i < ids.size(); ++i) theirs[static_cast<std::int64_t>(ids[i][0])].insert(i);
    std::set<std::set<std::size_t>> a, b;
    for (auto& [k, v] : ours) a.insert(v);
    for (auto& [k, v] : theirs) b.insert(v);
    int same = 0;
    for (const auto& s : a) same += b.count(s);
    std::printf("trackpy linking (%s): ours %zu tracks, trackpy %zu, identical %d\n", file.c_str(), a.size(), b.size(), same);
    // Search range 5 px as trackpy; without prediction the two linkers solve the same problem.
    EXPECT_EQ(a.size(), b.size());
    EXPECT_GE(same, static_cast<int>(b.size()) - 1);
  }
}

TEST(TrackpyPeer, StuckSpotsInAMultiPageTiffAreImmobile) {
  FrameSource src((kData / "stuck.tif").string());
  EXPECT_EQ(src.count(), 5);
  DetectOptions o;
  o.subtract_background = false;
  TrackLinker linker({Linker::global, 3.0, 0, false});
  cv::Mat f;
  int i = 0;
  std::size_t per_frame = 0;
  while (src.next(f, i)) {
    const auto d = detect(f, {}, Polarity::automatic, o);
    per_frame = d.size();
    linker.push(i, d);
  }
  Tracks t;
  for (const auto& p : linker.points()) t.points.push_back({p.frame, p.particle, p.frame * 1.0, p.x * 1e-6, p.y * 1e-6});
  TrackOptions opt;
  opt.immobile_distance = 2e-6;  // 2 px at 1 um/px: the jitter is ~0.4 px rms
  const TrackStats s = analyseTracks(t, opt);
  std::printf("stuck.tif: %zu spots per frame, %d tracks, %d immobile\n", per_frame, s.particles, s.immobile);
  // About 44 spots (PROVENANCE.md); all of them immobile.
  EXPECT_NEAR(static_cast<double>(per_frame), 44.0, 5.0);
  EXPECT_GE(s.immobile, s.particles - 2);
}

}  // namespace
}  // namespace mmval::tracking
