// Large bright-rimmed discs: Hough proposals, rim test and circle fit (LargeDiscs.hpp).
#include "mmval/tracking/LargeDiscs.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace mmval::tracking {

namespace {

constexpr int kRays = 72;                 // rays cast from a proposed centre (5 degrees apart)
constexpr double kSearchFraction = 0.1;   // the rim is looked for within +-10 % of the radius
constexpr double kSideFraction = 0.15;    // darker ground within 15 % of the radius on each side
constexpr double kStepPx = 0.5;           // sampling step along a ray
constexpr double kRimContrast = 4;        // rim above the darker side by this many noise sigmas
constexpr double kMinRimContrast = 0.05;   // ... and at least this fraction of the frame's 1-99 % grey range
constexpr double kMinRimShare = 0.3;      // a disc keeps rim points on at least 30 % of the rays
// A rim point is on the fitted circle when within this share of the radius (at least
// kMinRimResidualPx): discs are round to a few per cent.
constexpr double kRimResidualShare = 0.04, kMinRimResidualPx = 1.5;
constexpr double kFirstResidualShare = 0.15;  // about the proposal (the Hough centre is coarse)
// Proposals are made on the frame shrunk so that the smallest radius is about this many px
// (the Hough transform's cost grows with the radii searched; the fit is at full resolution).
constexpr double kProposalRadiusPx = 20;
constexpr int kFitPasses = 3;             // rays cast again from each refitted centre
constexpr double kFirstSearchFraction = 0.25;  // the first pass, about the Hough centre (good to ~10 px)
constexpr std::size_t kMinFitPoints = 8;
// Discs do not overlap: of two fits whose centres are closer than this share of their
// summed radii, the one with fewer rim points goes (touching discs are ~1.0 apart, the
// fitted rim lying just inside each edge; 0.85 leaves room for the fits' radius error).
constexpr double kMostOverlap = 0.85;
constexpr double kRangeSlack = 0.85;      // the rim radius is looked for from 0.85 rmin to rmax / 0.85
constexpr double kInsideShares[] = {0.6, 0.7, 0.8};  // radii, in rim radii, of the interior compared
constexpr double kOutsideShare = 1.25;
constexpr int kMedianPx = 5;              // the Hough image's median filter (the source project's choice)
constexpr double kHoughDp = 2;            // accumulator at half resolution
constexpr double kCannyHigh = 100;        // on the grey range stretched to 0-255
// Accumulator threshold: this share of the votes a complete circle of the smallest radius
// casts at the accumulator's resolution (one per rim pixel, 2 pi r / dp cells).
constexpr double kHoughVoteShare = 0.25;
constexpr double kStretchLow = 0.01, kStretchHigh = 0.99;

double sample(const cv::Mat& g, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= g.cols || y0 + 1 >= g.rows) return std::nan("");
  const double fx = x - x0, fy = y - y0;
  const float* r0 = g.ptr<float>(y0);
  const float* r1 = g.ptr<float>(y0 + 1);
  return (1 - fy) * ((1 - fx) * r0[x0] + fx * r0[x0 + 1]) + fy * ((1 - fx) * r1[x0] + fx * r1[x0 + 1]);
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

/// Robust noise sigma of `g`: the MAD of g minus its 3x3 mean, over that residual's
/// factor for white noise, sqrt((8/9)^2 + 8/81) = 0.943.
double noiseSigma(const cv::Mat& g) {
  cv::Mat mean, diff;
  cv::blur(g, mean, cv::Size(3, 3));
  cv::subtract(g, mean, diff);
  std::vector<double> v;
  const int step = std::max<int>(1, static_cast<int>(diff.total() / 50000));
  const float* p = diff.ptr<float>();
  for (std::size_t i = 0; i < diff.total(); i += static_cast<std::size_t>(step)) v.push_back(p[i]);
  const double m = median(v);
  for (auto& x : v) x = std::abs(x - m);
  return 1.4826 * median(v) / 0.943;
}

struct Circle {
  double x = 0, y = 0, r = 0;
  int rim_points = 0;
  double contrast = 0;  // mean rim height above the darker side
};

/// The rim on one ray's profile `prof` (searched from index first to last, the sides
/// reaching `reach` samples): of the local maxima standing above the darkest point on the
/// inner side by `margin` (and above the outer side), the one nearest the expected radius
/// (the window's middle), not the brightest: a glint or glare inside the disc can outshine
/// its rim. -1 when none qualifies.
int rimOnRay(const std::vector<double>& prof, int first, int last, int reach, double margin, double& height) {
  const int mid = (first + last) / 2;
  int best = -1;
  for (int i = first + 1; i < last; ++i) {
    if (!(prof[i] >= prof[i - 1] && prof[i] > prof[i + 1])) continue;
    const double in_low = *std::min_element(prof.begin() + (i - reach), prof.begin() + i + 1);
    const double out_low = *std::min_element(prof.begin() + i, prof.begin() + std::min<int>(static_cast<int>(prof.size()), i + reach + 1));
    // Above the interior by the margin, and a maximum on the outside too (a neighbour's
    // touching rim may leave it only slightly darker there).
    if (prof[i] - in_low < margin || prof[i] <= out_low) continue;
    if (best < 0 || std::abs(i - mid) < std::abs(best - mid)) {
      best = i;
      height = prof[i] - in_low;
    }
  }
  return best;
}

/// Rim points along kRays rays from (cx, cy), looked for from lo to hi px out on the
/// smoothed frame `g`; r sets the sides' reach. Adds each point's height to contrast_sum.
std::vector<cv::Point2d> rimPoints(const cv::Mat& g, double cx, double cy, double lo, double hi, double r, double margin, double& contrast_sum) {
  std::vector<cv::Point2d> out;
  const double side = kSideFraction * r;
  const int n = static_cast<int>((hi - lo + 2 * side) / kStepPx) + 1;
  std::vector<double> prof(static_cast<std::size_t>(n));
  const int first = static_cast<int>(side / kStepPx), last = n - 1 - first;
  for (int k = 0; k < kRays; ++k) {
    const double a = 2 * M_PI * k / kRays, dx = std::cos(a), dy = std::sin(a);
    bool inside = true;
    for (int i = 0; i < n && inside; ++i) {
      prof[i] = sample(g, cx + (lo - side + i * kStepPx) * dx, cy + (lo - side + i * kStepPx) * dy);
      inside = !std::isnan(prof[i]);
    }
    double height = 0;
    const int best = inside ? rimOnRay(prof, first, last, first, margin, height) : -1;
    if (best < 0) continue;
    // Sub-pixel: the vertex of the parabola through the maximum and its neighbours.
    const double l = prof[best - 1], c = prof[best], rr = prof[best + 1], den = l - 2 * c + rr;
    const double shift = den < 0 ? std::clamp(0.5 * (l - rr) / den, -0.5, 0.5) : 0.0;
    const double t = lo - side + (best + shift) * kStepPx;
    out.emplace_back(cx + t * dx, cy + t * dy);
    contrast_sum += height;
  }
  return out;
}

/// Least-squares circle through `p` (Kasa): x^2 + y^2 + D x + E y + F = 0.
bool kasaFit(const std::vector<cv::Point2d>& p, Circle& c) {
  cv::Matx33d a = cv::Matx33d::zeros();
  cv::Vec3d b(0, 0, 0);
  for (const auto& q : p) {
    const cv::Vec3d row(q.x, q.y, 1);
    const double z = -(q.x * q.x + q.y * q.y);
    for (int i = 0; i < 3; ++i) {
      b[i] += row[i] * z;
      for (int j = 0; j < 3; ++j) a(i, j) += row[i] * row[j];
    }
  }
  cv::Vec3d s;
  if (p.size() < 3 || !cv::solve(a, b, s, cv::DECOMP_SVD)) return false;
  c.x = -s[0] / 2;
  c.y = -s[1] / 2;
  const double r2 = c.x * c.x + c.y * c.y - s[2];
  if (!(r2 > 0) || !std::isfinite(r2)) return false;
  c.r = std::sqrt(r2);
  return true;
}

/// Circle fitted to the rim points, starting from the circle `c` they were found on, with
/// outliers (a neighbour's rim, a glint) dropped: points off the current circle by more
/// than a wide, then the final share of its radius.
bool robustFit(std::vector<cv::Point2d>& p, Circle& c) {
  for (const double share : {kFirstResidualShare, kRimResidualShare, kRimResidualShare}) {
    const double limit = std::max(kMinRimResidualPx, share * c.r);
    std::erase_if(p, [&](const cv::Point2d& q) { return std::abs(std::hypot(q.x - c.x, q.y - c.y) - c.r) > limit; });
    if (!kasaFit(p, c)) return false;
  }
  return true;
}

/// Median over kRays rays of the brightness at distance t from (cx, cy); NaN when fewer
/// than half of the rays stay in the frame.
double ringMedian(const cv::Mat& g, double cx, double cy, double t) {
  std::vector<double> ring;
  for (int k = 0; k < kRays; ++k) {
    const double a = 2 * M_PI * k / kRays, v = sample(g, cx + t * std::cos(a), cy + t * std::sin(a));
    if (!std::isnan(v)) ring.push_back(v);
  }
  return ring.size() >= 0.5 * kRays ? median(ring) : std::nan("");
}

/// The radius (lo to hi px) where the ring median peaks (the rim, robust to a neighbour's
/// rim or a glint on a few rays), and how far that peak stands above the ring medians
/// inside (kInsideShares of it) and outside (kOutsideShare): the rim's prominence.
std::pair<double, double> rimRadius(const cv::Mat& g, double cx, double cy, double lo, double hi) {
  double best = lo, best_value = -1;
  for (double t = lo; t <= hi; t += kStepPx) {
    const double m = ringMedian(g, cx, cy, t);
    if (m > best_value) {
      best_value = m;
      best = t;
    }
  }
  double ground = ringMedian(g, cx, cy, kOutsideShare * best);
  for (double share : kInsideShares) ground = std::max(ground, ringMedian(g, cx, cy, share * best));
  return {best, std::isnan(ground) ? 0.0 : best_value - ground};
}

/// The rim test and circle fit from a proposal; false when it is not a disc in range.
/// The Hough centre is good to a few px but its radius is coarse: the rim radius is
/// where the ring median peaks over the whole range; then rim points within
/// kSearchFraction of it on every ray, a circle fitted to them, twice.
bool fitRim(const cv::Mat& g, const cv::Vec3f& proposal, double margin, double rmin, double rmax, Circle& c) {
  c.x = proposal[0];
  c.y = proposal[1];
  const auto [radius, prominence] = rimRadius(g, c.x, c.y, kRangeSlack * rmin, rmax / kRangeSlack);
  if (prominence < margin) return false;
  c.r = radius;
  std::size_t inliers = 0;
  for (int pass = 0; pass < kFitPasses; ++pass) {
    double contrast = 0;
    const double window = pass == 0 ? kFirstSearchFraction : kSearchFraction;
    std::vector<cv::Point2d> p = rimPoints(g, c.x, c.y, (1 - window) * c.r, (1 + window) * c.r, c.r, margin, contrast);
    const std::size_t found = p.size();
    if (found < kMinFitPoints || !robustFit(p, c)) return false;
    inliers = p.size();
    c.contrast = contrast / static_cast<double>(found);
  }
  c.rim_points = static_cast<int>(inliers);
  if (inliers < kMinRimShare * kRays) return false;
  return c.r >= rmin && c.r <= rmax;
}

/// The 1 % and 99 % quantiles of the grey levels of `g8`.
std::pair<int, int> greyRange(const cv::Mat& g8) {
  int hist[256] = {};
  for (int y = 0; y < g8.rows; ++y)
    for (int x = 0; x < g8.cols; ++x) ++hist[g8.at<std::uint8_t>(y, x)];
  const double total = static_cast<double>(g8.total());
  int lo = 0, hi = 255;
  for (double acc = 0; lo < 255 && (acc += hist[lo]) < kStretchLow * total;) ++lo;
  for (double acc = 0; hi > 0 && (acc += hist[hi]) < (1 - kStretchHigh) * total;) --hi;
  return {lo, std::max(lo, hi)};
}

/// Hough proposals (x, y, r in px of the frame): on the 8-bit frame shrunk by `shrink`,
/// median-filtered and stretched to its 1-99 % grey range.
std::vector<cv::Vec3f> proposals(const cv::Mat& g8, std::pair<int, int> range, double rmin, double rmax) {
  const double shrink = std::max(1.0, std::floor(rmin / kProposalRadiusPx));
  cv::Mat small, out;
  if (shrink > 1) cv::resize(g8, small, cv::Size(), 1 / shrink, 1 / shrink, cv::INTER_AREA);
  else small = g8;
  cv::medianBlur(small, small, kMedianPx);
  const double scale = range.second > range.first ? 255.0 / (range.second - range.first) : 1.0;
  small.convertTo(out, CV_8U, scale, -range.first * scale);
  const double lo = rmin / shrink, hi = rmax / shrink;
  const double votes = std::max(10.0, kHoughVoteShare * 2 * M_PI * lo / kHoughDp);
  std::vector<cv::Vec3f> found;
  cv::HoughCircles(out, found, cv::HOUGH_GRADIENT, kHoughDp, 0.5 * lo, kCannyHigh, votes, static_cast<int>(std::floor(lo)), static_cast<int>(std::ceil(hi)));
  for (auto& v : found) v *= static_cast<float>(shrink);
  return found;
}

}  // namespace

