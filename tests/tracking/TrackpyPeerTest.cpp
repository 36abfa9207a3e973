// Our tracker next to trackpy's outputs on real microscope frames
// (../shared/data/trackpy-tests, see its PROVENANCE.md). Agreement with a peer
// within a stated tolerance, not ground truth.
#include <gtest/gtest.h>

#include <algorithm>
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
#include "../NumericCsv.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;
const fs::path kData = fs::path(MMVAL_SHARED_DATA_DIR) / "trackpy-tests";

std::vector<std::vector<double>> readCsv(const fs::path& p) { return mmval::test::readNumericCsv(p); }

struct PeerMatch {
  std::size_t ours = 0;
  int within_1px = 0, within_2px = 0;
  double rms_px = 0;  ///< of the pairs within 1 px
};

/// Pairs each trackpy feature (y, x) with our nearest detection.
PeerMatch matchFeatures(const std::vector<std::vector<double>>& ref, const std::vector<Detection>& found) {
  PeerMatch m;
  m.ours = found.size();
  double se = 0;
  for (const auto& r : ref) {
    double best = 1e9;
    for (const auto& d : found) best = std::min(best, std::hypot(d.x - r[1], d.y - r[0]));
    if (best < 2) ++m.within_2px;
    if (best < 1) {
      ++m.within_1px;
      se += best * best;
    }
  }
  m.rms_px = std::sqrt(se / std::max(1, m.within_1px));
  return m;
}

cv::Mat firstFrame() {
  FrameSource src((kData / "frames" / "T76S3F00001.png").string());
  cv::Mat frame;
  int index = 0;
  EXPECT_TRUE(src.next(frame, index));
  return frame;
}

TEST(TrackpyPeer, DetectionsOnTheFirstFrame) {
  ASSERT_TRUE(fs::exists(kData)) << "shared data missing: " << kData;
  const auto ref = readCsv(kData / "reference" / "locate_first_frame_d9_minmass140.csv");  // (y, x)
  ASSERT_EQ(ref.size(), 344u);
  const cv::Mat frame = firstFrame();
  // Settings that match trackpy's locate(diameter=9, minmass=140, invert=True): dark
  // particles, no video to take a median from, a band pass of Gaussian sigma 1 px minus
  // a 9 px boxcar, local maxima at least 4 px apart, the centroid over a disc of radius 4.
  DetectOptions o;
  o.subtract_background = false;
  o.method = SeedMethod::peaks;
  o.local_background = 4;
  o.blur_sigma = 1.0;
  o.refine_radius = 4;
  o.refinement = Refinement::disc;
  o.min_area = 1;
  o.min_snr = 0;  // a crowded frame without a median background: its MAD is texture, not noise
  o.min_contrast = 0.004;  // 1 grey level of 255
  // trackpy's minmass is on its band-passed image rescaled to fill 0..255, ours on the
  // signal in fractions of full scale: 0.42 keeps every feature trackpy keeps and ~25 %
  // fainter ones (measured: 431 ours for 344 trackpy).
  o.min_mass = 0.42;
  const PeerMatch peaks = matchFeatures(ref, detect(frame, {}, Polarity::dark, o));
  // The paper's pipeline (threshold, opening, contours) on the same frame, for the record:
  // a global threshold merges touching particles and drops faint ones.
  DetectOptions c;
  c.subtract_background = false;
  c.min_area = 4;
  c.min_snr = 0;
  const PeerMatch contours = matchFeatures(ref, detect(frame, {}, Polarity::dark, c));
  std::printf("trackpy peer, %zu trackpy features: peaks %zu ours, %d within 1 px (%.1f %%), RMS %.3f px; "
              "contours %zu ours, %d within 1 px (%.1f %%), RMS %.3f px\n",
              ref.size(), peaks.ours, peaks.within_1px, 100.0 * peaks.within_1px / ref.size(), peaks.rms_px, contours.ours, contours.within_1px,
              100.0 * contours.within_1px / ref.size(), contours.rms_px);
  // The target is >= 90 % within 1 px; measured 343 / 344 (the one left is 1.0-2 px
  // away: two touching particles whose centroid windows overlap). Where both find a
  // particle the positions agree to the ~0.1 px localisation noise of either method.
  EXPECT_GE(peaks.within_1px, static_cast<int>(0.97 * ref.size()));
  EXPECT_LT(peaks.rms_px, 0.2);
  EXPECT_LT(peaks.ours, 1.5 * ref.size());
  EXPECT_GT(contours.within_1px, static_cast<int>(0.75 * ref.size()));
}

TEST(TrackpyPeer, LinkingPartitionsMatch) {
  const auto input = readCsv(kData / "reference" / "link_input.csv");  // y, x, frame
  for (const auto& [file, memory] : std::vector<std::pair<std::string, int>>{{"link_sr5_mem0_ids.csv", 0}, {"link_sr5_mem2_ids.csv", 2}}) {
    const auto ids = readCsv(kData / "reference" / file);
    ASSERT_EQ(ids.size(), input.size());
    TrackLinker linker({Linker::global, 5.0, memory, Prediction::none});
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
  // Contours with Otsu: the 44 spots are bright and well separated; local maxima would
  // also pick up a few flickering noise bumps on this dark, noisy 16-bit background.
  o.method = SeedMethod::contours;
  TrackLinker linker({Linker::global, 3.0, 0, Prediction::none});
  cv::Mat f;
  int i = 0;
  std::size_t per_frame = 0;
  while (src.next(f, i)) {
    const auto d = detect(f, {}, Polarity::automatic, o);
    per_frame = d.size();
    linker.push(i, d);
  }
  Tracks t;
  for (const auto& p : linker.points()) {
    TrackPoint q;
    q.frame = p.frame;
    q.particle = p.particle;
    q.t = p.frame * 1.0;
    q.x = p.x * 1e-6;
    q.y = p.y * 1e-6;
    t.points.push_back(q);
  }
  TrackOptions opt;
  opt.immobile_distance = 2e-6;  // 2 px at 1 um/px: the jitter is ~0.4 px rms
  const TrackStats s = analyseTracks(t, opt);
  std::printf("stuck.tif: %zu spots per frame, %d tracks, %d immobile\n", per_frame, s.particles, s.immobile);
  // About 44 spots (PROVENANCE.md); every one of them one track over the 5 pages, immobile.
  EXPECT_NEAR(static_cast<double>(per_frame), 44.0, 5.0);
  EXPECT_EQ(s.particles, static_cast<int>(per_frame));
  EXPECT_EQ(s.immobile, s.particles);
}

}  // namespace
}  // namespace mmval::tracking
