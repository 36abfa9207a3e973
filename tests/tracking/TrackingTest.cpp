// The tracker against references it cannot bend: brute-force assignment,
// spots rendered at known sub-pixel positions, and a synthetic micromodel
// video with ground truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numeric>
#include <fstream>
#include <random>

#include "mmval/core/Error.hpp"

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "mmval/tracking/Assignment.hpp"
#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Link.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/Score.hpp"
#include "mmval/tracking/Synth.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

TEST(Assignment, MatchesBruteForceOnRandomMatrices) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0, 10);
  for (int trial = 0; trial < 50; ++trial) {
    const int n = 1 + trial % 5, m = n + trial % 3;
    std::vector<std::vector<double>> c(n, std::vector<double>(m));
    for (auto& row : c)
      for (auto& x : row) x = U(rng);
    const auto a = solveAssignment(c);
    double got = 0;
    for (int i = 0; i < n; ++i) got += c[i][a[i]];
    // Brute force over all injective maps rows -> columns.
    std::vector<int> cols(m);
    std::iota(cols.begin(), cols.end(), 0);
    double best = 1e300;
    do {
      double s = 0;
      for (int i = 0; i < n; ++i) s += c[i][cols[i]];
      best = std::min(best, s);
    } while (std::next_permutation(cols.begin(), cols.end()));
    EXPECT_NEAR(got, best, 1e-9) << "trial " << trial;
  }
}

/// Clean Gaussian spots at known sub-pixel positions on a flat background.
cv::Mat spots(const std::vector<cv::Point2d>& at, double sigma, double amplitude, double noise, unsigned seed) {
  cv::Mat img(120, 160, CV_32F, cv::Scalar(0.8));
  for (const auto& p : at)
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x)
        img.at<float>(y, x) -= static_cast<float>(amplitude * std::exp(-((x - p.x) * (x - p.x) + (y - p.y) * (y - p.y)) / (2 * sigma * sigma)));
  std::mt19937 rng(seed);
  std::normal_distribution<double> N(0, noise);
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) img.at<float>(y, x) += static_cast<float>(N(rng));
  return img;
}

double rmseOf(const std::vector<cv::Point2d>& truth, const std::vector<Detection>& found, int& matched) {
  double se = 0;
  matched = 0;
  for (const auto& t : truth) {
    double best = 1e9;
    for (const auto& d : found) best = std::min(best, std::hypot(d.x - t.x, d.y - t.y));
    if (best < 2) {
      se += best * best;
      ++matched;
    }
  }
  return matched ? std::sqrt(se / matched) : 1e9;
}

TEST(Detect, SubPixelLocalisationOnCleanSpots) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0, 1);
  std::vector<cv::Point2d> truth;
  for (int gy = 0; gy < 5; ++gy)
    for (int gx = 0; gx < 7; ++gx) truth.push_back({15 + gx * 20 + U(rng), 15 + gy * 20 + U(rng)});
  const cv::Mat background(120, 160, CV_32F, cv::Scalar(0.8));
  DetectOptions o;
  o.blur_sigma = 1.0;
  int matched = 0;
  // Noise-free: the intensity-weighted centroid recovers sub-pixel positions to
  // far better than Crocker & Grier's ~0.05 px (reference-data/tracking-accuracy.toml).
  o.refinement = Refinement::intensity;
  const double intensity = rmseOf(truth, detect(spots(truth, 1.5, 0.4, 0.0, 1), background, Polarity::dark, o), matched);
  EXPECT_EQ(matched, 35);
  EXPECT_LT(intensity, 0.01);
  // The contour centroid of the thresholded blob is pixel-quantised: worse.
  o.refinement = Refinement::moments;
  const double moments = rmseOf(truth, detect(spots(truth, 1.5, 0.4, 0.0, 1), background, Polarity::dark, o), matched);
  EXPECT_EQ(matched, 35);
  EXPECT_GT(moments, intensity);
  // With 2 % camera noise the refined centroid still stays within 0.1 px.
  o.refinement = Refinement::intensity;
  const double noisy = rmseOf(truth, detect(spots(truth, 1.5, 0.4, 0.02, 2), background, Polarity::dark, o), matched);
  EXPECT_EQ(matched, 35);
  EXPECT_LT(noisy, 0.1);
  std::printf("localisation RMSE: intensity %.4f px, moments %.4f px, intensity with noise %.4f px\n", intensity, moments, noisy);
}

