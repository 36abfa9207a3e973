// Per-detection quality: the size, shape and amplitude of each spot by
// adaptive Gaussian-weighted moments, its local background, its localisation
// uncertainty, and the focus filter that drops blurred spots.
#include "SpotFit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <map>
#include <utility>

#include <opencv2/core/hal/intrin.hpp>

#include "DetectionGrid.hpp"
#include "Selection.hpp"
#include "Simd.hpp"
#include "SimdKernels.hpp"

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

#if MMVAL_HAVE_AVX2
/// Per 8-bit mask, a permutation of 8 lanes that puts the lanes whose bit is set first,
/// in order: AVX2 has no compress instruction, so a vectorised partition packs the values
/// it keeps through such a table.
struct PackTable {
  alignas(32) std::int32_t lanes[256][8];
  PackTable() {
    for (int m = 0; m < 256; ++m) {
      int j = 0;
      for (int b = 0; b < 8; ++b)
        if ((m >> b) & 1) lanes[m][j++] = b;
      for (int b = 0; b < 8; ++b)
        if (!((m >> b) & 1)) lanes[m][j++] = b;
    }
  }
};

/// The value std::nth_element would put at position k of v[0, n) (kthSmallest's
/// contract: finite values, k < n; the k-th smallest, exactly), for CPUs with AVX2 and
/// POPCNT: quickselect whose partitions take 8 values at a time, each pass splitting the
/// values below and above a pivot (the median of three of them) into two buffers; the
/// pivot's equals are counted, so every pass removes the pivot and the selection ends
/// (equal values are interchangeable: of -0 and +0 either may be returned). For ring
/// medians (~100-300 values) it takes under half of kthSmallest's instructions, whose
/// histogram counts one value at a time (bench/tracking/README.md, stop 46).
MMVAL_TARGET_AVX2_POPCNT float quickselectAvx2(const float* v, std::size_t n, std::size_t k, std::vector<float>& scratch) {
  static const PackTable table;
  const std::size_t cap = n + 8;  // a partition writes whole vectors of 8
  if (scratch.size() < 3 * cap) scratch.resize(3 * cap);
  float* buf[3] = {scratch.data(), scratch.data() + cap, scratch.data() + 2 * cap};
  const float* in = v;
  int free_a = 0, free_b = 1;  // the buffers the next pass writes (the third holds `in`, or v does)
  while (n > 16) {
    const float a = in[n / 4], b = in[n / 2], c = in[3 * n / 4];
    const float p = std::max(std::min(a, b), std::min(std::max(a, b), c));
    float* lt = buf[free_a];
    float* gt = buf[free_b];
    std::size_t nlt = 0, ngt = 0, i = 0;
    const __m256 vp = _mm256_set1_ps(p);
    for (; i + 8 <= n; i += 8) {
      const __m256 x = _mm256_loadu_ps(in + i);
      const unsigned mlt = static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(x, vp, _CMP_LT_OQ)));
      const unsigned mgt = static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(x, vp, _CMP_GT_OQ)));
      _mm256_storeu_ps(lt + nlt, _mm256_permutevar8x32_ps(x, _mm256_load_si256(reinterpret_cast<const __m256i*>(table.lanes[mlt]))));
      _mm256_storeu_ps(gt + ngt, _mm256_permutevar8x32_ps(x, _mm256_load_si256(reinterpret_cast<const __m256i*>(table.lanes[mgt]))));
      nlt += static_cast<std::size_t>(_mm_popcnt_u32(mlt));
      ngt += static_cast<std::size_t>(_mm_popcnt_u32(mgt));
    }
    for (; i < n; ++i) {
      if (in[i] < p) lt[nlt++] = in[i];
      else if (in[i] > p) gt[ngt++] = in[i];
    }
    const std::size_t neq = n - nlt - ngt;
    const int held = 3 - free_a - free_b;  // the buffer `in` is in (when not v): free now
    if (k < nlt) {
      in = lt;
      n = nlt;
      free_a = free_b;
    } else if (k < nlt + neq) {
      return p;
    } else {
      k -= nlt + neq;
      in = gt;
      n = ngt;
    }
    free_b = held;
  }
  float tail[16];
  std::copy(in, in + n, tail);
  std::nth_element(tail, tail + k, tail + n);
  return tail[k];
}
#endif  // MMVAL_HAVE_AVX2

