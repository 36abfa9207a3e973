#include "mmval/particles/MicromodelBookkeeping.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace mmval::particles {

namespace {
constexpr double kEdge_s = 1e-9;  // output frame times are k x interval: round-off, not a physical time
}

std::string PumpStall::reasonName() const { return reason == Reason::pressure_limit ? "pressure-limit" : "no-flow-path"; }

std::string PumpStall::describe() const {
  if (reason == Reason::pressure_limit)
    return fmt::format("pump stalled at t = {:g} s: the set flow rate needs {:.4g} Pa across the chip, above its limit of {:.4g} Pa",
                       time_s, pressure_Pa, max_pressure_Pa);
  return fmt::format("pump stalled at t = {:g} s: deposits left no flow path from inlet to outlet, so no pressure drives the set flow rate", time_s);
}

std::optional<PumpStall> pumpStall(const FlowSolveResult& solve, double max_pressure_Pa, double t_s) {
  PumpStall s;
  s.time_s = t_s;
  s.pressure_Pa = solve.pressure_drop;
  s.max_pressure_Pa = max_pressure_Pa > 0 ? max_pressure_Pa : 0.0;
  if (solve.blocked) {
    s.reason = PumpStall::Reason::no_flow_path;
    return s;
  }
  if (max_pressure_Pa > 0 && solve.pressure_drop > max_pressure_Pa) {
    s.reason = PumpStall::Reason::pressure_limit;
    return s;
  }
  return std::nullopt;
}

std::int64_t dueBy(double rate_per_s, double fraction, double t_s, double injection_time_s) {
  return static_cast<std::int64_t>(std::floor(rate_per_s * fraction * std::min(t_s, injection_time_s) + 1e-9));
}

WindowRetention retentionInWindow(const std::vector<ParticleLife>& lives, double from_s, double to_s) {
  if (!(from_s >= 0) || !(to_s > from_s))
    throw std::invalid_argument(fmt::format("retentionInWindow: need 0 <= from < to, got ({:g}, {:g}] s", from_s, to_s));
  WindowRetention w;
  w.from_s = from_s;
  w.to_s = to_s;
  for (const ParticleLife& p : lives) {
    if (!(p.injected_s > from_s + kEdge_s && p.injected_s <= to_s + kEdge_s)) continue;
    ++w.injected;
    if (p.retained_s >= 0 && p.retained_s <= to_s + kEdge_s) ++w.retained;
  }
  return w;
}

}  // namespace mmval::particles
