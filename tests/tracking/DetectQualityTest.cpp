// Per-detection quality: sigma, eccentricity, amplitude, local background
// and localisation uncertainty of rendered Gaussian spots against the values they were
// rendered with; the uncertainty against the Cramer-Rao bound and the scatter of the
// positions over noise realisations; the focus filter; the quality columns of tracks.csv.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

struct Spot {
  double x, y, sx, sy, amplitude;  ///< px, px, principal sigmas (axis-aligned), fraction of full scale
};

/// Dark spots (the usual brightfield case) on a flat background `level`, with white
/// Gaussian noise of std `noise`; each pixel takes the spot's value at its centre.
cv::Mat render(const std::vector<Spot>& spots, int w, int h, double level, double noise, std::mt19937& rng) {
  cv::Mat f(h, w, CV_32F, cv::Scalar(level));
  for (const auto& s : spots)
    for (int y = std::max(0, static_cast<int>(s.y - 6 * s.sy)); y <= std::min(h - 1, static_cast<int>(s.y + 6 * s.sy)); ++y)
      for (int x = std::max(0, static_cast<int>(s.x - 6 * s.sx)); x <= std::min(w - 1, static_cast<int>(s.x + 6 * s.sx)); ++x) {
        const double dx = (x - s.x) / s.sx, dy = (y - s.y) / s.sy;
        f.at<float>(y, x) -= static_cast<float>(s.amplitude * std::exp(-0.5 * (dx * dx + dy * dy)));
      }
  std::normal_distribution<double> n(0, noise);
  if (noise > 0)
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) f.at<float>(y, x) += static_cast<float>(n(rng));
  return f;
}

/// The detection nearest (x, y), or nullptr beyond 1.5 px.
const Detection* nearest(const std::vector<Detection>& found, double x, double y) {
  const Detection* best = nullptr;
  double dist = 1.5;
  for (const auto& d : found)
    if (std::hypot(d.x - x, d.y - y) < dist) {
      dist = std::hypot(d.x - x, d.y - y);
      best = &d;
    }
  return best;
}

/// Spots on a grid 24 px apart (no neighbour within any measurement window), jittered
/// sub-pixel so that the pixel grid's phase varies.
std::vector<Spot> grid(int w, int h, double sx, double sy, double amplitude, std::mt19937& rng) {
  std::uniform_real_distribution<double> jitter(-0.5, 0.5);
  std::vector<Spot> s;
  for (int y = 16; y < h - 16; y += 24)
    for (int x = 16; x < w - 16; x += 24) s.push_back({x + jitter(rng), y + jitter(rng), sx, sy, amplitude});
  return s;
}