/// Median of the pixels of `img` in the ring r_in <= |p - (cx, cy)| < r_out (clipped to
/// the image); NaN when the ring is empty.
double ringMedian(const cv::Mat& img, int cx, int cy, int r_in, int r_out) {
  if (r_out <= 0) return std::nan("");
  // Per row, only the ring's one or two runs of columns (the box around the ring holds
  // ~12 times as many pixels for the large windows of blurred spots).
  const std::vector<std::pair<int, int>>& widths = ringWidths(r_in, r_out);
  thread_local std::vector<float> v;
  // Grown only (a vector resized down and up again would zero the regrown part each time);
  // 4 floats of slack for the last run's whole group of 4.
  const std::size_t room = static_cast<std::size_t>(2 * r_out) * static_cast<std::size_t>(2 * r_out) + 4;
  if (v.size() < room) v.resize(room);
  float* out = v.data();
  const int cols = img.cols;
  // Columns a..b of `row`, in order: 4 at a time where whole groups of 4 stay in the row
  // (the group past b is overwritten by the next run; most runs are the ring's 2-3 px).
  auto copyRun = [&out, cols](const float* row, int a, int b) {
    const int len = b - a + 1;
    if (len <= 0) return;
    if (a + ((len + 3) & ~3) <= cols) {
      for (int j = 0; j < len; j += 4) std::memcpy(out + j, row + a + j, 4 * sizeof(float));
    } else {
      for (int j = 0; j < len; ++j) out[j] = row[a + j];
    }
    out += len;
  };
  for (int y = std::max(0, cy - r_out + 1); y <= std::min(img.rows - 1, cy + r_out - 1); ++y) {
    const float* row = img.ptr<float>(y);
    const auto [wo, wi] = widths[static_cast<std::size_t>(std::abs(y - cy))];
    // Columns cx - wo < x <= cx - wi and cx + wi <= x < cx + wo (one run when wi = 0).
    const int xa = std::max(0, cx - wo + 1), xd = std::min(cols - 1, cx + wo - 1);
    if (wi == 0) {
      copyRun(row, xa, xd);
      continue;
    }
    copyRun(row, xa, std::min(xd, cx - wi));
    copyRun(row, std::max(xa, cx + wi), xd);
  }
  const std::size_t n = static_cast<std::size_t>(out - v.data());
  if (n == 0) return std::nan("");
  thread_local std::vector<float> scratch;
#if MMVAL_HAVE_AVX2
  if (cpuHasAvx2Popcnt()) return quickselectAvx2(v.data(), n, n / 2, scratch);
#endif
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

/// One window row's columns past the vector part [n4, n) added to its lane sums (rw, rx, rxx),
/// then the row's weighted sums into the moments in double precision: the scalar part every
/// windowMoments path shares, so each gives the same bits.
inline void addRowMoments(WindowMoments& m, const float* row, int n4, int n, const float* dxs, const float* mask, float flevel, double wy,
                          double dy, float rw, float rx, float rxx) {
  for (int k = n4; k < n; ++k) {
    const float w = (row[k] - flevel) * mask[k], wdx = w * dxs[k];
    rw += w;
    rx += wdx;
    rxx += wdx * dxs[k];
  }
  m.s0 += rw * wy;
  m.sxx += rxx * wy;
  m.syy += rw * wy * dy * dy;
  m.sxy += rx * wy * dy;
}

/// Sums of the Gaussian-weighted moments over a window (see measureSpot).
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
    addRowMoments(m, row, n4, n, dxs, mask, flevel, ey[y - cy + r], y - my, cv::v_reduce_sum(vw), cv::v_reduce_sum(vx), cv::v_reduce_sum(vxx));
  }
  return m;
}

#if MMVAL_HAVE_AVX2
/// Per 128-bit half of `v`, v_reduce_sum's sum of the half's 4 lanes, in its lane 0:
/// (l0 + l2) + (l1 + l3).
MMVAL_TARGET_AVX2 inline __m256 reduceHalves(__m256 v) {
  v = _mm256_add_ps(v, _mm256_castsi256_ps(_mm256_srli_si256(_mm256_castps_si256(v), 8)));
  return _mm256_add_ps(v, _mm256_castsi256_ps(_mm256_srli_si256(_mm256_castps_si256(v), 4)));
}

