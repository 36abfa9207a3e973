// The one rule every reader of a grain/pore mask image applies (the solver's and
// OpenFOAM's geometry, the rendered and synthetic videos, compare's registration),
// so that one image means the same grains everywhere: a mask has two grey levels,
// and it is split halfway between the darkest and the brightest grey it holds.
// A grey at or below the split is dark, above it bright; geometry.grains says
// which of the two is grain. A 0/255 mask splits at 127.5, a 0/1 mask at 0.5, a
// 16-bit mask at the midpoint of its own levels. An image of one grey level is
// split at mid-scale (it is all dark or all bright: a chip with no grains, or
// nothing but grain, which the callers' pore-space checks then report).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>

namespace mmval {

/// The split level for grey values in [lo, hi] (the image's darkest and brightest),
/// `full_scale` the largest value the type holds (255 for 8-bit, 1 for normalised).
constexpr double maskSplit(double lo, double hi, double full_scale) { return hi > lo ? 0.5 * (lo + hi) : 0.5 * full_scale; }

/// The split of an 8-bit grey image of `n` pixels.
inline double maskSplit(const std::uint8_t* grey, std::size_t n) {
  if (n == 0) return 127.5;
  const auto [lo, hi] = std::minmax_element(grey, grey + n);
  return maskSplit(*lo, *hi, 255.0);
}

/// True when `grey` is grain under the split: dark greys (<= split) when grains are dark.
constexpr bool isGrain(double grey, double split, bool grains_dark) { return (grey <= split) == grains_dark; }

}  // namespace mmval