TEST(DetectQuality, SigmaEccentricityAmplitudeAndBackgroundOfRenderedSpots) {
  // Noise 0.005 of full scale (SNR 40 to 60): averaged over ~60 spots the moments' own
  // noise is well below 1 %, so the tolerances (4 % on sigma and amplitude) judge their
  // bias: the pixel sampling of a 1.2 px spot and the smoothing deconvolved.
  std::mt19937 rng(3);
  DetectOptions o;
  o.subtract_background = false;
  o.max_size_ratio = 0;  // every spot measured, none dropped
  o.deblend = false;     // an elongated spot is one spot here, not a pair to split
  for (const auto& [sx, sy, amplitude] : std::vector<std::array<double, 3>>{{1.2, 1.2, 0.2}, {2.0, 2.0, 0.3}, {3.0, 3.0, 0.3}, {2.4, 1.2, 0.3}}) {
    const auto spots = grid(240, 192, sx, sy, amplitude, rng);
    const cv::Mat frame = render(spots, 240, 192, 0.8, 0.005, rng);
    DetectOptions oo = o;
    oo.refine_radius = static_cast<int>(std::ceil(2.5 * sx));
    oo.separation = 10;
    const auto found = detect(frame, {}, Polarity::dark, oo);
    const double sigma_true = std::sqrt(0.5 * (sx * sx + sy * sy));
    const double ecc_true = std::sqrt(1 - (sy * sy) / (sx * sx));
    double sum_sigma = 0, sum_ecc = 0, sum_signal = 0, worst_bg = 0;
    int n = 0;
    for (const auto& s : spots) {
      const Detection* d = nearest(found, s.x, s.y);
      ASSERT_NE(d, nullptr) << "spot at " << s.x << ", " << s.y << " sigma " << sx << " not found";
      ASSERT_TRUE(d->quality.measured());
      sum_sigma += d->quality.sigma_px;
      sum_ecc += d->quality.eccentricity;
      sum_signal += d->quality.signal;
      worst_bg = std::max(worst_bg, std::abs(d->quality.background - 0.8));
      EXPECT_NEAR(d->quality.mass, d->mass, 1e-12);
      ++n;
    }
    const double sigma = sum_sigma / n, ecc = sum_ecc / n, signal = sum_signal / n;
    std::printf("spots sigma %.2f x %.2f px, amplitude %.2f: measured sigma %.3f px (true %.3f), eccentricity %.3f (true %.3f), signal %.4f, "
                "worst background error %.4f, over %d spots\n",
                sx, sy, amplitude, sigma, sigma_true, ecc, ecc_true, signal, worst_bg, n);
    EXPECT_NEAR(sigma, sigma_true, 0.04 * sigma_true);
    // Near 0 the eccentricity is biased up by noise (the square root of a small
    // difference of two noisy variances; measured 0.27 at sigma 1.2 px, amplitude 40 noise
    // std): round spots are judged by a bound, elongated ones by their value.
    if (ecc_true == 0)
      EXPECT_LT(ecc, 0.35);
    else
      EXPECT_NEAR(ecc, ecc_true, 0.05);
    EXPECT_NEAR(signal, amplitude, 0.04 * amplitude);
    EXPECT_LT(worst_bg, 0.01);  // two noise std: the ring's median over ~100 pixels is much closer
  }
}

TEST(DetectQuality, LocalisationUncertaintyIsTheCramerRaoBoundAndBoundsTheScatter) {
  // Round spots, sigma 1.5 px, amplitude A = 0.1, noise b = 0.01: the bound for a Gaussian
  // spot in uniform noise is sqrt(2 / pi) b / A (s^2 + 1/12) / s^2 per axis = 0.0842 px
  // (Thompson, Larson & Webb 2002, eq. 17, background term, with Mortensen et al.'s
  // pixelation term), derived here independently of the code. The reported ep_px must
  // be that within 10 % (b and A are measured), and the positions' actual scatter over
  // noise realisations must lie above the bound (no unbiased estimator beats it) and
  // within 1.5 x of it (the Gaussian-masked centroid is near-efficient).
  const double s = 1.5, a = 0.1, b = 0.01;
  const double bound = std::sqrt(2 / M_PI) * b / a * (s * s + 1.0 / 12) / (s * s);
  DetectOptions o;
  o.subtract_background = false;
  o.max_size_ratio = 0;
  o.separation = 10;
  o.refine_sigma = s;
  std::mt19937 rng(11);
  double se = 0, sum_ep = 0, sum_sigma = 0, sum_sigma2 = 0;
  int n = 0;
  for (int rep = 0; rep < 6; ++rep) {
    const auto spots = grid(240, 192, s, s, a, rng);
    const cv::Mat frame = render(spots, 240, 192, 0.7, b, rng);
    const auto found = detect(frame, {}, Polarity::dark, o);
    for (const auto& sp : spots) {
      const Detection* d = nearest(found, sp.x, sp.y);
      ASSERT_NE(d, nullptr);
      se += 0.5 * ((d->x - sp.x) * (d->x - sp.x) + (d->y - sp.y) * (d->y - sp.y));
      sum_ep += d->quality.ep_px;
      sum_sigma += d->quality.sigma_px;
      sum_sigma2 += d->quality.sigma_px * d->quality.sigma_px;
      ++n;
    }
  }
  const double rms = std::sqrt(se / n), ep = sum_ep / n;
  const double sigma_sd = std::sqrt(std::max(0.0, sum_sigma2 / n - (sum_sigma / n) * (sum_sigma / n)));
  std::printf("localisation: bound %.4f px, reported ep %.4f px, measured scatter %.4f px per axis over %d spots; sigma %.4f +- %.4f px\n", bound, ep,
              rms, n, sum_sigma / n, sigma_sd);
  EXPECT_NEAR(ep, bound, 0.1 * bound);
  // The scatter's own statistical error over ~n spots x 2 axes is ~1/sqrt(2 n) ~ 3 %.
  EXPECT_GT(rms, 0.93 * bound);
  EXPECT_LT(rms, 1.5 * bound);
  // The focus filter takes ep_px as the standard error of a measured sigma: the width's
  // Cramer-Rao bound with the amplitude fitted is of that order. Measured here, the
  // spread of the measured sigmas must be within a factor 1.5 of ep either way.
  EXPECT_GT(sigma_sd, ep / 1.5);
  EXPECT_LT(sigma_sd, 1.5 * ep);
  EXPECT_NEAR(sum_sigma / n, s, 0.02 * s);
}

