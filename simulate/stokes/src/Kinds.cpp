#include "mmval/stokes/Kinds.hpp"

#include <cmath>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/stokes/Stokes.hpp"

namespace mmval::stokes {

namespace {

const char* kSolverName = "mmval stokes";

std::vector<int> levelsOf(const Case& c, const char* single) {
  std::vector<int> levels;
  if (c.has("numerics.levels"))
    for (auto v : c.integers("numerics.levels")) levels.push_back(static_cast<int>(v));
  if (levels.empty()) levels.push_back(static_cast<int>(c.integer(single)));
  for (int l : levels)
    if (l < 4 || l > 2048) throw InputError(c.where("numerics.levels"), "a resolution level must be between 4 and 2048 cells", std::to_string(l), "4 ... 2048");
  return levels;
}

}  // namespace

RunOutput runPeriodicArray(const Case& c, const RunContext& ctx) {
  const double L = c.quantity("geometry.cell");
  const double phi = c.quantity("geometry.solid_fraction");
  const double a = L * std::sqrt(phi / M_PI);
  const double mu = c.quantity("fluid.viscosity");
  const std::vector<int> levels = levelsOf(c, "numerics.cells_around");
  const Acceptance* primary = c.acceptanceFor("F_star");
  RunOutput out;
  out.details["solver"] = kSolverName;
  nlohmann::json ladder = nlohmann::json::array();
  Progress progress("stokes " + c.name(), levels.size(), ctx.quiet);
  double fstar = 0;
  for (std::size_t k = 0; k < levels.size(); ++k) {
    Problem p;
    p.nx = p.ny = levels[k];
    p.h = L / levels[k];
    p.viscosity = mu;
    p.pressure_gradient = 1.0;
    setSolidFromIndicator(p, [&](double x, double y) { return std::hypot(x - 0.5 * L, y - 0.5 * L) < a; });
    const Solution s = solve(p);
    // Sangani & Acrivos: F = G L^2 per unit length, F* = F / (mu U_d).
    fstar = p.pressure_gradient * L * L / (mu * s.superficial_u);
    nlohmann::json row = {{"level", k}, {"cells_per_side", levels[k]}, {"cells", p.nx * p.ny}, {"unknowns", s.unknowns},
                          {"wall_seconds", s.assemble_seconds + s.solve_seconds}, {"solve_seconds", s.solve_seconds}, {"value", fstar},
                          {"max_divergence", s.max_divergence}};
    if (primary != nullptr && !primary->reference.isInterval()) row["error"] = (fstar - primary->reference.value) / primary->reference.value;
    ladder.push_back(row);
    progress.update(k + 1);
  }
  progress.finish();
  addObservedOrder(ladder, levels);
  out.details["ladder"] = ladder;
  out.details["cells"] = ladder.back()["cells"];
  out.metrics["F_star"] = fstar;
  out.metrics["k_over_L2"] = 1.0 / fstar;
  out.metrics["permeability"] = L * L / fstar;
  out.units["permeability"] = "m2";
  return out;
}

void registerStokesKinds(CaseKindRegistry& registry) {
  CaseKind ch;
  ch.name = "channel";
  ch.summary = "Pressure-driven flow between plates (2D) or through a shallow duct (depth-averaged, Hele-Shaw friction): flow rate";
  ch.declare = [](Schema& s) {
    s.quantity("geometry.width", "um", "Distance between the side walls").positive();
    s.quantity("geometry.depth", "um", "Chip depth h for the depth-averaged model; 0: plane 2D flow").def("0 um").nonNegative();
    s.quantity("fluid.viscosity", "Pa s", "Dynamic viscosity").def("1e-3 Pa s").positive();
    s.quantity("flow.pressure_gradient", "Pa/m", "Driving pressure gradient G").def("1e4 Pa/m").positive();
    s.integer("numerics.cells", "Cells across the width").def(64).min(4).max(4096);
    s.integerList("numerics.levels", "Resolution ladder (cells across the width)").optional();
  };
  ch.run = [](const Case& c, const RunContext& ctx) {
    const double W = c.quantity("geometry.width"), hd = c.quantity("geometry.depth");
    const double mu = c.quantity("fluid.viscosity"), G = c.quantity("flow.pressure_gradient");
    const std::vector<int> levels = levelsOf(c, "numerics.cells");
    // Exact flow rates of the discretised models, for the ladder's error:
    // plane Poiseuille q = G W^3 / (12 mu) per unit depth; depth-averaged Brinkman
    // channel Q = G h^2 W / (12 mu) (1 - tanh(k W / 2) / (k W / 2)), k^2 = 12 / h^2.
    const double kappa = hd > 0 ? std::sqrt(12.0) / hd : 0;
    const double exact = hd > 0 ? G * hd * hd * W / (12 * mu) * (1 - std::tanh(kappa * W / 2) / (kappa * W / 2)) * hd : G * W * W * W / (12 * mu);
    RunOutput out;
    out.details["solver"] = kSolverName;
    nlohmann::json ladder = nlohmann::json::array();
    double q = 0;
    for (std::size_t k = 0; k < levels.size(); ++k) {
      Problem p;
      p.ny = levels[k];
      p.nx = 4;
      p.h = W / levels[k];
      p.walls_y = true;
      p.viscosity = mu;
      p.pressure_gradient = G;
      p.depth = hd;
      const Solution s = solve(p);
      q = s.superficial_u * W * (hd > 0 ? hd : 1.0);
      ladder.push_back({{"level", k}, {"cells_across", levels[k]}, {"unknowns", s.unknowns}, {"wall_seconds", s.assemble_seconds + s.solve_seconds},
                        {"value", q}, {"error", (q - exact) / exact}});
    }
    addObservedOrder(ladder, levels);
    out.details["ladder"] = ladder;
    out.details["model_exact_flow_rate"] = exact;
    if (hd > 0) {
      out.metrics["flow_rate"] = q;
      out.units["flow_rate"] = "uL/min";
      // Against the parallel-plate flow through the same section: comparable with the
      // exact rectangular-duct series (reference-data/shallow-channels.toml).
      out.metrics["flow_rate_factor"] = q / (G * hd * hd * hd * W / (12 * mu));
      out.metrics["model_flow_rate_factor"] = exact / (G * hd * hd * hd * W / (12 * mu));
    } else {
      out.metrics["flow_rate_per_depth"] = q;
      out.units["flow_rate_per_depth"] = "m2/s";
    }
    return out;
  };
  registry.add(ch);
}

}  // namespace mmval::stokes