std::vector<Detection> detectDiscs(const cv::Mat& frame, double radius_min_px, double radius_max_px) {
  if (!(radius_min_px > 0 && radius_max_px >= radius_min_px && std::isfinite(radius_max_px)))
    throw std::invalid_argument(fmt::format("disc radius range {} to {} px: need 0 < min <= max", radius_min_px, radius_max_px));
  cv::Mat grey, smooth, g8;
  frame.convertTo(grey, CV_32F);
  cv::GaussianBlur(grey, smooth, cv::Size(0, 0), 1.0);
  grey.convertTo(g8, CV_8U, 255.0);
  const std::pair<int, int> range = greyRange(g8);
  const double margin = std::max(kMinRimContrast * (range.second - range.first) / 255.0, kRimContrast * noiseSigma(grey));
  const std::vector<cv::Vec3f> proposed = proposals(g8, range, radius_min_px, radius_max_px);
  std::vector<Circle> fits;
  // In the Hough transform's order (most votes first); a proposal inside a disc already
  // fitted cannot be another disc's centre (they do not overlap) and is skipped.
  for (const auto& p : proposed) {
    const bool inside = std::any_of(fits.begin(), fits.end(), [&](const Circle& k) { return std::hypot(k.x - p[0], k.y - p[1]) < k.r; });
    Circle c;
    if (!inside && fitRim(smooth, p, margin, radius_min_px, radius_max_px, c)) fits.push_back(c);
  }
  std::stable_sort(fits.begin(), fits.end(), [](const Circle& a, const Circle& b) { return a.rim_points > b.rim_points; });
  std::vector<Detection> out;
  std::vector<Circle> kept;
  for (const auto& c : fits) {
    const bool taken = std::any_of(kept.begin(), kept.end(), [&](const Circle& k) { return std::hypot(k.x - c.x, k.y - c.y) < kMostOverlap * (k.r + c.r); });
    if (taken) continue;
    kept.push_back(c);
    Detection d;
    d.x = c.x;
    d.y = c.y;
    d.area = M_PI * c.r * c.r;
    d.peak = c.contrast;
    d.mass = static_cast<double>(c.rim_points) / kRays;
    out.push_back(d);
  }
  std::sort(out.begin(), out.end(), [](const Detection& a, const Detection& b) { return a.y != b.y ? a.y < b.y : a.x < b.x; });
  return out;
}

}  // namespace mmval::tracking
