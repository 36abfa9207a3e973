// Measuring one engine against another on a shared window of the same scene
// (the cheaper model's error against LIGGGHTS): both get the same
// particles at the same positions and are advanced to the same output times.
#pragma once
#include <cstdint>
#include <memory>
#include <string>
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
  /// The reference engine's engineVersion() (for the run's provenance; not in toJson).
  std::string reference_version;
  nlohmann::json toJson() const;
};

/// Inserts `positions` into the reference and every candidate, advances all to
/// k * interval for k = 1 .. window / interval and compares each candidate with the
/// reference (which runs once). Engines must be fresh (time 0, empty).
std::vector<EngineComparison> compareEngines(ParticleEngine& reference, const std::vector<ParticleEngine*>& candidates, const std::vector<Vec3>& positions,
                                             double window, double interval);
/// One candidate.
EngineComparison compareEngines(ParticleEngine& reference, ParticleEngine& candidate, const std::vector<Vec3>& positions, double window,
                                double interval);

/// `n` positions spread uniformly over a field's pore space: (x, y) uniform over
/// the fluid of the bounds, z uniform over [a, h - a], each accepted only where
/// insertionProblem has nothing against it (clear of grains, walls and each
/// other). Deterministic for a seed; throws InputError when the pore space cannot
/// take them in 1000 n tries.
std::vector<Vec3> samplePoreSpace(const FlowField& flow, double radius, int n, std::uint64_t seed);

/// The shared window of a scene: particles spread over its pore space, both
/// engines from the same positions on the same field, deterministic (no
/// Brownian motion: LIGGGHTS has none), gravity x `gravity_factor` so that
/// particles reach the bottom plate within a short window.
struct SceneWindow {
  double window = 0.2;          ///< s
  double interval = 0.01;       ///< s, comparison times
  int particles = 40;
  double gravity_factor = 100;
  std::uint64_t seed = 5;
};

/// LIGGGHTS (the reference: Hertz contacts, grains as an STL mesh wall) against
/// the overdamped engine on `flow` with the scene's physics `config`, once per entry of
/// `candidates` (the overdamped settings; empty: `config` itself); Brownian motion is
/// off and gravity scaled for all. LIGGGHTS runs once. Throws InputError when this
/// build has no LIGGGHTS.
std::vector<EngineComparison> compareOnScene(std::shared_ptr<const FlowField> flow, SceneConfig config, const SceneWindow& w,
                                             const std::vector<SceneConfig>& candidates = {});

}  // namespace mmval::particles
