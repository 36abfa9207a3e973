// What a tracks file must hold before it can be compared: rows, a particle
// seen at two or more times, time that advances, one row per particle and
// frame. Without these the metrics are 0 or NaN and look like a result.
#pragma once
#include <string>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::compare {

/// Throws InputError naming `tracks.source` (or "(<role> tracks)" when it has
/// none), the column, the bad value and what was expected when `tracks` has no
/// rows, no particle with two rows, two rows of one particle at one frame, or
/// no particle whose t_s advances. `role` is "experiment" or "simulation".
void checkComparable(const Tracks& tracks, const std::string& role);

/// Throws InputError when the reference (experiment) analysis has no step to
/// measure a speed from: every particle immobile or shorter than
/// `options.min_points` rows. Relative errors against its zero speed mean nothing.
void checkReferenceMoves(const Tracks& tracks, const tracking::TrackStats& stats, const tracking::TrackOptions& options);

}  // namespace mmval::compare
