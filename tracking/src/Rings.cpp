// Ring-shaped brightfield colloids: the test that recognises them, their matched
// filter, and the radial-symmetry centre (SceneDecisions.hpp).
#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "Selection.hpp"
#include "mmval/tracking/SceneDecisions.hpp"

namespace mmval::tracking {

namespace {

// Radii of the ring test, px: the dark ring is looked for out to kMaxRingPx, the local
// level taken from the annulus kLevelInnerPx..kLevelOuterPx (beyond ring and halo).
constexpr int kMinRingPx = 2, kMaxRingPx = 20, kLevelInnerPx = 22, kLevelOuterPx = 25;
constexpr int kSectors = 16;
// Band-pass of the candidate search: a difference of Gaussians of these sigmas, px.
constexpr double kFineSigmaPx = 1, kCoarseSigmaPx = 10;
constexpr double kCandidateSigmas = 6;   // candidates: maxima above this many robust noise sigma
constexpr double kContrastSigmas = 4;    // centre and ring beyond this many noise sigma of the level
constexpr int kMaxCandidatesPerFrame = 300;
constexpr std::size_t kRingFrames = 8;
constexpr double kRelativeStrength = 0.3;

/// 1.4826 x the median absolute deviation of a CV_32F image (exact medians).
double robustStd(const cv::Mat& image) {
  if (image.empty()) return 0;
  const cv::Mat m = image.isContinuous() ? image : image.clone();
  const float* p = m.ptr<float>();
  const std::size_t n = m.total();
  std::vector<float> scratch;
  const float med = detail::kthSmallest(p, n, n / 2, scratch);
  std::vector<float> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = std::abs(p[i] - med);
  return 1.4826 * detail::kthSmallest(v.data(), n, n / 2, scratch);
}

struct RingTest {
  bool ringed = false;
  int radius = 0;
  std::vector<float> profile;  // sign * (azimuthal mean - level), r = 0 .. kLevelOuterPx
};

/// The ring test at (cx, cy) on the smoothed frame `g` with polarity `sign` (+1: bright
/// centre, dark ring).
RingTest testRing(const cv::Mat& g, int cx, int cy, double sign, double noise) {
  RingTest t;
  std::vector<double> sum(kLevelOuterPx + 1, 0.0);
  std::vector<int> count(kLevelOuterPx + 1, 0);
  std::vector<float> level_pixels;
  for (int y = cy - kLevelOuterPx; y <= cy + kLevelOuterPx; ++y)
    for (int x = cx - kLevelOuterPx; x <= cx + kLevelOuterPx; ++x) {
      const double r = std::hypot(x - cx, y - cy);
      const int b = static_cast<int>(std::lround(r));
      if (b > kLevelOuterPx) continue;
      const float v = g.at<float>(y, x);
      sum[b] += v;
      ++count[b];
      if (r >= kLevelInnerPx) level_pixels.push_back(v);
    }
  auto mid = level_pixels.begin() + static_cast<std::ptrdiff_t>(level_pixels.size() / 2);
  std::nth_element(level_pixels.begin(), mid, level_pixels.end());
  const double level = *mid;
  t.profile.resize(sum.size());
  for (std::size_t r = 0; r < sum.size(); ++r) t.profile[r] = static_cast<float>(sign * (sum[r] / std::max(1, count[r]) - level));
  int rm = kMinRingPx;
  for (int r = kMinRingPx; r <= kMaxRingPx; ++r)
    if (t.profile[r] < t.profile[rm]) rm = r;
  const double centre = t.profile[0], ring = -t.profile[rm];
  if (!(centre > kContrastSigmas * noise && ring > kContrastSigmas * noise)) return t;
  // Closed ring: every sector of the band |r - rm| <= 1 at least half as dark as the ring.
  double sector_sum[kSectors] = {};
  int sector_count[kSectors] = {};
  for (int y = cy - rm - 1; y <= cy + rm + 1; ++y)
    for (int x = cx - rm - 1; x <= cx + rm + 1; ++x) {
      const double r = std::hypot(x - cx, y - cy);
      if (std::abs(r - rm) > 1.0) continue;
      const double a = std::atan2(y - cy, x - cx) + M_PI;
      const int s = std::min(kSectors - 1, static_cast<int>(a / (2 * M_PI) * kSectors));
      sector_sum[s] += sign * (g.at<float>(y, x) - level);
      ++sector_count[s];
    }
  for (int s = 0; s < kSectors; ++s)
    if (sector_count[s] == 0 || sector_sum[s] / sector_count[s] > -0.5 * ring) return t;
  t.ringed = true;
  t.radius = rm;
  return t;
}

struct SideCount {
  int candidates = 0, ringed = 0;
  std::vector<int> radii;
  std::vector<double> profile_sum;
};

/// Candidates (maxima of sign * band-passed frame), strongest first, and their ring tests.
void countRings(const cv::Mat& g, const cv::Mat& band, double sign, double noise, SideCount& out) {
  cv::Mat s = sign * band, dil;
  cv::dilate(s, dil, cv::Mat());
  struct Peak {
    int x, y;
    float v;
  };
  std::vector<Peak> peaks;
  const int border = kLevelOuterPx + 1;
  for (int y = border; y < s.rows - border; ++y)
    for (int x = border; x < s.cols - border; ++x) {
      const float v = s.at<float>(y, x);
      if (v > kCandidateSigmas * noise && v >= dil.at<float>(y, x)) peaks.push_back({x, y, v});
    }
  std::sort(peaks.begin(), peaks.end(), [](const Peak& a, const Peak& b) { return a.v > b.v; });
  if (peaks.size() > kMaxCandidatesPerFrame) peaks.resize(kMaxCandidatesPerFrame);
  // Only maxima of the strength of the strongest count: weak ones are halos, noise or
  // the tails of objects at the border.
  if (!peaks.empty()) std::erase_if(peaks, [&](const Peak& p) { return p.v < kRelativeStrength * peaks.front().v; });
  // A ring's own halo and a candidate's near twins are not new candidates.
  std::vector<std::pair<cv::Point, int>> taken;  // centre, exclusion radius
  for (const Peak& p : peaks) {
    bool near = false;
    for (const auto& [c, r] : taken) near = near || (p.x - c.x) * (p.x - c.x) + (p.y - c.y) * (p.y - c.y) <= r * r;
    if (near) continue;
    const RingTest t = testRing(g, p.x, p.y, sign, noise);
    ++out.candidates;
    if (t.ringed) {
      ++out.ringed;
      out.radii.push_back(t.radius);
      out.profile_sum.resize(t.profile.size(), 0.0);
      for (std::size_t r = 0; r < t.profile.size(); ++r) out.profile_sum[r] += t.profile[r];
      taken.push_back({{p.x, p.y}, 2 * t.radius + 2});  // the ring, its halo and beyond
    } else {
      taken.push_back({{p.x, p.y}, 3});
    }
  }
}

}  // namespace

RingGuess guessRings(const std::vector<cv::Mat>& frames) {
  RingGuess guess;
  SideCount bright, dark;
  const std::size_t n = std::min(frames.size(), kRingFrames);
  // Each frame's band-pass and noise in parallel (independent); the candidates are counted
  // in frame order, so the profile sums add up in the same order whatever the threads.
  struct Filtered {
    cv::Mat g, band;
    double noise = 0;
  };
  std::vector<Filtered> filtered(n);
  cv::parallel_for_(cv::Range(0, static_cast<int>(n)), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      const cv::Mat& raw = frames[static_cast<std::size_t>(k) * frames.size() / n];
      if (raw.rows <= 2 * kLevelOuterPx + 2 || raw.cols <= 2 * kLevelOuterPx + 2) continue;
      Filtered& out = filtered[static_cast<std::size_t>(k)];
      cv::Mat f, coarse;
      raw.convertTo(f, CV_32F);
      cv::GaussianBlur(f, out.g, cv::Size(0, 0), kFineSigmaPx);
      cv::GaussianBlur(f, coarse, cv::Size(0, 0), kCoarseSigmaPx);
      out.band = out.g - coarse;
      // Noise of the smoothed frame: robust std of what the coarse blur leaves (an upper
      // bound where particles are dense, which makes the test stricter).
      out.noise = std::max(1e-6, robustStd(out.band));
    }
  });
  for (const Filtered& f : filtered) {
    if (f.band.empty()) continue;
    countRings(f.g, f.band, +1, f.noise, bright);
    countRings(f.g, f.band, -1, f.noise, dark);
  }
  guess.candidates = bright.candidates;
  guess.ringed = bright.ringed;
  guess.dark_ringed = dark.ringed;
  guess.share = bright.candidates > 0 ? static_cast<double>(bright.ringed) / bright.candidates : 0.0;
  if (!bright.radii.empty()) {
    std::vector<int> r = bright.radii;
    std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
    guess.radius_px = r[r.size() / 2];
    for (double v : bright.profile_sum) guess.profile.push_back(static_cast<float>(v / bright.ringed));
  }
  guess.rings = bright.ringed >= 3 && guess.share >= 0.5 && bright.ringed > 2 * dark.ringed;
  guess.reason = guess.rings
                     ? fmt::format("{} of {} bright spots are bright centres inside a closed dark ring of radius {:g} px (dark-centred rings: {}): "
                                   "ring-shaped brightfield colloids, detected by a matched filter of their mean profile",
                                   bright.ringed, bright.candidates, guess.radius_px, dark.ringed)
                     : fmt::format("{} of {} bright spots lie inside a closed dark ring (rings need >= 3, half of them, and more than twice the "
                                   "{} dark-centred ones): not ring colloids",
                                   bright.ringed, bright.candidates, dark.ringed);
  return guess;
}

