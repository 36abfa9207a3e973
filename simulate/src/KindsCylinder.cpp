// Flow around a cylinder in a channel (Schaefer & Turek 1996 DFG 2D-1; the
// paper's Table 1 set-up). Grid: uniform cells h = pi D / cells_around in a
// box around the cylinder and its near wake, stretched geometrically outside
// (ratio numerics.stretch_ratio, cells at most numerics.max_cell_ratio x h).
// Optionally a second box of cells h / numerics.body_refine within numerics.body_box
// diameters of the centre, graded back to h: the body's boundary layer at a finer
// spacing than the wake's (for shedding the lift depends on both: see the 2D-2 case).
#include <cmath>

#include <fmt/format.h>

#include "KindsCommon.hpp"
#include "MemoryBudget.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/simulate/CylinderScene.hpp"
#include "mmval/simulate/ThroatCheck.hpp"
#include "mmval/simulate/Kinds.hpp"

namespace mmval::simulate {

using namespace detail;

CaseKind cylinderChannelKind() {
  CaseKind k;
  k.name = "cylinder-channel";
  k.summary = "Flow around a circular cylinder in a channel (Schaefer-Turek and the paper's set-up): drag, lift, pressure difference";
  k.declare = [](Schema& s) {
    s.quantity("geometry.length", "m", "Channel length (x)").def("2.2 m").positive();
    s.quantity("geometry.height", "m", "Channel height (y)").def("0.41 m").positive();
    s.quantity("geometry.cylinder_x", "m", "Cylinder centre x").def("0.2 m").positive();
    s.quantity("geometry.cylinder_y", "m", "Cylinder centre y").def("0.2 m").positive();
    s.quantity("geometry.diameter", "m", "Cylinder diameter").def("0.1 m").positive();
    s.quantity("geometry.depth", "m", "Extrusion depth (OpenFOAM; mmval's 2D coefficients are per unit depth)").def("0.1 m").positive();
    declareFluid(s, {.viscosity = 1e-3, .density = 1.0});  // Schaefer-Turek's fluid
    s.choice("geometry.walls", {"no-slip", "slip"}, "Channel side walls: no-slip (Schaefer-Turek) or slip (free stream)").def("no-slip");
    s.choice("inflow.profile", {"parabolic", "uniform"}, "Inflow profile").def("parabolic");
    s.quantity("inflow.max_velocity", "m/s", "Peak of the parabolic inflow 4 U y (H - y) / H^2, or the uniform inflow velocity").positive();
    s.quantity("forces.reference_velocity", "m/s", "Velocity of the coefficients c = 2 F / (rho U^2 D); default: mean inflow (2/3 U_max if parabolic)").optional().positive();
    s.quantity("forces.reference_length", "m", "Length of the coefficients; default: the diameter").optional().positive();
    s.quantityList("probes.pressure_a", "m", "First pressure point (x, y); dp = p(a) - p(b)").optional();
    s.quantityList("probes.pressure_b", "m", "Second pressure point (x, y)").optional();
    s.choice("numerics.mode", {"steady", "unsteady"}, "Steady (Newton) or unsteady (BDF2 time stepping) solution").def("steady");
    s.quantity("numerics.end_time", "s", "Unsteady: simulated time").def("8 s").positive();
    s.quantity("numerics.time_step", "s", "Unsteady: first time step (then adjusted: mmval grows it by at most 25 % per step up to the Courant limit numerics.max_courant)").def("1e-3 s").positive();
    s.integer("numerics.cells_around",
              "Resolution: cells around the cylinder's circumference, so the surface spacing is pi D / cells_around in both solvers "
              "(mmval: uniform cells of that size in a box about the cylinder and its near wake; OpenFOAM: an O-grid with cells_around "
              "cells on the circumference, a multiple of 4, and cells of at most 8 D / cells_around at the edge of its 2 D box)")
        .def(64).min(8).max(4096);
    s.integerList("numerics.levels", "Resolution ladder (cells_around per level); absent: one run at cells_around").optional();
    s.real("numerics.stretch_ratio", "mmval: growth ratio of neighbouring cells outside the refined box").def(1.05).min(1.0).max(1.3);
    s.real("numerics.max_cell_ratio", "mmval: largest cell over the near-body spacing h").def(4.0).min(1.0).max(64);
    s.real("numerics.wall_refine",
           "mmval: cells next to the channel walls are h / wall_refine, growing by stretch_ratio into the grid (1: no wall layer). "
           "For shedding, whose wall (Stokes) layer sqrt(2 nu / omega) is only a few cells of h")
        .def(1.0).min(1.0).max(16);
    s.realList("numerics.grid_offset",
               "mmval: shift of the grid against the cylinder centre, as fractions [x, y] of the near-body spacing h. The default puts "
               "faces through the centre, so the cells cut the cylinder symmetrically; other offsets show how much a result depends on "
               "where the surface cuts the cells (a y offset other than 0 or 0.5 makes the discrete body lopsided and adds a spurious lift)")
        .def(std::vector<double>{0.0, 0.0})
        .min(0.0)
        .max(1.0, true);
    s.integer("numerics.body_refine",
              "mmval: a second, finer box about the cylinder: its cells are h / body_refine, graded back to h outside it by "
              "stretch_ratio per cell (1: none). Resolves the body's boundary layer without refining the whole wake")
        .def(1)
        .min(1)
        .max(8);
    s.real("numerics.body_box", "mmval: half-size of the finer box about the cylinder centre, in diameters (with body_refine > 1)")
        .def(1.0)
        .min(0.55)
        .max(100);
    declareSolverKeys(s, true);
    declareUnsteadyCylinderKeys(s);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    const CylinderScene scene = readCylinderScene(c);
    const double Lx = scene.length_m, H = scene.height_m;
    const double cx = scene.centre_x_m, cy = scene.centre_y_m, D = scene.diameter_m;
    const double Lref = scene.l_ref_m;
    const double coef = scene.forceCoefficient();
    const std::vector<int> levels = levelsOf(c, "numerics.cells_around", 8, 4096);
    const Acceptance* primary = c.acceptanceFor("c_D");
    const Acceptance* lift = c.acceptanceFor("c_L");
    const bool probes = !scene.pressure_probes.empty();
    RunOutput out;
    out.details["solver"] = kSolverName;
    out.details["immersed"] = immersedLabel(c);
    out.details["Re"] = scene.reynolds();
    out.details["domain"] = {{"length_m", Lx}, {"height_m", H}, {"blockage", scene.blockage()}};
    nlohmann::json ladder = nlohmann::json::array();
    std::unique_ptr<SteadyFlowSolver> last;
    BodyLoad load;
    double dp = 0;
    const double down = c.real("numerics.refine_downstream"), across = c.real("numerics.refine_across");
    const double wall_refine = c.real("numerics.wall_refine");
    if (wall_refine > 1 && scene.slip_walls)
      throw InputError(c.where("numerics.wall_refine"), "a wall layer needs no-slip walls", fmt::format("{} with slip walls", wall_refine),
                       "1 (no wall layer) or geometry.walls = \"no-slip\"");
    const int body_refine = static_cast<int>(c.integer("numerics.body_refine"));
    const double body_box = c.real("numerics.body_box");
    const std::vector<double> offset = c.reals("numerics.grid_offset");
    if (offset.size() != 2)
      throw InputError(c.where("numerics.grid_offset"), "the grid offset needs two fractions of a cell", fmt::format("{} values", offset.size()),
                       "[x, y], each in [0, 1)");
    auto makeProblem = [&](int cells_around) {
      const double h = surfaceSpacing(scene, cells_around);
      const double ratio = c.real("numerics.stretch_ratio"), hmax = c.real("numerics.max_cell_ratio") * h;
      FlowProblem p;
      // Refined box: 0.75 D upstream, `across` D to the sides, `down` D downstream
      // (defaults 0.75 and 1.5: the Re 20 recirculation is ~0.85 D; shedding needs the wake).
      // Faces through the centre: the cells cut the cylinder symmetrically about both axes
      // through its centre at every level (a box edge at a wall otherwise set the surface's
      // sub-cell position, so the discrete body was lopsided by a level-dependent amount).
      // numerics.grid_offset moves those faces by a fraction of h (sub-cell position studies).
      // With a finer box about the body (body_refine > 1), the box of h holds it and the graded
      // layer back to h: that layer spans ~ h (1 - 1 / m) / (ratio - 1).
      const double grade = std::max(ratio, 1.02), r = body_box * D;
      const double reach = body_refine > 1 ? r + h * (1 - 1.0 / body_refine) / (grade - 1) + 2 * h : 0.0;
      p.x = refinedAxis(0, Lx, std::max(0.0, cx - std::max(0.75 * D, reach)), std::min(Lx, cx + std::max(down * D, reach)), h, ratio, hmax,
                        cx + offset[0] * h);
      p.y = refinedAxis(0, H, std::max(0.0, cy - std::max(across * D, reach)), std::min(H, cy + std::max(across * D, reach)), h, ratio, hmax,
                        cy + offset[1] * h);
      if (body_refine > 1) {
        // Split the cells within body_box D of the centre (faces through the centre stay).
        p.x = innerRefinedAxis(p.x, cx - r, cx + r, body_refine, grade);
        p.y = innerRefinedAxis(p.y, cy - r, cy + r, body_refine, grade);
      }
      if (wall_refine > 1) p.y = wallGradedAxis(p.y, h / wall_refine, grade);
      p.boundary[0].type = BoundaryType::velocity;
      p.boundary[0].velocity = [scene](double y) { return scene.inflowAt(y); };
      p.boundary[1].type = BoundaryType::pressure;
      p.boundary[2].type = p.boundary[3].type = scene.slip_walls ? BoundaryType::slip : BoundaryType::no_slip;
      p.density = scene.density_kg_m3;
      p.viscosity = scene.viscosity_pa_s;
      p.inertia = true;
      p.shape = std::make_shared<Circles>(std::vector<Circle>{{cx, cy, 0.5 * D}});
      setImmersed(c, p);
      return p;
    };
    if (c.text("numerics.mode") == "unsteady") {
      RunOutput uo = runUnsteadyCylinder(c, ctx, scene, makeProblem);
      uo.details["immersed"] = c.text("numerics.immersed");
      uo.details["Re"] = scene.reynolds();
      uo.details["domain"] = {{"length_m", Lx}, {"height_m", H}, {"blockage", scene.blockage()}};
      return uo;
    }
    for (const int n : levels) {  // before the first level runs: the finest must fit too
      const FlowProblem p = makeProblem(n);
      requireSteadyFlowMemory(c, p.x.cells(), p.y.cells(), 0.0, c.has("numerics.levels") ? "numerics.levels" : "numerics.cells_around",
                              "fewer cells around the cylinder, or a coarser far field (numerics.max_cell_ratio, numerics.stretch_ratio)");
    }
    Progress progress("fluid " + c.name(), levels.size(), ctx.quiet);
    for (std::size_t li = 0; li < levels.size(); ++li) {
      const LevelClock clock;
      const double h = surfaceSpacing(scene, levels[li]);
      const FlowProblem p = makeProblem(levels[li]);
      last = std::make_unique<SteadyFlowSolver>(p, solverOptions(c, ctx.quiet));
      solveNamingKey(*last, c.has("numerics.levels") ? "numerics.levels" : "numerics.cells_around");
      load = last->bodyLoads()[0];
      if (probes) {
        const auto& a = scene.pressure_probes[0];
        const auto& b = scene.pressure_probes[1];
        dp = last->pressureAt(a[0], a[1]) - last->pressureAt(b[0], b[1]);
      }
      auto row = ladderRow(li, levels[li], *last, clock, coef * load.force.x(), primary);
      row["h_over_D"] = h / D;
      row["c_L"] = coef * load.force.y();
      // The lift error per level: at h ~ D/15-D/30 it scatters by several % with the sub-cell
      // position of the surface, so its ladder shows whether a level's c_L is converged or lucky.
      if (lift != nullptr && !lift->reference.isInterval() && lift->reference.value != 0)
        row["c_L_error"] = (coef * load.force.y() - lift->reference.value) / lift->reference.value;
      if (probes) row["dp"] = dp;
      row["newton_update"] = last->stats().update_norm;
      ladder.push_back(row);
      progress.update(li + 1);
    }
    progress.finish();
    addObservedOrder(ladder, levels);
    out.details["ladder"] = ladder;
    out.details["cells"] = last->stats().cells;
    out.metrics["c_D"] = coef * load.force.x();
    out.metrics["c_L"] = coef * load.force.y();
    out.metrics["torque_coefficient"] = coef * load.torque / Lref;
    if (probes) {
      out.metrics["dp"] = dp;
      out.units["dp"] = "Pa";
    }
    writeFields(*last, ctx, "fields", out);
    return out;
  };
  return k;
}

}  // namespace mmval::simulate
