#include "mmval/simulate/ThroatCheck.hpp"
#include "mmval/simulate/Kinds.hpp"


#include <cmath>

#include <fmt/format.h>

#include "KindsCommon.hpp"
#include "MemoryBudget.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/simulate/DuctFlow.hpp"
#include "mmval/simulate/FieldOutput.hpp"
#include "mmval/simulate/KindMetrics.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::simulate {

namespace detail {

std::vector<int> levelsOf(const Case& c, const char* single_key, int lo, int hi) {
  std::vector<int> levels;
  if (c.has("numerics.levels"))
    for (auto v : c.integers("numerics.levels")) levels.push_back(static_cast<int>(v));
  if (levels.empty()) levels.push_back(static_cast<int>(c.integer(single_key)));
  for (int l : levels)
    if (l < lo || l > hi)
      throw InputError(c.where(c.has("numerics.levels") ? "numerics.levels" : single_key), "resolution level out of range", std::to_string(l),
                       fmt::format("{} ... {}", lo, hi));
  return levels;
}

void declareSolverKeys(Schema& s, bool peer_keys) {
  s.choice("numerics.immersed", {"sharp", "penalized"},
           "Immersed-boundary treatment of mmval's solver: sharp (cut viscous stencil at the exact surface) or penalized "
           "(the paper's volume-fraction method u = M u + (1 - M) v)")
      .def("sharp");
  s.choice("numerics.cut_cells", {"merged", "separate"},
           "Sharp treatment: a cell whose centre lies inside a solid shares the pressure and mass balance of the neighbour "
           "across its most open fluid face (merged), or keeps its own (separate: the walls move by a fraction of a cell, first order)")
      .def("merged");
  s.choice("numerics.linear_solver", {"auto", "direct", "iterative"},
           "mmval's coupled (u, v, p) solve: direct LU (UMFPACK serial, MUMPS parallel), FGMRES + Schur fieldsplit with AMG, or auto: "
           "iterative for plane Stokes on analytic periodic solids from 12000 unknowns (or on more than one rank), direct otherwise and "
           "for time stepping, with one direct retry if an auto-chosen iterative solve does not converge (result.json: details.ladder[].linear_solver)")
      .def("auto");
  if (peer_keys) {
    s.integer("numerics.max_iterations", "Steady iteration limit (OpenFOAM: SIMPLE iterations; mmval: Newton steps, capped at 50)").def(4000).min(10).max(1000000);
    s.real("numerics.residual", "Steady convergence target (OpenFOAM: initial residuals; mmval: relative Newton update)").def(1e-7).min(0.0, true).max(1e-2);
  }
}

SolverOptions solverOptions(const Case& c, bool quiet) {
  SolverOptions o;
  o.linear = c.text("numerics.linear_solver");
  o.announce_choice = !quiet;
  if (c.has("numerics.max_iterations")) o.max_newton = static_cast<int>(std::min<std::int64_t>(50, c.integer("numerics.max_iterations")));
  if (c.has("numerics.residual")) o.newton_tolerance = std::max(1e-10, c.real("numerics.residual"));
  return o;
}

void setImmersed(const Case& c, FlowProblem& p) {
  p.method = c.text("numerics.immersed") == "penalized" ? ImmersedMethod::penalized : ImmersedMethod::sharp;
  p.merge_cut_cells = c.text("numerics.cut_cells") == "merged";
}

std::string immersedLabel(const Case& c) {
  const std::string m = c.text("numerics.immersed");
  return m == "sharp" ? m + " (" + c.text("numerics.cut_cells") + " cut cells)" : m;
}

nlohmann::json ladderRow(std::size_t index, int resolution, const SteadyFlowSolver& s, const LevelClock& clock, double value, const Acceptance* primary) {
  const FlowStats& st = s.stats();
  nlohmann::json row = {{"level", index},
                        {"resolution", resolution},
                        {"cells", st.cells},
                        {"nx", s.nx()},
                        {"ny", s.ny()},
                        {"unknowns", st.unknowns},
                        {"wall_seconds", clock.wallSeconds()},
                        {"cpu_seconds", clock.cpuSeconds()},
                        {"assemble_seconds", st.assemble_seconds},
                        {"solve_seconds", st.solve_seconds},
                        {"linear_iterations", st.linear_iterations},
                        {"newton_iterations", st.newton_iterations},
                        {"peak_memory_bytes", peakMemoryBytes()},
                        {"ranks", PetscSession::size()},
                        {"linear_solver", st.linear_solver},
                        {"linear_solver_reason", st.linear_reason},
                        {"linear_solver_fallback", st.linear_fallback},
                        {"value", value}};
  if (std::isfinite(st.linear_true_residual)) row["linear_true_residual"] = st.linear_true_residual;
  if (!st.velocity_preconditioner.empty()) row["velocity_preconditioner"] = st.velocity_preconditioner;
  if (primary != nullptr && !primary->reference.isInterval() && primary->reference.value != 0)
    row["error"] = (value - primary->reference.value) / primary->reference.value;
  return row;
}

void writeFields(const SteadyFlowSolver& s, const RunContext& ctx, const std::string& stem, RunOutput& out) {
  if (ctx.out_dir.empty()) return;
  if (PetscSession::rank() == 0) {
    writeVtr(s, ctx.out_dir / (stem + ".vtr"));
    writeSpeedPng(s, ctx.out_dir / (stem + "-speed.png"));
  }
  out.files.push_back(stem + ".vtr");
  out.files.push_back(stem + "-speed.png");
}

}  // namespace detail