/// windowMoments for CPUs with AVX2: two rows at a time, one in each 128-bit half of a
/// register. Each half does for its row what windowMoments' 4-lane loop does (the same
/// lanes, operations and order; v_reduce_sum's (l0 + l2) + (l1 + l3); then the row's
/// remaining columns and its double sums, row after row), so the moments are the same.
MMVAL_TARGET_AVX2 WindowMoments windowMomentsAvx2(const cv::Mat& img, int cx, int cy, int r, double mx, double my, double level,
                                                                const float* ex, const float* ey) {
  WindowMoments m;
  const int x0 = std::max(0, cx - r), x1 = std::min(img.cols - 1, cx + r);
  const int y0 = std::max(0, cy - r), y1 = std::min(img.rows - 1, cy + r);
  if (x1 < x0) return m;
  const int n = x1 - x0 + 1;
  float dxs[2 * 37 + 1], mask[2 * 37 + 1];
  for (int k = 0; k < n; ++k) {
    dxs[k] = static_cast<float>((x0 + k) - mx);
    mask[k] = ex[x0 + k - cx + r];
  }
  const float flevel = static_cast<float>(level);
  const int n4 = n & ~3;
  // One row's columns past n4 and its double sums (windowMoments' scalar part).
  auto finish = [&](int y, float rw, float rx, float rxx) {
    addRowMoments(m, img.ptr<float>(y) + x0, n4, n, dxs, mask, flevel, ey[y - cy + r], y - my, rw, rx, rxx);
  };
  const __m256 vlevel = _mm256_set1_ps(flevel);
  int y = y0;
  for (; y + 1 <= y1; y += 2) {
    const float* row0 = img.ptr<float>(y) + x0;
    const float* row1 = img.ptr<float>(y + 1) + x0;
    __m256 vw = _mm256_setzero_ps(), vx = vw, vxx = vw;
    for (int k = 0; k < n4; k += 4) {
      const __m256 dx = _mm256_broadcast_ps(reinterpret_cast<const __m128*>(dxs + k));
      const __m256 px = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(row0 + k)), _mm_loadu_ps(row1 + k), 1);
      const __m256 w = _mm256_mul_ps(_mm256_sub_ps(px, vlevel), _mm256_broadcast_ps(reinterpret_cast<const __m128*>(mask + k)));
      const __m256 wdx = _mm256_mul_ps(w, dx);
      vw = _mm256_add_ps(vw, w);
      vx = _mm256_add_ps(vx, wdx);
      vxx = _mm256_add_ps(vxx, _mm256_mul_ps(wdx, dx));
    }
    float sw[8], sx[8], sxx[8];
    _mm256_storeu_ps(sw, reduceHalves(vw));
    _mm256_storeu_ps(sx, reduceHalves(vx));
    _mm256_storeu_ps(sxx, reduceHalves(vxx));
    finish(y, sw[0], sx[0], sxx[0]);
    finish(y + 1, sw[4], sx[4], sxx[4]);
  }
  if (y == y1) {
    const float* row = img.ptr<float>(y) + x0;
    __m128 vw = _mm_setzero_ps(), vx = vw, vxx = vw;
    const __m128 vlevel4 = _mm_set1_ps(flevel);
    for (int k = 0; k < n4; k += 4) {
      const __m128 dx = _mm_loadu_ps(dxs + k);
      const __m128 w = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(row + k), vlevel4), _mm_loadu_ps(mask + k));
      const __m128 wdx = _mm_mul_ps(w, dx);
      vw = _mm_add_ps(vw, w);
      vx = _mm_add_ps(vx, wdx);
      vxx = _mm_add_ps(vxx, _mm_mul_ps(wdx, dx));
    }
    float sw[8], sx[8], sxx[8];
    _mm256_storeu_ps(sw, reduceHalves(_mm256_castps128_ps256(vw)));
    _mm256_storeu_ps(sx, reduceHalves(_mm256_castps128_ps256(vx)));
    _mm256_storeu_ps(sxx, reduceHalves(_mm256_castps128_ps256(vxx)));
    finish(y, sw[0], sx[0], sxx[0]);
  }
  return m;
}
#endif  // MMVAL_HAVE_AVX2

constexpr double kFocusSignificance = 3;  ///< standard errors of a sigma beyond the focus limit
constexpr double kFocusRoundness = 0.6;   ///< largest eccentricity of a spot judged blurred (principal axes 0.8:1)
constexpr double kFocusDim = 0.5;         ///< a wide elongated spot is blurred when its peak is below this x the in-focus median
constexpr double kMaxMaskSigma = 12;  ///< px: larger spots are measured as this large (a 73 px window)
constexpr int kMomentIterations = 8;

}  // namespace

WindowMoments windowMomentsBaseline(const cv::Mat& img, int cx, int cy, int r, double mx, double my, double level, const float* ex, const float* ey) {
  return windowMoments(img, cx, cy, r, mx, my, level, ex, ey);
}

#if MMVAL_HAVE_AVX2
WindowMoments windowMomentsWide(const cv::Mat& img, int cx, int cy, int r, double mx, double my, double level, const float* ex, const float* ey) {
  return windowMomentsAvx2(img, cx, cy, r, mx, my, level, ex, ey);
}

float kthSmallestAvx2(const float* v, std::size_t n, std::size_t k, std::vector<float>& scratch) { return quickselectAvx2(v, n, k, scratch); }
#endif

void measureSpot(const cv::Mat& zero_mean, const cv::Mat& frame, double sigma0, double blur, double pixel_noise, Detection& d) {
  // Adaptive Gaussian-weighted moments (Bernstein & Jarvis 2002, AJ 123:583, sec. 3.1):
  // the second moments of the spot under a round Gaussian mask of sigma m. For a
  // Gaussian spot of covariance S the weighted covariance is V = (S^-1 + I / m^2)^-1,
  // so S = (V^-1 - I / m^2)^-1 whatever m, and the weighted sum is the amplitude times
  // 2 pi sqrt(det V). The mask follows the spot's own size (m^2 = trace(S) / 2), which
  // weighs the pixels about as a least-squares fit would; the spot is measured on the
  // smoothed signal (its noise is lower), whose spot covariance is S + blur^2 I.
  [[maybe_unused]] const bool avx2 = cpuHasAvx2();
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
#if MMVAL_HAVE_AVX2
    const WindowMoments mom =
        avx2 ? windowMomentsAvx2(zero_mean, cx, cy, r, d.x, d.y, level, ex, ey) : windowMoments(zero_mean, cx, cy, r, d.x, d.y, level, ex, ey);
#else
    const WindowMoments mom = windowMoments(zero_mean, cx, cy, r, d.x, d.y, level, ex, ey);
#endif
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