TEST(Detect, PolarityIsGuessedAndBrightParticlesFound) {
  const std::vector<cv::Point2d> truth = {{40.3, 50.7}, {100.2, 30.1}};
  cv::Mat dark = spots(truth, 1.5, 0.4, 0.0, 1);
  const cv::Mat background(120, 160, CV_32F, cv::Scalar(0.8));
  EXPECT_EQ(guessPolarity(dark, background), Polarity::dark);
  cv::Mat bright = 1.6 - dark;  // bright spots on a 0.8 background
  EXPECT_EQ(guessPolarity(bright, background), Polarity::bright);
  int matched = 0;
  rmseOf(truth, detect(bright, background, Polarity::automatic, DetectOptions{}), matched);
  EXPECT_EQ(matched, 2);
}

fs::path synthetic(const char* name, const SynthOptions& o, SynthResult& r) {
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / name;
  fs::remove_all(dir);
  r = writeSyntheticVideo(o, dir);
  return dir;
}

Tracks withoutImmobile(const SynthResult& r) {
  Tracks t = r.truth;
  std::erase_if(t.points, [&](const TrackPoint& p) { return std::find(r.immobile_ids.begin(), r.immobile_ids.end(), p.particle) != r.immobile_ids.end(); });
  return t;
}

TEST(Pipeline, BothLinkersTrackTheSyntheticVideo) {
  SynthOptions o;
  o.frames = 40;
  o.seed = 5;
  SynthResult truth;
  const fs::path dir = synthetic("synth-link", o, truth);
  for (Linker method : {Linker::global, Linker::paper}) {
    TrackConfig c;
    c.link.method = method;
    FrameSource src((dir / "frames").string());
    const TrackRun run = runTracker(src, c, true);
    const Scores s = scoreTracks(withoutImmobile(truth), run.tracks);
    std::printf("%s linker: JSC %.3f alpha %.3f beta %.3f JSC_tracks %.3f RMSE %.3f px\n", method == Linker::global ? "global" : "paper",
                s.jaccard_points, s.alpha, s.beta, s.jaccard_tracks, s.rmse_px);
    EXPECT_GT(s.jaccard_points, method == Linker::global ? 0.9 : 0.85);
    EXPECT_GT(s.alpha, method == Linker::global ? 0.88 : 0.8);
    EXPECT_LT(s.rmse_px, 0.4);
  }
}

TEST(Frames, VideoFileAndRangeAndRoi) {
  SynthOptions o;
  o.frames = 12;
  SynthResult truth;
  const fs::path dir = synthetic("synth-video", o, truth);
  const fs::path avi = dir / "video.avi";
  {
    cv::VideoWriter w(avi.string(), cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 10, cv::Size(o.width, o.height), false);
    ASSERT_TRUE(w.isOpened());
    for (const auto& f : truth.frames) w.write(cv::imread(f, cv::IMREAD_GRAYSCALE));
  }
  FrameSource all(avi.string());
  cv::Mat f;
  int index = 0, n = 0;
  while (all.next(f, index)) ++n;
  EXPECT_EQ(n, 12);
  FrameSource part(avi.string(), cv::Rect(10, 20, 100, 50), FrameRange{2, 9, 3});
  std::vector<int> seen;
  while (part.next(f, index)) {
    seen.push_back(index);
    EXPECT_EQ(f.cols, 100);
    EXPECT_EQ(f.rows, 50);
  }
  EXPECT_EQ(seen, (std::vector<int>{2, 5, 8}));
  // The same frames from the PNG folder and from the video agree up to JPEG loss.
  FrameSource png((dir / "frames").string()), vid(avi.string());
  cv::Mat a, b;
  png.next(a, index);
  vid.next(b, index);
  EXPECT_LT(cv::norm(a, b, cv::NORM_L1) / a.total(), 0.02);
}

TEST(Pipeline, StuckParticlesAreFoundInTheBackground) {
  SynthOptions o;
  o.frames = 40;
  o.seed = 5;
  o.immobile = 6;
  SynthResult truth;
  const fs::path dir = synthetic("synth-stuck", o, truth);
  TrackConfig c;
  c.detect.find_stuck = true;
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  // Every particle stuck from the start is found (within 1 px) ...
  int found = 0;
  for (auto id : truth.immobile_ids) {
    const auto t = std::find_if(truth.truth.points.begin(), truth.truth.points.end(), [&](const TrackPoint& p) { return p.particle == id; });
    for (const auto& p : run.tracks.points)
      if (p.frame == 0 && std::hypot(p.x_px - t->x_px, p.y_px - t->y_px) < 1.0) {
        ++found;
        break;
      }
  }
  EXPECT_EQ(found, 6);
  // ... and scored against the whole truth, stuck ones included, the tracks stay good.
  EXPECT_GT(scoreTracks(truth.truth, run.tracks).jaccard_points, 0.9);
}