TEST(DetectQuality, FocusFilterDropsBlurredSpotsAndKeepsTheInFocusOnes) {
  // 40 in-focus spots (sigma 1.3 px) and 12 out of focus (sigma 3 px, the same integrated
  // light: amplitude x (1.3 / 3)^2): the modal sigma is the in-focus one, and the default
  // ratio 1.5 drops exactly the blurred spots; off (0), all are kept.
  std::mt19937 rng(5);
  std::vector<Spot> spots;
  int k = 0;
  for (int y = 20; y < 192 - 16; y += 30)
    for (int x = 20; x < 300 - 16; x += 30) {
      const bool blurred = (k++ % 9) < 2;  // scattered among the sharp ones
      const double sg = blurred ? 3.0 : 1.3;
      spots.push_back({x + 0.3, y - 0.2, sg, sg, 0.3 * (1.3 / sg) * (1.3 / sg)});
    }
  const cv::Mat frame = render(spots, 300, 192, 0.8, 0.004, rng);
  DetectOptions o;
  o.subtract_background = false;
  o.separation = 10;
  o.refine_radius = 5;
  ASSERT_GT(DetectOptions{}.max_size_ratio, 0.0) << "the focus filter is on by default";
  const auto on = detect(frame, {}, Polarity::dark, o);
  DetectOptions off = o;
  off.max_size_ratio = 0;
  const auto all = detect(frame, {}, Polarity::dark, off);
  int sharp_kept = 0, blurred_kept = 0, sharp = 0, blurred = 0, blurred_found_off = 0;
  for (const auto& s : spots) {
    const bool is_blurred = s.sx > 2;
    (is_blurred ? blurred : sharp) += 1;
    if (nearest(on, s.x, s.y)) (is_blurred ? blurred_kept : sharp_kept) += 1;
    if (is_blurred && nearest(all, s.x, s.y)) ++blurred_found_off;
  }
  std::printf("focus filter: %d of %d in-focus spots kept, %d of %d blurred (filter off: %d of them found, %zu detections)\n", sharp_kept, sharp,
              blurred_kept, blurred, blurred_found_off, all.size());
  EXPECT_GE(blurred, 10);
  EXPECT_EQ(blurred_found_off, blurred);  // the detector finds them: the filter is what drops them
  EXPECT_EQ(sharp_kept, sharp);
  EXPECT_EQ(blurred_kept, 0);
  EXPECT_EQ(all.size(), spots.size());
}

TEST(DetectQuality, FocusFilterNeedsEnoughSpotsToJudge) {
  // Below kFocusMinSpots spots the modal sigma is not judged: a lone blurred spot stays.
  std::mt19937 rng(9);
  const std::vector<Spot> spots = {{30, 30, 1.3, 1.3, 0.3}, {70, 30, 1.3, 1.3, 0.3}, {50, 70, 3.5, 3.5, 0.1}};
  const cv::Mat frame = render(spots, 100, 100, 0.8, 0.003, rng);
  DetectOptions o;
  o.subtract_background = false;
  o.separation = 10;
  o.deblend = false;  // the joint fit would cut the large spot into pieces
  EXPECT_EQ(detect(frame, {}, Polarity::dark, o).size(), 3u);
  o.max_size_ratio = 0;
  EXPECT_EQ(detect(frame, {}, Polarity::dark, o).size(), 3u);
}

