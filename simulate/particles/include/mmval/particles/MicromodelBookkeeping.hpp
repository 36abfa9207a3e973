// Bookkeeping of the micromodel scene: the
// syringe pump's limits and the particle counts a retention is made of.
//
// The pump. The experiment drives its chip with a syringe pump at a set flow
// rate (the source paper, doi:10.1016/j.powtec.2022.117130; reference-data/
// micromodel-experiment.toml). A syringe pump keeps that
// rate only up to its pressure limit, and a chip without an open path from
// inlet to outlet takes no flow at any pressure. Each fluid solve of the scene
// gives the pressure drop the set rate needs across the simulated geometry
// (FlowSolveResult::pressure_drop, Darcy's law); pumpStall() says whether the
// pump stalls there. What the runner then does (injection stops and the run
// ends) is stated in Micromodel.hpp.
//
// The counts. Retention is retained over injected, the paper's definition
// (about 6000 particles injected, 42.3 % retained: reference-data/micromodel-experiment.toml).
// Particles the injection schedule called for that never entered the chip (the
// pump stalled, or the inlet strip stayed full) are counted apart and are in
// neither number. retentionInWindow() gives the same ratio for the particles
// injected within a window of time.
#pragma once
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "mmval/particles/MicromodelFlow.hpp"

namespace mmval::particles {

/// The pump stopped delivering the set flow rate.
struct PumpStall {
  enum class Reason { pressure_limit, no_flow_path };
  Reason reason = Reason::no_flow_path;
  double time_s = 0;       ///< s: time of the fluid solve that found it
  double pressure_Pa = 0;  ///< Pa: pressure drop the set rate needed then (+infinity: no flow path)
  double max_pressure_Pa = 0;  ///< Pa: the pump's limit (0: none given)

  /// "pressure-limit" or "no-flow-path".
  std::string reasonName() const;
  /// One sentence with the time, the pressure and the limit, e.g. for the terminal.
  std::string describe() const;
};

/// The pump's verdict on a fluid solve at time `t_s`: a stall when no flow path
/// is left (solve.blocked), or when the pressure drop the set rate needs exceeds
/// `max_pressure_Pa` (<= 0: no pressure limit). Nothing otherwise.
std::optional<PumpStall> pumpStall(const FlowSolveResult& solve, double max_pressure_Pa, double t_s);

/// The injection schedule: particles of a class due by time `t_s`, for a scene
/// injecting `rate_per_s` simulated particles per second (all classes) during
/// [0, injection_time_s], the class taking `fraction` of them. Whole particles,
/// rounded down (1e-9 guards round-off on exact multiples).
std::int64_t dueBy(double rate_per_s, double fraction, double t_s, double injection_time_s);

/// One simulated particle as the outputs show it: when it entered (the output
/// frame it first appears in) and when it was retained (the frame of its
/// deposited row; < 0: never).
struct ParticleLife {
  double injected_s = 0;
  double retained_s = -1;
};

/// Retention of the particles injected within a window of time.
struct WindowRetention {
  double from_s = 0, to_s = 0;  ///< the window (from, to]
  std::int64_t injected = 0;    ///< particles injected at a time in (from, to]
  std::int64_t retained = 0;    ///< of those, retained at a time <= to
  double fraction() const { return injected > 0 ? static_cast<double>(retained) / static_cast<double>(injected) : 0.0; }
};

/// Particles injected in (from_s, to_s] and how many of them were retained by
/// to_s: for from_s = 0 exactly what a run ending at to_s reports as retained /
/// injected, and windows that tile a run count each particle once. Output frames
/// are discrete, so times within 1e-9 s of an edge count as on it.
/// std::invalid_argument unless 0 <= from_s < to_s.
WindowRetention retentionInWindow(const std::vector<ParticleLife>& lives, double from_s, double to_s);

}  // namespace mmval::particles