cv::Mat ringKernel(const std::vector<float>& measured, double radius_px) {
  std::vector<float> profile = measured;
  const double radius = std::max(2.0, radius_px);
  if (profile.size() < 3) {
    const double sc = radius / 3, w = radius / 5;
    profile.clear();
    for (int r = 0; r <= static_cast<int>(std::ceil(1.6 * radius)) + 1; ++r)
      profile.push_back(static_cast<float>(std::exp(-r * r / (2 * sc * sc)) - std::exp(-(r - radius) * (r - radius) / (2 * w * w))));
  }
  // Out to the halo beyond the ring (1.5 R + 2), within the measured profile.
  const int k = std::min(static_cast<int>(profile.size()) - 1, static_cast<int>(std::ceil(1.5 * radius)) + 2);
  auto at = [&](double r) {
    const int i = std::min(static_cast<int>(r), k - 1);
    const double f = std::clamp(r - i, 0.0, 1.0);
    return (1 - f) * profile[i] + f * profile[i + 1];
  };
  cv::Mat kernel(2 * k + 1, 2 * k + 1, CV_32F, cv::Scalar(0));
  double sum = 0;
  int n = 0;
  for (int y = -k; y <= k; ++y)
    for (int x = -k; x <= k; ++x) {
      const double r = std::hypot(x, y);
      if (r > k) continue;
      kernel.at<float>(y + k, x + k) = static_cast<float>(at(r));
      sum += at(r);
      ++n;
    }
  const double mean = sum / n;
  double ss = 0;
  for (int y = -k; y <= k; ++y)
    for (int x = -k; x <= k; ++x)
      if (std::hypot(x, y) <= k) {
        float& v = kernel.at<float>(y + k, x + k);
        v = static_cast<float>(v - mean);
        ss += v * v;
      }
  const double contrast = profile[0] - *std::min_element(profile.begin(), profile.begin() + k + 1);
  if (ss > 0) kernel *= contrast / ss;
  return kernel;
}