fs::path testFolder(const char* name) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / "detect-quality" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

TEST(DetectQuality, TracksCsvQualityColumnsRoundTripAndOldFilesStillRead) {
  const fs::path dir = testFolder("csv");
  Tracks t;
  for (int f = 0; f < 3; ++f) {
    TrackPoint p;
    p.frame = f;
    p.particle = 7;
    p.t = 0.1 * f;
    p.x = (10 + f) * 1e-6;
    p.y = 5e-6;
    if (f < 2) p.quality = {1.25 + f, 0.3, 0.12, 1.5, 0.81, 0.042};  // the last point: no measured spot
    t.points.push_back(p);
  }
  writeTracksCsv(dir / "tracks.csv", t, 1e-6);
  std::ifstream in(dir / "tracks.csv");
  std::string header, line;
  std::getline(in, header);
  EXPECT_EQ(header, "frame,particle,x,y,x_um,y_um,t_s,sigma_px,eccentricity,signal,mass,background,ep_px");
  // Every row has the header's number of fields (pandas, hence trackpy, needs no more),
  // and the unmeasured point's quality fields are empty (NaN to pandas).
  const auto fields = [](const std::string& s) { return std::count(s.begin(), s.end(), ',') + 1; };
  int rows = 0;
  std::string last;
  while (std::getline(in, line)) {
    EXPECT_EQ(fields(line), fields(header)) << line;
    last = line;
    ++rows;
  }
  EXPECT_EQ(rows, 3);
  EXPECT_EQ(last.substr(last.size() - 6), ",,,,,,");
  const Tracks back = readTracksCsv(dir / "tracks.csv");
  ASSERT_EQ(back.points.size(), 3u);
  EXPECT_NEAR(back.points[1].quality.sigma_px, 2.25, 1e-9);
  EXPECT_NEAR(back.points[0].quality.eccentricity, 0.3, 1e-9);
  EXPECT_NEAR(back.points[0].quality.signal, 0.12, 1e-9);
  EXPECT_NEAR(back.points[0].quality.mass, 1.5, 1e-9);
  EXPECT_NEAR(back.points[0].quality.background, 0.81, 1e-9);
  EXPECT_NEAR(back.points[0].quality.ep_px, 0.042, 1e-9);
  EXPECT_FALSE(back.points[2].quality.measured());
  EXPECT_NEAR(back.points[2].x, 12e-6, 1e-12);
  // A file in the schema without the quality columns reads, and so does
  // one with columns a reader does not know in between (trackpy writes its own: ecc, size,
  // raw_mass, ep) and NaN written as pandas writes it.
  std::ofstream(dir / "old.csv") << "frame,particle,x,y,x_um,y_um,t_s,state\n0,1,3.0,4.0,3.0,4.0,0,mobile\n1,1,3.5,4.0,3.5,4.0,0.1,mobile\n";
  const Tracks old = readTracksCsv(dir / "old.csv");
  ASSERT_EQ(old.points.size(), 2u);
  EXPECT_FALSE(old.points[0].quality.measured());
  EXPECT_NEAR(old.points[1].x, 3.5e-6, 1e-12);
  std::ofstream(dir / "trackpy.csv") << "y,x,mass,size,ecc,signal,raw_mass,ep,frame,particle,t_s\n"
                                        "4.0,3.0,120.5,1.9,0.05,30.2,900,0.03,0,1,0\n4.1,3.2,nan,1.8,0.04,29.0,880,nan,1,1,0.1\n";
  const Tracks tp = readTracksCsv(dir / "trackpy.csv", 1e-6);
  ASSERT_EQ(tp.points.size(), 2u);
  EXPECT_NEAR(tp.points[0].x, 3e-6, 1e-12);
  EXPECT_NEAR(tp.points[1].y, 4.1e-6, 1e-12);
  EXPECT_NEAR(tp.points[0].quality.mass, 120.5, 1e-9);
  EXPECT_TRUE(std::isnan(tp.points[1].quality.mass));
  EXPECT_FALSE(tp.points[0].quality.measured());  // trackpy's size is not our sigma_px
}

}  // namespace
}  // namespace mmval::tracking
