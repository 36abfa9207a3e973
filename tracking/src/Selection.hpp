// Internal to mmval::tracking: exact order statistics of small float arrays (ring
// medians, per-pixel temporal medians, noise estimates), faster than std::nth_element.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <opencv2/core/hal/intrin.hpp>

namespace mmval::tracking::detail {

/// The value std::nth_element would put at position k of v[0, n) (the k-th smallest,
/// 0-based), exactly; `v` is left unchanged, `scratch` is reused storage. Requires
/// k < n and finite values. A histogram of the values over [min, max] in up to n / 2
/// bins (a bin's index is monotone in the value, so the k-th smallest lies in the bin
/// where the cumulative count passes k) leaves a few values to select among: about 3x
/// faster than nth_element's introselect for n = 60-500, whose comparisons the CPU cannot
/// predict. (Counting the values below 8 thresholds per pass instead, without the
/// histogram's serialised increments, was measured 1.5x slower: 8 comparisons per value
/// and pass.)
inline float kthSmallest(const float* v, std::size_t n, std::size_t k, std::vector<float>& scratch) {
  // Extremes 4 values at a time (the values are finite, so v_min / v_max agree with
  // std::min / std::max).
  std::size_t i = 0;
  float lo = v[0], hi = v[0];
  if (n >= 4) {
    cv::v_float32x4 lo4 = cv::v_load(v), hi4 = lo4;
    for (i = 4; i + 4 <= n; i += 4) {
      const cv::v_float32x4 x = cv::v_load(v + i);
      lo4 = cv::v_min(lo4, x);
      hi4 = cv::v_max(hi4, x);
    }
    lo = cv::v_reduce_min(lo4);
    hi = cv::v_reduce_max(hi4);
  }
  for (; i < n; ++i) {
    lo = std::min(lo, v[i]);
    hi = std::max(hi, v[i]);
  }
  if (!(hi > lo) || !std::isfinite(hi - lo)) {
    if (hi == lo) return lo;
    scratch.assign(v, v + n);
    std::nth_element(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(k), scratch.end());
    return scratch[k];
  }
  constexpr std::size_t kMaxBins = 1024;
  const int bins = static_cast<int>(std::clamp<std::size_t>(n / 2, 8, kMaxBins));
  const float scale = static_cast<float>(bins - 1) / (hi - lo);
  // (x - lo) * scale is monotone in x; clamped to [0, bins - 1] against rounding at hi.
  thread_local std::vector<std::int32_t> bin_of;
  if (bin_of.size() < n) bin_of.resize(n);  // grown only: no zeroing of a regrown part
  {
    const cv::v_float32x4 vlo = cv::v_setall_f32(lo), vscale = cv::v_setall_f32(scale);
    const cv::v_int32x4 zero = cv::v_setzero_s32(), top = cv::v_setall_s32(bins - 1);
    for (i = 0; i + 4 <= n; i += 4)
      cv::v_store(bin_of.data() + i, cv::v_min(cv::v_max(cv::v_trunc((cv::v_load(v + i) - vlo) * vscale), zero), top));
    for (; i < n; ++i) bin_of[i] = std::clamp(static_cast<std::int32_t>((v[i] - lo) * scale), 0, bins - 1);
  }
  std::uint32_t counts[kMaxBins];
  std::fill(counts, counts + bins, 0u);
  for (i = 0; i < n; ++i) ++counts[bin_of[i]];
  std::size_t below = 0;
  int b = 0;
  while (below + counts[b] <= k) below += counts[b++];
  // The values of bin b, gathered without branches (each value is written, kept if in b).
  // (Measured on ring-like samples of 60-600 values, whose neighbours share bins: faster
  // than interleaved histograms or skipping blocks without a value of b.)
  if (scratch.size() < static_cast<std::size_t>(counts[b]) + 1) scratch.resize(static_cast<std::size_t>(counts[b]) + 1);
  std::size_t m = 0;
  for (i = 0; i < n; ++i) {
    scratch[m] = v[i];
    m += bin_of[i] == b ? 1 : 0;
  }
  std::nth_element(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(k - below), scratch.begin() + static_cast<std::ptrdiff_t>(m));
  return scratch[k - below];
}

}  // namespace mmval::tracking::detail
