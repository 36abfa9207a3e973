#include "mmval/particles/SceneSelection.hpp"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

namespace mmval::particles {

const char* engineName(EngineKind e) { return e == EngineKind::overdamped ? "overdamped" : "liggghts"; }

const char* couplingName(CouplingMode c) {
  switch (c) {
    case CouplingMode::resolved: return "resolved";
    case CouplingMode::dilated: return "dilated";
    case CouplingMode::unresolved: return "unresolved";
  }
  return "?";
}

nlohmann::json DimensionlessNumbers::toJson() const {
  return {{"Re", reynolds}, {"St", stokes}, {"Pe", peclet}, {"Pe_settling", settling_peclet},
          {"d_over_dx", d_over_dx}, {"d_over_h", d_over_h}, {"volume_fraction", volume_fraction}};
}

nlohmann::json EngineChoice::toJson() const {
  return {{"engine", engineName(engine)}, {"coupling", couplingName(coupling)}, {"wall_hindrance", wall_hindrance},
          {"brownian", brownian}, {"numbers", numbers.toJson()}, {"reason", reason}};
}

DimensionlessNumbers dimensionlessNumbers(const SceneScales& s) {
  if (!(s.velocity >= 0) || !(s.length > 0) || !(s.particle.diameter > 0) || !(s.fluid.viscosity > 0))
    throw std::invalid_argument("scene scales: velocity >= 0, length, diameter and viscosity > 0 are required");
  DimensionlessNumbers n;
  const double D = stokesEinstein(s.fluid, s.particle.diameter);
  n.reynolds = s.fluid.density * s.velocity * s.length / s.fluid.viscosity;
  n.stokes = relaxationTime(s.fluid, s.particle) * s.velocity / s.length;
  n.peclet = s.velocity * s.particle.diameter / D;
  n.settling_peclet = std::abs(settlingSpeed(s.fluid, s.particle, s.gravity)) * (s.depth > 0 ? s.depth : s.length) / D;
  n.d_over_dx = s.cell_size > 0 ? s.particle.diameter / s.cell_size : 0.0;
  n.d_over_h = s.depth > 0 ? s.particle.diameter / s.depth : 0.0;
  n.volume_fraction = s.volume_fraction;
  return n;
}

EngineChoice chooseEngine(const SceneScales& s, const SelectionThresholds& t) {
  EngineChoice c;
  c.numbers = dimensionlessNumbers(s);
  const auto& n = c.numbers;
  const bool inertialess = n.stokes <= t.stokes_overdamped;
  const bool dilute = n.volume_fraction <= t.volume_fraction_dilute;
  const bool dense = n.volume_fraction >= t.volume_fraction_dense;
  if (inertialess && dilute) {
    c.engine = EngineKind::overdamped;
    c.reason = fmt::format(
        "overdamped: St = {:.3g} <= {:.3g} (particle inertia relaxes in tau_p = {:.3g} s, the velocity lag is ~St), "
        "and phi = {:.3g} <= {:.3g} (dilute: contacts rare and brief), so velocity = local flow + mobility x forces; "
        "the inertial DEM would spend its steps resolving tau_p and the Hertz time",
        n.stokes, t.stokes_overdamped, relaxationTime(s.fluid, s.particle), n.volume_fraction, t.volume_fraction_dilute);
  } else {
    c.engine = EngineKind::liggghts;
    std::string why;
    if (!inertialess) why += fmt::format("St = {:.3g} > {:.3g} (inertia matters: particles lag the flow and collide with momentum)", n.stokes, t.stokes_overdamped);
    if (!dilute) {
      if (!why.empty()) why += "; ";
      why += fmt::format("phi = {:.3g} > {:.3g} ({}contacts carry force)", n.volume_fraction, t.volume_fraction_dilute,
                         dense ? "dense: enduring " : "not dilute: frequent ");
    }
    c.reason = "liggghts: " + why + ", so contacts and inertia are resolved (Hertz + tangential history)";
  }
  if (n.d_over_dx >= t.d_over_dx_resolved) c.coupling = CouplingMode::resolved;
  else if (n.d_over_dx >= 1.0) c.coupling = CouplingMode::dilated;
  else c.coupling = CouplingMode::unresolved;
  c.reason += fmt::format("; coupling {} (d/dx = {:.3g})", couplingName(c.coupling), n.d_over_dx);
  if (c.coupling == CouplingMode::resolved)
    c.reason += " (the kind particles-resolved solves such particles on the grid; the depth-averaged scenes move every particle "
                "with the local flow and its wall corrections and dilate deposits onto the grid)";
  c.wall_hindrance = n.d_over_h >= t.d_over_h_hindrance;
  c.reason += fmt::format("; wall hindrance {} (d/h = {:.3g})", c.wall_hindrance ? "on" : "off", n.d_over_h);
  c.brownian = n.peclet < t.peclet_brownian || n.settling_peclet < t.peclet_brownian;
  c.reason += fmt::format("; Brownian motion {} (Pe = {:.3g}, settling Pe = {:.3g}); Re = {:.3g}", c.brownian ? "on" : "off", n.peclet,
                          n.settling_peclet, n.reynolds);
  return c;
}

}  // namespace mmval::particles
