// The micromodel scene as a picture (deposits.png): what a reader wants to see before the
// numbers, where the particles went and where they stayed.
#pragma once
#include <filesystem>

#include "mmval/core/Tracks.hpp"
#include "mmval/particles/MicromodelFlow.hpp"

namespace mmval::particles {

struct DepositPictureCounts {
  long long paths = 0;     ///< particle paths drawn (at most kMaxPaths, evenly over the ids)
  long long retained = 0;  ///< particles whose last row is deposited (all drawn)
  long long particles = 0; ///< particles in the trajectories
};

/// Writes `file` (PNG, staged and renamed): grains grey on white pore space, up to 600 particle
/// paths (blue: left or still moving; orange: ended deposited), and every retained particle
/// as a red disc of its radius at the place it stopped, with a one-line legend. Trajectory pixel
/// columns as in trajectories.csv (x_px, y_px from the first pixel's centre, y down), sorted
/// by particle then frame; `radius_px` the (largest) particle radius in mask pixels. The image
/// is the mask scaled by a whole factor to at most ~1200 px on its long side.
DepositPictureCounts writeDepositPicture(const std::filesystem::path& file, const PixelMask& grains, const Tracks& trajectories,
                                         double radius_px);

}  // namespace mmval::particles
