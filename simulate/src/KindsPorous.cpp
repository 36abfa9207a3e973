// Porous-media kinds: periodic square arrays (Stokes permeability) and chip
// permeability from a binary mask.
#include <cmath>

#include <fmt/format.h>

#include "KindsCommon.hpp"
#include "MemoryBudget.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/ThroatCheck.hpp"
#include "mmval/simulate/FieldOutput.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/Petsc.hpp"
#include "mmval/simulate/PoreSpace.hpp"
#include "mmval/simulate/Stokes3D.hpp"

namespace mmval::simulate {

using namespace detail;

namespace {
constexpr double kDarcy = 9.869233e-13;  // m2

/// The coarse 3D model of image-permeability: the (isolated-pore-free) mask block-averaged onto
/// the 3D grid and extruded between no-slip plates; one solve per cells_z level. Adds
/// permeability_3d (last level), its z-extrapolation (with a ladder), the 3D grid's porosity,
/// k_3d / k_depth_averaged, and details.runs_3d (cells, unknowns, iterations, wall time).
void run3d(const Case& c, const RunContext& ctx, const BoolArray& solid, double px, double depth, double mu, double dp, std::map<std::string, double>& k_of,
           RunOutput& out) {
  const double cpp = c.real("numerics.cells_per_pixel_3d");
  const int nx = std::max(4, static_cast<int>(std::lround(solid.cols() * cpp)));
  const int ny = std::max(4, static_cast<int>(std::lround(solid.rows() * cpp)));
  std::vector<int> levels{static_cast<int>(c.integer("numerics.cells_z"))};
  if (c.has("numerics.cells_z_levels")) {
    levels.clear();
    for (const auto v : c.integers("numerics.cells_z_levels")) {
      if (v < 2 || v > 256) throw InputError(c.where("numerics.cells_z_levels"), "a cells_z level is out of range", fmt::format("{}", v), "integers in [2, 256]");
      levels.push_back(static_cast<int>(v));
    }
    if (levels.empty()) throw InputError(c.where("numerics.cells_z_levels"), "the ladder is empty", "[]", "e.g. [4, 8, 16]");
  }
  Stokes3DProblem p;
  p.length = static_cast<double>(solid.cols()) * px;
  p.width = static_cast<double>(solid.rows()) * px;
  p.depth = depth;
  p.nx = nx;
  p.ny = ny;
  p.solid = coarsenMask(solid, nx, ny);  // row j = y cell j (the image mirrored in y: k along x is unchanged)
  p.slip_sides = true;
  p.viscosity = mu;
  p.inlet_pressure = dp;
  p.outlet_pressure = 0;
  Stokes3DOptions o;
  o.schur = c.text("numerics.schur_3d");
  nlohmann::json runs = nlohmann::json::array();
  std::vector<double> ks;
  Stokes3DStats last;
  std::unique_ptr<Stokes3DSolver> s;
  for (const int nz : levels) {
    const auto t0 = std::chrono::steady_clock::now();
    p.nz = nz;
    try {
      s = std::make_unique<Stokes3DSolver>(p, o);
    } catch (const NoFlowPath& e) {
      throw InputError(c.where("numerics.cells_per_pixel_3d"), std::string("the block-averaged 3D mask has no open path: ") + e.what(),
                       fmt::format("{}", cpp), "a larger cells_per_pixel_3d (the throats close when cells are coarser than them)");
    }
    s->solve();
    const double k = s->permeability();
    ks.push_back(k);
    last = s->stats();
    nlohmann::json row;
    row["cells_xyz"] = {nx, ny, nz};
    row["cells"] = last.cells;
    row["fluid_cells"] = last.fluid_cells;
    row["unknowns"] = last.unknowns;
    row["iterations"] = last.iterations;
    row["assemble_seconds"] = last.assemble_seconds;
    row["solve_seconds"] = last.solve_seconds;
    row["wall_seconds"] = secondsSince(t0);
    row["value"] = k;
    row["permeability_D"] = k / kDarcy;
    row["mass_balance"] = s->flowRate(nx) / s->flowRate(0);
    row["max_divergence"] = s->maxRelativeDivergence();
    row["schur"] = o.schur;
    runs.push_back(row);
  }
  out.details["runs_3d"] = runs;
  // Fields of the last level: the whole 3D solution for ParaView, and its mid-depth speed.
  if (!ctx.out_dir.empty()) {
    if (PetscSession::rank() == 0) {
      writeVtr(*s, ctx.out_dir / "fields-3d.vtr");
      writeMidDepthSpeedPng(*s, ctx.out_dir / "fields-3d-middepth-speed.png");
    }
    out.files.push_back("fields-3d.vtr");
    out.files.push_back("fields-3d-middepth-speed.png");
  }
  out.details["cells_3d"] = last.cells;
  out.details["boundaries_3d"] = "pressure inlet/outlet on x, slip sides, no-slip plates at z = 0 and z = depth";
  k_of["3d"] = ks.back();
  out.metrics["permeability_3d"] = ks.back();
  out.units["permeability_3d"] = "D";
  if (ks.size() >= 2 && levels[levels.size() - 1] != levels[levels.size() - 2]) {
    // Richardson in dz with the plate closure's order 2 (exact for plane Poiseuille, Stokes3D.hpp).
    const double r = static_cast<double>(levels.back()) / levels[levels.size() - 2];
    const double kx = ks.back() + (ks.back() - ks[ks.size() - 2]) / (r * r - 1);
    out.metrics["permeability_3d_extrapolated"] = kx;
    out.units["permeability_3d_extrapolated"] = "D";
  }
  out.metrics["porosity_3d_grid"] = last.porosity_connected;
  if (k_of.count("depth-averaged")) out.metrics["k_3d_over_depth_averaged"] = k_of["3d"] / k_of["depth-averaged"];
}
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
    for (const int n : levels)  // before the first level runs: the finest must fit too
      requireSteadyFlowMemory(c, n, n, 0.0, c.has("numerics.levels") ? "numerics.levels" : "numerics.cells_around",
                              "fewer cells along the unit cell (256 give F* within 1 % at phi 0.2)");
    const Acceptance* primary = c.acceptanceFor("F_star");
    RunOutput out;
    out.details["solver"] = kSolverName;
    out.details["immersed"] = immersedLabel(c);
    nlohmann::json ladder = nlohmann::json::array();
    Progress progress("fluid " + c.name(), levels.size(), ctx.quiet);
    std::unique_ptr<SteadyFlowSolver> last;
    double fstar = 0, force_check = 0;
    const double G = 1.0;  // Pa/m; Stokes is linear, F* does not depend on it
    for (std::size_t li = 0; li < levels.size(); ++li) {
      const auto t0 = std::chrono::steady_clock::now();
      FlowProblem p = squareArrayProblem(L, levels[li], phi, mu, G);
      setImmersed(c, p);
      p.supersample = static_cast<int>(c.integer("numerics.supersample"));
      const std::string res_key = c.has("numerics.levels") ? "numerics.levels" : "numerics.cells_around";
      checkThroats(p, res_key, levels[li], out, ctx.quiet);
      last = std::make_unique<SteadyFlowSolver>(p, solverOptions(c));
      solveNamingKey(*last, res_key);
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
    s.choice("numerics.depth_model", {"2d", "depth-averaged", "both", "3d", "all"},
             "2d: plane flow; depth-averaged: with the Hele-Shaw friction of the chip depth; both: solve both and report their ratio; "
             "3d: coarse 3D Stokes of the mask extruded between no-slip plates; all: 2d, depth-averaged and 3d")
        .def("both");
    s.real("numerics.cells_per_pixel_3d", "3D model: grid cells per image pixel in the plane (the mask is block-averaged: a cell is solid if more than half solid)")
        .def(0.25).min(0.02).max(2);
    s.integer("numerics.cells_z", "3D model: cells across the depth").def(8).min(2).max(256);
    s.integerList("numerics.cells_z_levels",
                  "3D model: ladder of cells across the depth (the last is reported, with the Richardson extrapolation of the last two, order 2); absent: cells_z only")
        .optional();
    s.choice("numerics.schur_3d", {"lsc", "selfp", "mass"},
             "3D model: Schur-complement preconditioner (lsc: least-squares commutator with AMG, iterations grow slowly with cells_z; "
             "selfp: B diag(A)^-1 B^T with AMG, iterations grow ~linearly with cells_z; mass: pressure mass matrix / mu, fails to converge on thin chips)")
        .def("lsc");
    declareSolverKeys(s, true);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    const std::filesystem::path file = c.path("geometry.mask");
    // Sizes from the image header, before anything is decoded: the mask's own processing, then the
    // grid the solver builds from it (the 3D model is checked in run3d).
    if (const auto header = requireImageWithin(file, c.where("geometry.mask"), maxMemoryBytes(c), kMaskBytesPerPixel,
                                               "a smaller image: crop or downscale it")) {
      const double cpp = c.real("numerics.cells_per_pixel");
      const std::string model = c.text("numerics.depth_model");
      if (model != "3d")
        requireSteadyFlowMemory(c, std::max(4.0, std::round(header->width * cpp)), std::max(4.0, std::round(header->height * cpp)),
                                kMaskKeptBytesPerPixel * header->pixels(), "numerics.cells_per_pixel",
                                fmt::format("fewer grid cells per image pixel, or a smaller image ({} x {} px)", header->width, header->height));
      if (model == "3d" || model == "all") {
        const double cpp3 = c.real("numerics.cells_per_pixel_3d");
        double nz = static_cast<double>(c.integer("numerics.cells_z"));
        if (c.has("numerics.cells_z_levels"))
          for (const auto v : c.integers("numerics.cells_z_levels")) nz = std::max(nz, static_cast<double>(v));
        const double nx3 = std::max(4.0, std::round(header->width * cpp3)), ny3 = std::max(4.0, std::round(header->height * cpp3));
        requireMemory(c, kStartupBytes + kMaskKeptBytesPerPixel * header->pixels() + nx3 * ny3 * nz * kStokes3DBytesPerCell,
                      fmt::format("the 3D Stokes solve on {:.0f} x {:.0f} x {:.0f} = {:.3g} cells (about {:.1f} kB per cell measured)", nx3, ny3, nz,
                                  nx3 * ny3 * nz, kStokes3DBytesPerCell / 1e3),
                      "numerics.cells_per_pixel_3d", "fewer 3D cells per pixel or across the depth (numerics.cells_z, numerics.cells_z_levels)");
      }
    }
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
    const std::string model = c.text("numerics.depth_model");
    const bool want_2d = model == "2d" || model == "both" || model == "all";
    const bool want_da = model == "depth-averaged" || model == "both" || model == "all";
    const bool want_3d = model == "3d" || model == "all";
    if (pores.porosity_total >= 1.0 && want_2d)
      // No grain at all: plane 2D flow between slip sides meets no resistance, so its permeability is unbounded.
      throw InputError(c.where("numerics.depth_model"), "the mask has no grain pixel, so the plane 2D permeability is unbounded (slip sides, no solid)",
                       model, "depth_model = \"depth-averaged\" or \"3d\" (they give the parallel-plate k = h^2/12), or a mask with grains");
    const double px = c.quantity("geometry.pixel_size"), depth = c.quantity("geometry.depth");
    const double mu = c.quantity("fluid.viscosity"), dp = c.quantity("flow.pressure_drop");
    const auto shape = std::make_shared<MaskShape>(pores.solid_connected, px);
    const double cpp = c.real("numerics.cells_per_pixel");
    const int nx = std::max(4, static_cast<int>(std::lround(shape->cols() * cpp)));
    const int ny = std::max(4, static_cast<int>(std::lround(shape->rows() * cpp)));
    RunOutput out;
    out.details["solver"] = kSolverName;
    out.details["immersed"] = immersedLabel(c);
    out.details["image_pixels"] = {shape->cols(), shape->rows()};
    out.details["pore_components"] = pores.components;
    out.details["spanning_components"] = pores.spanning_components;
    out.details["boundaries"] = "pressure inlet (left), pressure outlet (right), slip sides";
    nlohmann::json runs = nlohmann::json::array();
    std::map<std::string, double> k_of;
    std::unique_ptr<SteadyFlowSolver> last;
    for (const std::string m : {"2d", "depth-averaged"}) {
      if ((m == "2d" && !want_2d) || (m == "depth-averaged" && !want_da)) continue;
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
      setImmersed(c, p);
      if (runs.empty()) checkThroats(p, "numerics.cells_per_pixel", cpp, out, ctx.quiet);
      last = std::make_unique<SteadyFlowSolver>(p, solverOptions(c));
      solveNamingKey(*last, "numerics.cells_per_pixel");
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
    if (last) out.details["cells"] = last->stats().cells;
    if (want_3d) run3d(c, ctx, pores.solid_connected, px, depth, mu, dp, k_of, out);
    const double k_main = k_of.count("depth-averaged") ? k_of["depth-averaged"] : k_of.count("3d") ? k_of["3d"] : k_of["2d"];
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
    if (k_of.count("2d") && k_of.count("depth-averaged")) out.metrics["depth_model_ratio"] = k_of["depth-averaged"] / k_of["2d"];
    out.metrics["porosity_total"] = pores.porosity_total;
    out.metrics["porosity_connected"] = pores.porosity_connected;
    out.details["darcy_m2"] = kDarcy;
    if (last) writeFields(*last, ctx, "fields", out);
    return out;
  };
  return k;
}

}  // namespace mmval::simulate