TEST(Statistics, BrownianDiffusionFromTheMsd) {
  // 300 free Brownian particles, D = 0.5 um^2/s, dt = 0.1 s, 100 steps: MSD = 4 D t.
  std::mt19937_64 rng(9);
  const double D = 0.5e-12, dt = 0.1;
  std::normal_distribution<double> step(0, std::sqrt(2 * D * dt));
  Tracks t;
  for (int p = 0; p < 300; ++p) {
    double x = 1e-4, y = 1e-4;
    for (int f = 0; f < 100; ++f) {
      TrackPoint q;
      q.frame = f;
      q.particle = p;
      q.t = f * dt;
      q.x = x;
      q.y = y;
      t.points.push_back(q);
      x += step(rng);
      y += step(rng);
    }
  }
  TrackOptions o;
  o.immobile_distance = 0;  // every particle counts
  const TrackStats s = analyseTracks(t, o);
  std::printf("Brownian: D linear %.4g, D power %.4g um^2/s, alpha %.3f\n", s.msd.d_linear * 1e12, s.msd.d_power * 1e12, s.msd.alpha);
  EXPECT_NEAR(s.msd.d_linear, D, 0.05 * D);
  EXPECT_NEAR(s.msd.alpha, 1.0, 0.05);
}

TEST(Pipeline, UniformFlowVelocityWithinOnePercent) {
  SynthOptions o;
  o.grains = 0;  // no grains: the flow is uniform, 3 px per frame
  o.frames = 30;
  o.immobile = 0;
  o.deposit_fraction = 0;
  o.speed = 3.0;
  o.fps = 10;
  SynthResult truth;
  const fs::path dir = synthetic("synth-uniform", o, truth);
  TrackConfig c;
  c.fps = o.fps;
  c.pixel_size = o.pixel_size;
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  const TrackStats s = analyseTracks(run.tracks, c.analysis);
  double vx = 0;
  for (const auto& st : s.steps) vx += st.vx;
  vx /= static_cast<double>(s.steps.size());
  EXPECT_NEAR(vx, 30e-6, 0.01 * 30e-6);  // 3 px/frame x 10 frames/s x 1 um/px
  // Dispersion against the truth's, frame by frame (Eq. 18).
  const TrackStats ts = analyseTracks(truth.truth, c.analysis);
  EXPECT_NEAR(s.sigma_y, ts.sigma_y, 0.05 * ts.sigma_y);
}

TEST(Frames, BadInputsAreNamed) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / "bad-frames";
  fs::remove_all(d);
  fs::create_directories(d / "empty");
  EXPECT_THROW(FrameSource((d / "empty").string()), InputError);
  fs::create_directories(d / "sizes");
  cv::imwrite((d / "sizes" / "a.png").string(), cv::Mat(20, 30, CV_8U, cv::Scalar(100)));
  cv::imwrite((d / "sizes" / "b.png").string(), cv::Mat(25, 30, CV_8U, cv::Scalar(100)));
  FrameSource sizes((d / "sizes").string());
  cv::Mat f;
  int i = 0;
  EXPECT_TRUE(sizes.next(f, i));
  try {
    sizes.next(f, i);
    FAIL() << "expected a size error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("b.png"), std::string::npos) << e.what();
  }
  std::ofstream(d / "broken.avi") << "not a video at all";
  EXPECT_THROW(FrameSource((d / "broken.avi").string()), InputError);
  EXPECT_THROW(FrameSource((d / "none*.png").string()), InputError);
  // Blank frames: no particles, no crash, no NaN.
  fs::create_directories(d / "blank");
  for (int k = 0; k < 3; ++k) cv::imwrite((d / "blank" / ("f" + std::to_string(k) + ".png")).string(), cv::Mat(40, 40, CV_8U, cv::Scalar(128)));
  FrameSource blank((d / "blank").string());
  const TrackRun run = runTracker(blank, TrackConfig{}, true);
  EXPECT_TRUE(run.tracks.points.empty());
}

TEST(Link, GapClosingBridgesMissedFrames) {
  // One particle moving 2 px per frame, missing in frames 3 and 4.
  TrackLinker with({Linker::global, 5.0, 2, Prediction::automatic});
  TrackLinker without({Linker::global, 5.0, 0, Prediction::automatic});
  for (int f = 0; f < 8; ++f) {
    std::vector<Detection> d;
    if (f != 3 && f != 4) d.push_back({10.0 + 2 * f, 20.0, 5, 1, 1});
    with.push(f, d);
    without.push(f, d);
  }
  auto ids = [](const std::vector<LinkedPoint>& pts) {
    std::vector<std::int64_t> v;
    for (const auto& p : pts) v.push_back(p.particle);
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
    return v.size();
  };
  EXPECT_EQ(ids(with.points()), 1u);
  EXPECT_EQ(with.stats().gap_closures, 1);
  EXPECT_EQ(ids(without.points()), 2u);
}