using namespace detail;

CaseKind channelKind() {
  CaseKind k;
  k.name = "channel";
  k.summary = "Flow between parallel plates (2D) or through a shallow duct (depth-averaged, Hele-Shaw friction): flow rate against the exact solutions";
  k.declare = [](Schema& s) {
    s.quantity("geometry.width", "um", "Distance between the side walls").positive();
    s.quantity("geometry.depth", "um", "Chip depth h for the depth-averaged model (friction 12 mu u / h^2); 0: plane 2D flow").def("0 um").nonNegative();
    s.quantity("geometry.length", "um", "Channel length for the inlet/outlet drives; 0: 8 widths").def("0 um").nonNegative();
    declareFluid(s, {.viscosity = 1e-3, .density = 1000.0});  // the density matters to the velocity-driven drive only
    s.choice("flow.drive", {"periodic", "pressure", "velocity"},
             "periodic: periodic along x with the body force G; pressure: fixed inlet/outlet pressures G x length apart; "
             "velocity: parabolic inflow of mean flow.mean_velocity with a pressure outlet (steady Navier-Stokes)")
        .def("periodic");
    s.quantity("flow.pressure_gradient", "Pa/m", "Driving pressure gradient G (periodic and pressure drives)").def("1e4 Pa/m").positive();
    s.quantity("flow.mean_velocity", "m/s", "Mean inflow velocity (velocity drive)").def("1e-3 m/s").positive();
    s.integer("numerics.cells", "Cells across the width").def(64).min(4).max(4096);
    s.integerList("numerics.levels", "Resolution ladder (cells across the width)").optional();
    declareSolverKeys(s, false);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    const double W = c.quantity("geometry.width"), hd = c.quantity("geometry.depth");
    const double mu = c.quantity("fluid.viscosity"), rho = c.quantity("fluid.density"), G = c.quantity("flow.pressure_gradient");
    const double L = c.quantity("geometry.length") > 0 ? c.quantity("geometry.length") : 8 * W;
    const std::string drive = c.text("flow.drive");
    const double Umean = c.quantity("flow.mean_velocity");
    const std::vector<int> levels = levelsOf(c, "numerics.cells", 4, 4096);
    for (const int n : levels)  // before the first level runs: the finest must fit too
      requireSteadyFlowMemory(c, drive == "periodic" ? 4.0 : std::max(4.0, std::round(n * L / W)), n, 0.0,
                              c.has("numerics.levels") ? "numerics.levels" : "numerics.cells",
                              "fewer cells across the width, or a shorter geometry.length (the inlet/outlet drives mesh the whole length)");
    // Exact solutions of the continuous models: q = G W^3 / (12 mu) (plates); the depth-averaged
    // (Brinkman-Hele-Shaw) channel: Q = G h^3 W / (12 mu) (1 - tanh(kW/2) / (kW/2)), k = sqrt(12) / h.
    const double plates = G * hd * hd * hd * W / (12 * mu);
    const double exact = hd > 0 ? plates * ductFlowFactorDepthAveraged(W, hd) : G * W * W * W / (12 * mu);
    const char* primary_name = drive == "velocity" ? "pressure_gradient" : (hd > 0 ? "flow_rate_factor" : "flow_rate_per_depth");
    const Acceptance* primary = c.acceptanceFor(primary_name);
    RunOutput out;
    out.details["solver"] = kSolverName;
    out.details["drive"] = drive;
    nlohmann::json ladder = nlohmann::json::array();
    Progress progress("fluid " + c.name(), levels.size(), ctx.quiet);
    std::unique_ptr<SteadyFlowSolver> last;
    double value = 0, q = 0, grad = 0;
    for (std::size_t li = 0; li < levels.size(); ++li) {
      const int n = levels[li];
      const LevelClock clock;
      FlowProblem p;
      p.y = uniformAxis(0, W, n);
      p.viscosity = mu;
      p.density = rho;
      p.depth = hd;
      if (drive == "periodic") {
        p.x = uniformAxis(0, 4 * W / n, 4);
        p.boundary[0].type = p.boundary[1].type = BoundaryType::periodic;
        p.body_force = {G, 0};
      } else {
        p.x = uniformAxis(0, L, std::max(4, static_cast<int>(std::lround(n * L / W))));
        p.boundary[1].type = BoundaryType::pressure;
        if (drive == "pressure") {
          p.boundary[0].type = BoundaryType::pressure;
          p.boundary[0].pressure = G * L;
        } else {
          p.boundary[0].type = BoundaryType::velocity;
          p.boundary[0].velocity = [W, Umean](double y) { return 6 * Umean * y * (W - y) / (W * W); };
          p.inertia = true;
        }
      }
      last = std::make_unique<SteadyFlowSolver>(p, solverOptions(c, ctx.quiet));
      solveNamingKey(*last, c.has("numerics.levels") ? "numerics.levels" : "numerics.cells");
      q = last->flowRate(Side::east) * (hd > 0 ? hd : 1.0);
      if (drive == "velocity") {
        // Developed-flow pressure gradient between 1/4 and 3/4 of the length.
        grad = (last->pressureAt(0.25 * L, 0.5 * W) - last->pressureAt(0.75 * L, 0.5 * W)) / (0.5 * L);
        value = grad;
      } else {
        value = hd > 0 ? q / plates : q;
      }
      ladder.push_back(ladderRow(li, n, *last, clock, value, primary));
      progress.update(li + 1);
    }
    progress.finish();
    addObservedOrder(ladder, levels);
    out.details["ladder"] = ladder;
    out.details["cells"] = last->stats().cells;
    out.details["model_exact_flow_rate"] = exact;
    if (drive == "velocity") {
      out.metrics["pressure_gradient"] = grad;
      out.units["pressure_gradient"] = "Pa/m";
      // Plane Poiseuille: G = 12 mu U / W^2 (2D only; the depth-averaged duct adds friction).
      if (hd == 0) out.metrics["pressure_gradient_exact"] = 12 * mu * Umean / (W * W);
      out.units["pressure_gradient_exact"] = "Pa/m";
    } else if (hd > 0) {
      out.metrics["flow_rate"] = q;
      out.units["flow_rate"] = "uL/min";
      out.metrics["flow_rate_factor"] = q / plates;
      out.metrics["model_flow_rate_factor"] = exact / plates;
    } else {
      out.metrics["flow_rate_per_depth"] = q;
      out.units["flow_rate_per_depth"] = "m2/s";
    }
    return out;
  };
  return k;
}

void registerFluidKinds(CaseKindRegistry& registry) {
  registry.add(channelKind());
  registry.add(chipGeneratorKind());
  registry.add(periodicArrayKind());
  registry.add(cylinderChannelKind());
  registry.add(imagePermeabilityKind());
  declareFluidMetrics(registry);
}

}  // namespace mmval::simulate
