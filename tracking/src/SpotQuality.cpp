// Per-detection quality: the size, shape and amplitude of each spot by
// adaptive Gaussian-weighted moments, its local background, its localisation
// uncertainty, and the focus filter that drops blurred spots.
#include "SpotFit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <utility>

#include <opencv2/core/hal/intrin.hpp>

#include "DetectionGrid.hpp"
#include "Selection.hpp"

namespace mmval::tracking::detail {

double pixelNoise(const cv::Mat& img) {
  // Neighbour differences cancel everything that varies slowly over a pixel (particles,
  // illumination, the background) and keep white noise with twice its variance; their
  // median absolute value is robust to the edges of spots (a minority of the pixels).
  thread_local std::vector<float> diffs;
  diffs.clear();
  if (img.cols < 2 || img.rows < 1) return 0;
  const int row_step = std::max(1, static_cast<int>(static_cast<double>(img.rows) * img.cols / 40000));
  for (int y = 0; y < img.rows; y += row_step) {
    const float* row = img.ptr<float>(y);
    for (int x = 0; x + 1 < img.cols; ++x) diffs.push_back(std::abs(row[x + 1] - row[x]));
  }
  if (diffs.empty()) return 0;
  thread_local std::vector<float> scratch;
  return 1.4826 * kthSmallest(diffs.data(), diffs.size(), diffs.size() / 2, scratch) / std::sqrt(2.0);
}

namespace {

/// Per |dy| from 0 to r_out - 1, the ring's half-widths (wo, wi): the ring's pixels in the
/// row dy are |dx| < wo and |dx| >= wi, the same pixels as the test r_in^2 <= r2 < r_out^2.
/// Computed once per thread and ring (measureSpot asks for a few dozen rings, again and
/// again, each r_in = r_out - 2: those are looked up by r_out in a vector, the rest in a map).
const std::vector<std::pair<int, int>>& ringWidths(int r_in, int r_out) {
  constexpr int kRingWidth = 2, kDirect = 64;
  thread_local std::vector<std::vector<std::pair<int, int>>> direct(kDirect);
  const bool is_direct = r_in == r_out - kRingWidth && r_out >= 0 && r_out < kDirect;
  if (is_direct && !direct[static_cast<std::size_t>(r_out)].empty()) return direct[static_cast<std::size_t>(r_out)];
  thread_local std::map<std::pair<int, int>, std::vector<std::pair<int, int>>> tables;
  auto [it, added] = tables.try_emplace({r_in, r_out});
  if (added) {
    auto halfWidth = [](int r2_limit, int dy2) {  // smallest w >= 0 with w^2 + dy2 >= r2_limit
      int w = 0;
      if (r2_limit > dy2) w = static_cast<int>(std::sqrt(static_cast<double>(r2_limit - dy2)));
      while (w > 0 && (w - 1) * (w - 1) + dy2 >= r2_limit) --w;
      while (w * w + dy2 < r2_limit) ++w;
      return w;
    };
    for (int dy = 0; dy < r_out; ++dy) it->second.emplace_back(halfWidth(r_out * r_out, dy * dy), halfWidth(r_in * r_in, dy * dy));
  }
  if (is_direct && !it->second.empty()) direct[static_cast<std::size_t>(r_out)] = it->second;
  return it->second;
}

/// Median of the pixels of `img` in the ring r_in <= |p - (cx, cy)| < r_out (clipped to
/// the image); NaN when the ring is empty.
double ringMedian(const cv::Mat& img, int cx, int cy, int r_in, int r_out) {
  if (r_out <= 0) return std::nan("");
  // Per row, only the ring's one or two runs of columns (the box around the ring holds
  // ~12 times as many pixels for the large windows of blurred spots).
  const std::vector<std::pair<int, int>>& widths = ringWidths(r_in, r_out);
  thread_local std::vector<float> v;
  // Grown only (a vector resized down and up again would zero the regrown part each time).
  const std::size_t room = static_cast<std::size_t>(2 * r_out) * static_cast<std::size_t>(2 * r_out);
  if (v.size() < room) v.resize(room);
  float* out = v.data();
  for (int y = std::max(0, cy - r_out + 1); y <= std::min(img.rows - 1, cy + r_out - 1); ++y) {
    const float* row = img.ptr<float>(y);
    const auto [wo, wi] = widths[static_cast<std::size_t>(std::abs(y - cy))];
    // Columns cx - wo < x <= cx - wi and cx + wi <= x < cx + wo (one run when wi = 0).
    const int xa = std::max(0, cx - wo + 1), xd = std::min(img.cols - 1, cx + wo - 1);
    if (wi == 0) {
      for (int x = xa; x <= xd; ++x) *out++ = row[x];
      continue;
    }
    for (int x = xa, end = std::min(xd, cx - wi); x <= end; ++x) *out++ = row[x];
    for (int x = std::max(xa, cx + wi); x <= xd; ++x) *out++ = row[x];
  }
  const std::size_t n = static_cast<std::size_t>(out - v.data());
  if (n == 0) return std::nan("");
  thread_local std::vector<float> scratch;
  return kthSmallest(v.data(), n, n / 2, scratch);
}

/// Symmetric 2 x 2 matrix [a b; b c].
struct Sym2 {
  double a = 0, b = 0, c = 0;
  double det() const { return a * c - b * b; }
  Sym2 inverse() const {
    const double d = det();
    return {c / d, -b / d, a / d};
  }
  /// Eigenvalues, larger first.
  std::array<double, 2> eigen() const {
    const double h = 0.5 * (a + c), r = std::sqrt(0.25 * (a - c) * (a - c) + b * b);
    return {h + r, h - r};
  }
};

/// Sums of the Gaussian-weighted moments over a window (see measureSpot).
struct WindowMoments {
  double s0 = 0, sxx = 0, syy = 0, sxy = 0;
};

/// The moments of (img - level) under the separable mask ex(x - cx + r) ey(y - cy + r)
/// over the window of half-width r around (cx, cy) (clipped to the image), about (mx, my).
/// Each row is summed along x in single precision, four columns at a time in the lanes of
/// a float vector (a row holds at most 75 pixels of a few hundredths each: its sums keep
/// ~6 significant digits, the moments' relative error ~1e-6, far below what the mask
/// iteration's 1 % convergence and the pixel noise leave), then the rows in double
/// precision, in order. The same arithmetic whatever the thread: the sums are reproducible.
WindowMoments windowMoments(const cv::Mat& img, int cx, int cy, int r, double mx, double my, double level, const float* ex, const float* ey) {
  WindowMoments m;
  const int x0 = std::max(0, cx - r), x1 = std::min(img.cols - 1, cx + r);
  const int y0 = std::max(0, cy - r), y1 = std::min(img.rows - 1, cy + r);
  if (x1 < x0) return m;
  const int n = x1 - x0 + 1;
  float dxs[2 * 37 + 1], mask[2 * 37 + 1];  // per column: offset from mx, mask weight
  for (int k = 0; k < n; ++k) {
    dxs[k] = static_cast<float>((x0 + k) - mx);
    mask[k] = ex[x0 + k - cx + r];
  }
  const float flevel = static_cast<float>(level);
  const int n4 = n & ~3;
  const cv::v_float32x4 vlevel = cv::v_setall_f32(flevel);
  for (int y = y0; y <= y1; ++y) {
    const float* row = img.ptr<float>(y) + x0;
    cv::v_float32x4 vw = cv::v_setzero_f32(), vx = vw, vxx = vw;
    for (int k = 0; k < n4; k += 4) {
      const cv::v_float32x4 dx = cv::v_load(dxs + k);
      const cv::v_float32x4 w = (cv::v_load(row + k) - vlevel) * cv::v_load(mask + k);
      const cv::v_float32x4 wdx = w * dx;
      vw = vw + w;
      vx = vx + wdx;
      vxx = vxx + wdx * dx;
    }
    float rw = cv::v_reduce_sum(vw), rx = cv::v_reduce_sum(vx), rxx = cv::v_reduce_sum(vxx);
    for (int k = n4; k < n; ++k) {
      const float w = (row[k] - flevel) * mask[k], wdx = w * dxs[k];
      rw += w;
      rx += wdx;
      rxx += wdx * dxs[k];
    }
    const double wy = ey[y - cy + r], dy = y - my;
    m.s0 += rw * wy;
    m.sxx += rxx * wy;
    m.syy += rw * wy * dy * dy;
    m.sxy += rx * wy * dy;
  }
  return m;
}

constexpr double kFocusSignificance = 3;  ///< standard errors of a sigma beyond the focus limit
constexpr double kFocusRoundness = 0.6;   ///< largest eccentricity of a spot judged blurred (principal axes 0.8:1)
constexpr double kFocusDim = 0.5;         ///< a wide elongated spot is blurred when its peak is below this x the in-focus median
constexpr double kMaxMaskSigma = 12;  ///< px: larger spots are measured as this large (a 73 px window)
constexpr int kMomentIterations = 8;

}  // namespace

void measureSpot(const cv::Mat& zero_mean, const cv::Mat& frame, double sigma0, double blur, double pixel_noise, Detection& d) {
  // Adaptive Gaussian-weighted moments (Bernstein & Jarvis 2002, AJ 123:583, sec. 3.1):
  // the second moments of the spot under a round Gaussian mask of sigma m. For a
  // Gaussian spot of covariance S the weighted covariance is V = (S^-1 + I / m^2)^-1,
  // so S = (V^-1 - I / m^2)^-1 whatever m, and the weighted sum is the amplitude times
  // 2 pi sqrt(det V). The mask follows the spot's own size (m^2 = trace(S) / 2), which
  // weighs the pixels about as a least-squares fit would; the spot is measured on the
  // smoothed signal (its noise is lower), whose spot covariance is S + blur^2 I.
  const int cx = static_cast<int>(std::lround(d.x)), cy = static_cast<int>(std::lround(d.y));
  double m = std::clamp(std::sqrt(sigma0 * sigma0 + blur * blur), 0.7, kMaxMaskSigma);
  Sym2 smoothed;  // the spot's covariance in the smoothed signal
  double weighted_sum = 0, det_v = 0;
  int r = 0;
  bool ok = false;
  float ex[2 * 37 + 1], ey[2 * 37 + 1];
  // The background level per window radius it was taken for: the ring depends on r only,
  // and the iterations mostly keep r or return to an earlier one.
  std::array<std::pair<int, double>, kMomentIterations> levels;
  int n_levels = 0;
  double level = 0;
  for (int it = 0; it < kMomentIterations; ++it) {
    r = std::max(2, static_cast<int>(std::ceil(3 * m)));
    // The local background: the median of a ring just outside the window (robust to a
    // neighbour or two in it), taken off the signal before the moments.
    const auto known = std::find_if(levels.begin(), levels.begin() + n_levels, [r](const auto& e) { return e.first == r; });
    if (known != levels.begin() + n_levels) {
      level = known->second;
    } else {
      const double bg = ringMedian(zero_mean, cx, cy, r + 1, r + 3);
      level = std::isnan(bg) ? 0.0 : bg;
      levels[n_levels++] = {r, level};
    }
    const double a = 1 / (2 * m * m), c = std::exp(-2 * a);  // (gaussianRow's own c, once for both rows)
    gaussianRow(ex, 2 * r + 1, cx - r, d.x, a, c);
    gaussianRow(ey, 2 * r + 1, cy - r, d.y, a, c);
    const WindowMoments mom = windowMoments(zero_mean, cx, cy, r, d.x, d.y, level, ex, ey);
    const double s0 = mom.s0, sxx = mom.sxx, syy = mom.syy, sxy = mom.sxy;
    if (!(s0 > 0)) break;
    const Sym2 v{sxx / s0, sxy / s0, syy / s0};
    const auto ev = v.eigen();
    if (!(ev[1] > 0)) break;
    const double m2 = m * m;
    if (ev[0] >= 0.9 * m2) {
      // The spot fills the mask (or noise says so): widen it and measure again.
      if (m >= kMaxMaskSigma) break;
      m = std::min(kMaxMaskSigma, 1.5 * m);
      continue;
    }
    const Sym2 vi = v.inverse();
    smoothed = Sym2{vi.a - 1 / m2, vi.b, vi.c - 1 / m2}.inverse();
    weighted_sum = s0;
    det_v = v.det();
    ok = true;
    const double next = std::clamp(std::sqrt(0.5 * (smoothed.a + smoothed.c)), 0.7, kMaxMaskSigma);
    const bool done = std::abs(next - m) < 0.01 * m;
    m = next;
    if (done) break;
  }
  if (!ok) return;
  // The spot itself: the smoothing's variance off each axis, no narrower than a pixel's
  // own spread (1/12 px^2: a point source still covers a pixel).
  const Sym2 spot{smoothed.a - blur * blur, smoothed.b, smoothed.c - blur * blur};
  auto ev = spot.eigen();
  ev[1] = std::max(ev[1], 1.0 / 12);
  ev[0] = std::max(ev[0], ev[1]);
  const double s2 = 0.5 * (ev[0] + ev[1]);
  // Integrated signal N: the weighted sum is A_s 2 pi sqrt(det V) for the smoothed spot's
  // amplitude A_s, and N = 2 pi A_s sqrt(det S_s) (smoothing keeps the integral).
  const double n_signal = weighted_sum * std::sqrt(std::max(smoothed.det(), 0.0) / det_v);
  SpotQuality& q = d.quality;
  q.sigma_px = std::sqrt(s2);
  q.eccentricity = std::sqrt(std::max(0.0, 1 - ev[1] / ev[0]));
  q.signal = n_signal / (2 * M_PI * std::sqrt(ev[0] * ev[1]));
  if (frame.type() == CV_32F) q.background = ringMedian(frame, cx, cy, r + 1, r + 3);
  // Localisation uncertainty per axis: the Cramer-Rao bound of a Gaussian spot in
  // uniform background noise of std b per pixel, sigma_loc^2 = 8 pi s_a^4 b^2 / N^2
  // with s_a^2 = s^2 + a^2 / 12 for pixels of side a = 1 px (Thompson, Larson & Webb
  // 2002, Biophys. J. 82:2775, eq. 17, background term; Mortensen et al. 2010, Nat.
  // Methods 7:377, eq. 6, the same term with the pixelation correction). For a spot of
  // peak amplitude A this is sqrt(2 / pi) b / A: a blurred spot (larger s, lower A at the
  // same N) is localised worse as s^2. The photon (shot) term needs the camera gain,
  // which a video does not carry; where the background is bright (brightfield) its shot
  // noise is part of b.
  if (pixel_noise > 0 && n_signal > 0) {
    const double sa2 = s2 + 1.0 / 12;
    q.ep_px = std::sqrt(8 * M_PI) * sa2 * pixel_noise / n_signal;
  }
}

double halfSampleMode(std::vector<double> v) {
  // Bickel & Fruehwirth 2006 (Comput. Stat. Data Anal. 50:3500): the half of the sorted
  // sample with the smallest range, recursively; robust to a skewed tail (here the
  // blurred spots) that pulls a mean or a median.
  if (v.empty()) return std::nan("");
  std::sort(v.begin(), v.end());
  std::size_t lo = 0, n = v.size();
  while (n > 3) {
    const std::size_t h = (n + 1) / 2;
    std::size_t best = lo;
    for (std::size_t i = lo; i + h <= lo + n; ++i)
      if (v[i + h - 1] - v[i] < v[best + h - 1] - v[best]) best = i;
    lo = best;
    n = h;
  }
  if (n == 3) {
    const double left = v[lo + 1] - v[lo], right = v[lo + 2] - v[lo + 1];
    if (left < right) return 0.5 * (v[lo] + v[lo + 1]);
    if (right < left) return 0.5 * (v[lo + 1] + v[lo + 2]);
    return v[lo + 1];
  }
  return n == 2 ? 0.5 * (v[lo] + v[lo + 1]) : v[lo];
}

double focusFilter(std::vector<Detection>& dets, double max_ratio, double blur) {
  if (!(max_ratio > 0)) return std::nan("");
  std::vector<double> sizes;
  for (const auto& d : dets)
    if (d.quality.measured()) sizes.push_back(d.quality.sigma_px);
  if (static_cast<int>(sizes.size()) < kFocusMinSpots) return std::nan("");
  const double mode = halfSampleMode(sizes);
  const double limit = max_ratio * mode;
  // Blurred: the measured sigma beyond the limit by more than kFocusSignificance of its own
  // standard error. That error is about the localisation uncertainty: the Cramer-Rao bound
  // of a Gaussian spot's width, b / (A sqrt(2 pi)) with the amplitude known, grows to
  // ~ep_px when the amplitude is fitted too (measured: DetectQualityTest). On the SNR 4
  // micromodel scenes (ep ~0.2 px) a bare limit of 1.5 x the mode dropped ~4 % of the true
  // particles (JSC 0.921-0.937 against 0.970-0.981 unfiltered); with the margin of 3 errors
  // and the roundness condition below, 0.970-0.981 again.
  // Only round spots: defocus blurs a sphere's image the same way in every direction,
  // so a wide elongated spot is a blend (two particles, a particle on a grain's edge), not
  // blur. Measured on the clean sparse flow scenes (tests/tracking/TrackingValidationTest):
  // without this condition clusters of touching particles (eccentricity 0.8-1) were
  // dropped and JSC was 0.941 at SNR 20; with it, 0.989.
  // An elongated spot still counts when it is dim: defocus spreads a particle's light,
  // so its peak falls as (in-focus sigma / sigma)^2 (0.44 at the limit of 1.5), while a
  // blend of sharp particles keeps their peaks. Dim: below kFocusDim of the median peak
  // of the in-focus spots. On the synthetic Brownian slab, blurred spots in a crowd
  // overlap and look elongated; judged by roundness alone, most of them stayed.
  std::vector<double> sharp_peaks;
  for (const auto& d : dets)
    if (d.quality.measured() && d.quality.sigma_px <= limit) sharp_peaks.push_back(d.peak);
  double sharp_peak = 0;
  if (!sharp_peaks.empty()) {
    std::nth_element(sharp_peaks.begin(), sharp_peaks.begin() + static_cast<std::ptrdiff_t>(sharp_peaks.size() / 2), sharp_peaks.end());
    sharp_peak = sharp_peaks[sharp_peaks.size() / 2];
  }
  auto blurred = [&](const Detection& d) {
    return d.quality.sigma_px > limit + kFocusSignificance * d.quality.ep_px &&
           (d.quality.eccentricity < kFocusRoundness || d.peak < kFocusDim * sharp_peak);
  };
  // A sharp neighbour within the measurement window adds its light to the moments: a spot
  // beside one is measured as their pair and kept. Pieces of one blurred blob (the joint
  // fit can cut a large spot into several) are all blurred and go together.
  const double crowd = 3 * std::sqrt(mode * mode + blur * blur);
  const DetectionGrid grid(dets, crowd);
  std::vector<char> drop(dets.size(), 0);
  for (std::size_t i = 0; i < dets.size(); ++i) {
    if (!blurred(dets[i])) continue;
    bool beside_sharp = false;
    grid.near(dets[i].x, dets[i].y, crowd, [&](int j, double) { beside_sharp = beside_sharp || (j != static_cast<int>(i) && !blurred(dets[j])); });
    drop[i] = !beside_sharp;
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < dets.size(); ++i)
    if (!drop[i]) dets[kept++] = dets[i];
  dets.resize(kept);
  return mode;
}

}  // namespace mmval::tracking::detail
