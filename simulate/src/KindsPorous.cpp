// Porous-media kinds: periodic square arrays (Stokes permeability) and chip
// permeability from a binary mask.
#include <cmath>

#include <fmt/format.h>

#include "KindsCommon.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::simulate {

using namespace detail;

namespace {
constexpr double kDarcy = 9.869233e-13;  // m2
}

CaseKind periodicArrayKind() {
  CaseKind k;
  k.name = "periodic-array";
  k.summary = "Periodic square array of cylinders in creeping flow: dimensionless drag F* = F / (mu U) and permeability";
  k.declare = [](Schema& s) {
    s.quantity("geometry.cell", "um", "Side L of the square unit cell").def("100 um").positive();
    s.quantity("geometry.solid_fraction", "1", "Solid area fraction phi = pi a^2 / L^2").min(0.0, true).max(0.75);
    s.quantity("fluid.density", "kg/m3", "Fluid density").def("1000 kg/m3").positive();
    s.quantity("fluid.viscosity", "Pa s", "Dynamic viscosity").def("1e-3 Pa s").positive();
    s.quantity("flow.mean_velocity", "m/s", "Mean velocity scale (keep Re << 1; mmval solves Stokes, so F* does not depend on it)").def("1e-4 m/s").positive();
    s.integer("numerics.cells_around", "Resolution (mmval: cells along the unit-cell side; OpenFOAM: cells around the cylinder)").def(64).min(8).max(4096);
    s.integerList("numerics.levels", "Resolution ladder (cells_around per level); absent: one run at cells_around").optional();
    s.integer("numerics.supersample", "Penalized method: samples per face control volume and direction").def(6).min(1).max(32);
    declareSolverKeys(s, true);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    const double L = c.quantity("geometry.cell"), phi = c.quantity("geometry.solid_fraction"), mu = c.quantity("fluid.viscosity");
    if (phi > M_PI / 4 - 1e-9)
      throw InputError(c.where("geometry.solid_fraction"), "the cylinders touch (phi > pi/4 closes the square array)", fmt::format("{}", phi), "phi < 0.785");
    const std::vector<int> levels = levelsOf(c, "numerics.cells_around", 8, 4096);
    const Acceptance* primary = c.acceptanceFor("F_star");
    RunOutput out;
    out.details["solver"] = kSolverName;
    out.details["immersed"] = c.text("numerics.immersed");
    nlohmann::json ladder = nlohmann::json::array();
    Progress progress("fluid " + c.name(), levels.size(), ctx.quiet);
    std::unique_ptr<SteadyFlowSolver> last;
    double fstar = 0, force_check = 0;
    const double G = 1.0;  // Pa/m; Stokes is linear, F* does not depend on it
    for (std::size_t li = 0; li < levels.size(); ++li) {
      const auto t0 = std::chrono::steady_clock::now();
      FlowProblem p = squareArrayProblem(L, levels[li], phi, mu, G);
      p.method = immersedMethod(c);
      p.supersample = static_cast<int>(c.integer("numerics.supersample"));
      last = std::make_unique<SteadyFlowSolver>(p, solverOptions(c));
      last->solve();
      // Sangani & Acrivos: F = G L^2 per unit length, F* = F / (mu U_darcy).
      fstar = G * L * L / (mu * last->superficialVelocity());
      force_check = last->bodyLoads()[0].force.x() / (G * L * L);
      auto row = ladderRow(li, levels[li], *last, secondsSince(t0), fstar, primary);
      row["force_over_GL2"] = force_check;
      row["max_divergence"] = last->maxRelativeDivergence();
      ladder.push_back(row);
      progress.update(li + 1);
    }
    progress.finish();
    addObservedOrder(ladder, levels);
    out.details["ladder"] = ladder;
    out.details["cells"] = last->stats().cells;
    out.metrics["F_star"] = fstar;
    out.metrics["k_over_L2"] = 1.0 / fstar;
    out.metrics["permeability"] = L * L / fstar;
    out.units["permeability"] = "m2";
    // Self-consistency (no reference needed): the body's drag balances the driving force G L^2.
    out.metrics["drag_balance"] = force_check;
    writeFields(*last, ctx, "fields", out);
    return out;
  };
  return k;
}

