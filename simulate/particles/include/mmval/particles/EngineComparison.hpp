// Measuring one engine against another on a shared window of the same scene
// (issue 6: the cheaper model's error against LIGGGHTS): both get the same
// particles at the same positions and are advanced to the same output times.
#pragma once
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/particles/Scene.hpp"

namespace mmval::particles {

struct EngineComparison {
  double window_s = 0;
  int particles = 0;
  double rms_position_difference = 0;  ///< m, over all particles and output times (both mobile or both stopped)
  double max_position_difference = 0;  ///< m
  double median_final_difference = 0;  ///< m, median over particles of the difference at the end of the window
  int captured_reference = 0, captured_candidate = 0;
  int captured_both = 0;               ///< same particle captured by both engines
  double rms_capture_time_difference = 0;  ///< s, over particles captured by both
  double retained_fraction_reference = 0, retained_fraction_candidate = 0;
  double wall_seconds_reference = 0, wall_seconds_candidate = 0;
  long long steps_reference = 0, steps_candidate = 0;
  nlohmann::json toJson() const;
};

/// Inserts `positions` into both engines, advances both to k * interval for
/// k = 1 .. window / interval and compares. Engines must be fresh (time 0, empty).
EngineComparison compareEngines(ParticleEngine& reference, ParticleEngine& candidate, const std::vector<Vec3>& positions, double window,
                                double interval);

}  // namespace mmval::particles