void radialSymmetryCentre(const cv::Mat& image, double radius_px, Detection& d) {
  const double reach = std::max(2.0, radius_px) + 1.5;
  double cx = d.x, cy = d.y;
  for (int it = 0; it < 3; ++it) {
    const int x0 = std::max(0, static_cast<int>(std::floor(cx - reach))), x1 = std::min(image.cols - 2, static_cast<int>(std::ceil(cx + reach)));
    const int y0 = std::max(0, static_cast<int>(std::floor(cy - reach))), y1 = std::min(image.rows - 2, static_cast<int>(std::ceil(cy + reach)));
    double a11 = 0, a12 = 0, a22 = 0, b1 = 0, b2 = 0;
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        // Gradient at the half-pixel (x + 1/2, y + 1/2) from its four pixels.
        const double p00 = image.at<float>(y, x), p01 = image.at<float>(y, x + 1), p10 = image.at<float>(y + 1, x), p11 = image.at<float>(y + 1, x + 1);
        const double gx = 0.5 * ((p01 - p00) + (p11 - p10)), gy = 0.5 * ((p10 - p00) + (p11 - p01));
        const double g2 = gx * gx + gy * gy;
        const double px = x + 0.5, py = y + 0.5, dist = std::hypot(px - cx, py - cy);
        if (g2 <= 0 || dist > reach) continue;
        // Unit normal of the gradient line; the point c lies on it when n . (c - p) = 0.
        const double nx = -gy / std::sqrt(g2), ny = gx / std::sqrt(g2);
        const double w = g2 / std::max(0.5, dist);
        const double np = nx * px + ny * py;
        a11 += w * nx * nx;
        a12 += w * nx * ny;
        a22 += w * ny * ny;
        b1 += w * nx * np;
        b2 += w * ny * np;
      }
    const double det = a11 * a22 - a12 * a12;
    if (!(det > 1e-12 * (a11 + a22) * (a11 + a22))) return;
    const double nx = (a22 * b1 - a12 * b2) / det, ny = (a11 * b2 - a12 * b1) / det;
    if (!(std::hypot(nx - d.x, ny - d.y) <= 0.5 * std::max(2.0, radius_px))) return;
    const bool done = std::hypot(nx - cx, ny - cy) < 1e-3;
    cx = nx;
    cy = ny;
    if (done) break;
  }
  d.x = cx;
  d.y = cy;
}

}  // namespace mmval::tracking