TEST(Link, NewTracksFollowTheirNeighboursVelocity) {
  // Two lanes moving 6 px per frame along x. Lane B (y = 30) is sparse (20 px apart),
  // tracked from the start and fed at x = 0 as it leaves at x = 300. Into lane A (y = 20) a particle enters at x = 0 every frame
  // from frame 5, so its particles are 6 px apart: a particle's first link is ambiguous,
  // the newcomer appears exactly where it was (distance 0) while it moved 6 px. Without a
  // velocity of its own a new track takes the newcomer; borrowing the velocity of its
  // neighbours in lane B (10 px away) it takes itself.
  auto run = [](double neighbour_radius) {
    LinkOptions o;
    o.search_radius = 8.0;
    o.memory = 0;
    o.neighbour_radius = neighbour_radius;
    TrackLinker linker(o);
    for (int f = 0; f < 40; ++f) {
      std::vector<Detection> d;
      const auto add = [&](double x, double y) {
        Detection q;
        q.x = x;
        q.y = y;
        if (x < 300) d.push_back(q);
      };
      for (int k = 0; k < 15; ++k) add(std::fmod(20.0 * k + 6.0 * f, 300.0), 30.0);  // lane B: re-enters at x = 0
      for (int k = 5; k <= f; ++k) add(6.0 * (f - k), 20.0);      // lane A: particle k entered at frame k
      linker.push(f, d);
    }
    // Links of lane A: right when consecutive points of one track are 6 px apart along x.
    int right = 0, wrong = 0;
    const auto pts = linker.points();
    for (std::size_t i = 1; i < pts.size(); ++i)
      if (pts[i].particle == pts[i - 1].particle && pts[i].y == 20.0) (std::abs(pts[i].x - pts[i - 1].x - 6.0) < 1e-9 ? right : wrong)++;
    return std::make_pair(right, wrong);
  };
  const auto [right_n, wrong_n] = run(20.0);
  const auto [right_0, wrong_0] = run(0.0);
  std::printf("lane A: with neighbours %d right / %d wrong links; without %d / %d\n", right_n, wrong_n, right_0, wrong_0);
  EXPECT_GT(right_n, 300);
  EXPECT_EQ(wrong_n, 0);
  EXPECT_GT(wrong_0, 30);
}

TEST(Link, DenseFieldStaysLinear) {
  // 2,500 particles per frame on a lattice drifting 1 px per frame: every one linked,
  // components stay small (no combinatorial blow-up).
  TrackLinker linker({Linker::global, 3.0, 0, Prediction::automatic});
  for (int f = 0; f < 5; ++f) {
    std::vector<Detection> d;
    for (int i = 0; i < 50; ++i)
      for (int j = 0; j < 50; ++j) d.push_back({i * 8.0 + f, j * 8.0, 5, 1, 1});
    linker.push(f, d);
  }
  EXPECT_EQ(linker.stats().new_tracks, 2500);
  EXPECT_EQ(linker.stats().links, 4 * 2500);
  EXPECT_LE(linker.stats().largest_component, 4);
}

TEST(Score, PerfectAndShiftedTracks) {
  Tracks t;
  for (int p = 0; p < 3; ++p)
    for (int f = 0; f < 10; ++f) {
      TrackPoint q;
      q.frame = f;
      q.particle = p;
      q.x_px = 10 + 3 * f;
      q.y_px = 10 + 20 * p;
      t.points.push_back(q);
    }
  const Scores same = scoreTracks(t, t);
  EXPECT_DOUBLE_EQ(same.alpha, 1.0);
  EXPECT_DOUBLE_EQ(same.jaccard_points, 1.0);
  EXPECT_DOUBLE_EQ(same.jaccard_tracks, 1.0);
  Tracks shifted = t;
  for (auto& p : shifted.points) p.x_px += 1.0;  // 1 px off everywhere, gate 5: alpha = 1 - 1/5
  const Scores s = scoreTracks(t, shifted);
  EXPECT_NEAR(s.alpha, 0.8, 1e-12);
  EXPECT_NEAR(s.rmse_px, 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(s.jaccard_points, 1.0);
  Tracks half = t;
  std::erase_if(half.points, [](const TrackPoint& p) { return p.particle == 2; });
  const Scores h = scoreTracks(t, half);
  EXPECT_NEAR(h.jaccard_points, 20.0 / 30.0, 1e-12);
  EXPECT_NEAR(h.jaccard_tracks, 2.0 / 3.0, 1e-12);
}

}  // namespace
}  // namespace mmval::tracking