CaseKind imagePermeabilityKind() {
  CaseKind k;
  k.name = "image-permeability";
  k.summary = "Permeability and porosity of a pore geometry given as a binary image, pressure-driven left to right";
  k.declare = [](Schema& s) {
    s.path("geometry.mask", "Binary image of the geometry (PNG, TIFF), relative to the case file");
    s.quantity("geometry.pixel_size", "um", "Size of one pixel (the image carries no scale)").positive();
    s.choice("geometry.grains", {"dark", "bright"}, "Which pixels are grains").def("dark");
    s.quantity("geometry.depth", "um", "Chip depth h (depth-averaged model: friction 12 mu u / h^2)").def("20 um").positive();
    s.quantity("fluid.density", "kg/m3", "Fluid density").def("1000 kg/m3").positive();
    s.quantity("fluid.viscosity", "Pa s", "Dynamic viscosity").def("1e-3 Pa s").positive();
    s.quantity("flow.pressure_drop", "Pa", "Inlet minus outlet pressure (keep Re << 1)").def("1 Pa").positive();
    s.real("numerics.cells_per_pixel", "Grid cells per image pixel").def(0.5).min(0.05).max(4);
    s.choice("numerics.depth_model", {"2d", "depth-averaged", "both"},
             "2d: plane flow; depth-averaged: with the Hele-Shaw friction of the chip depth; both: solve both and report their ratio")
        .def("both");
    declareSolverKeys(s, true);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    const std::filesystem::path file = c.path("geometry.mask");
    BoolArray raw;
    try {
      raw = readMask(file, c.text("geometry.grains") == "dark");
    } catch (const std::exception& e) {
      throw InputError(c.where("geometry.mask"), e.what(), file.string(), "a readable PNG/TIFF image");
    }
    PoreSpaceReport pores;
    try {
      pores = analysePoreSpace(raw);
    } catch (const NoFlowPath& e) {
      throw InputError(c.where("geometry.mask"), e.what(), file.string(),
                       "a mask with a connected pore path from the left to the right edge (check geometry.grains polarity)");
    }
    if (pores.porosity_total >= 1.0 && c.text("numerics.depth_model") != "depth-averaged")
      // No grain at all: plane 2D flow between slip sides meets no resistance, so its permeability is unbounded.
      throw InputError(c.where("numerics.depth_model"), "the mask has no grain pixel, so the plane 2D permeability is unbounded (slip sides, no solid)",
                       c.text("numerics.depth_model"), "depth_model = \"depth-averaged\" (gives the parallel-plate k = h^2/12), or a mask with grains");
    const double px = c.quantity("geometry.pixel_size"), depth = c.quantity("geometry.depth");
    const double mu = c.quantity("fluid.viscosity"), dp = c.quantity("flow.pressure_drop");
    const auto shape = std::make_shared<MaskShape>(pores.solid_connected, px);
    const double cpp = c.real("numerics.cells_per_pixel");
    const int nx = std::max(4, static_cast<int>(std::lround(shape->cols() * cpp)));
    const int ny = std::max(4, static_cast<int>(std::lround(shape->rows() * cpp)));
    const std::string model = c.text("numerics.depth_model");
    RunOutput out;
    out.details["solver"] = kSolverName;
    out.details["immersed"] = c.text("numerics.immersed");
    out.details["image_pixels"] = {shape->cols(), shape->rows()};
    out.details["pore_components"] = pores.components;
    out.details["spanning_components"] = pores.spanning_components;
    out.details["boundaries"] = "pressure inlet (left), pressure outlet (right), slip sides";
    nlohmann::json runs = nlohmann::json::array();
    std::map<std::string, double> k_of;
    std::unique_ptr<SteadyFlowSolver> last;
    for (const std::string m : {"2d", "depth-averaged"}) {
      if (model != "both" && model != m) continue;
      const auto t0 = std::chrono::steady_clock::now();
      FlowProblem p;
      p.x = uniformAxis(0, shape->width(), nx);
      p.y = uniformAxis(0, shape->height(), ny);
      p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
      p.boundary[0].pressure = dp;
      p.boundary[2].type = p.boundary[3].type = BoundaryType::slip;
      p.viscosity = mu;
      p.depth = m == "2d" ? 0.0 : depth;
      p.shape = shape;
      p.method = immersedMethod(c);
      last = std::make_unique<SteadyFlowSolver>(p, solverOptions(c));
      last->solve();
      // Darcy: k = mu Q L / (A dp), per unit depth in 2D (Q per depth, A = height).
      const double q = last->flowRate(Side::east);
      const double kk = mu * q * shape->width() / (shape->height() * dp);
      k_of[m] = kk;
      auto row = ladderRow(runs.size(), nx, *last, secondsSince(t0), kk, nullptr);
      row["depth_model"] = m;
      row["mass_balance"] = last->flowRate(Side::west) != 0 ? q / last->flowRate(Side::west) : 0.0;
      runs.push_back(row);
    }
    out.details["runs"] = runs;
    out.details["cells"] = last->stats().cells;
    const double k_main = k_of.count("depth-averaged") ? k_of["depth-averaged"] : k_of["2d"];
    out.metrics["permeability"] = k_main;
    out.units["permeability"] = "D";
    if (k_of.count("2d")) {
      out.metrics["permeability_2d"] = k_of["2d"];
      out.units["permeability_2d"] = "D";
    }
    if (k_of.count("depth-averaged")) {
      out.metrics["permeability_depth_averaged"] = k_of["depth-averaged"];
      out.units["permeability_depth_averaged"] = "D";
    }
    if (k_of.size() == 2) out.metrics["depth_model_ratio"] = k_of["depth-averaged"] / k_of["2d"];
    out.metrics["porosity_total"] = pores.porosity_total;
    out.metrics["porosity_connected"] = pores.porosity_connected;
    out.details["darcy_m2"] = kDarcy;
    writeFields(*last, ctx, "fields", out);
    return out;
  };
  return k;
}

}  // namespace mmval::simulate
