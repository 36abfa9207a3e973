// Porous-media kinds: periodic square arrays (Stokes permeability) and chip
// permeability from a binary mask.
#include <cmath>
#include <cstdio>

#include <fmt/format.h>

#include "KindsCommon.hpp"
#include "MemoryBudget.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Checkpoint.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/JsonNumbers.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/simulate/ThroatCheck.hpp"
#include "mmval/simulate/DuctFlow.hpp"
#include "mmval/simulate/FieldOutput.hpp"
#include "mmval/simulate/GridConvergence.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/PeriodicArrayScene.hpp"
#include "mmval/simulate/Petsc.hpp"
#include "mmval/simulate/PoreSpace.hpp"
#include "mmval/simulate/Stokes3D.hpp"

namespace mmval::simulate {

using namespace detail;

namespace {
constexpr double kDarcy = 9.869233e-13;  // m2

/// The levels a ladder has solved, in `checkpoint-levels.json` of the run's staging folder: written
/// after every solved level and read by `mmval run --resume`, so that a run stopped at a later level
/// (killed, out of memory, a solver failure) keeps the levels it had finished. A level's answer does
/// not depend on the ladder's other levels, the linear solver (each row names the solver that gave
/// it; they agree to numerics.residual) or the run's resource limits, so these may change between
/// the stop and the resume; any other key may not.
class LadderCheckpoint {
 public:
  LadderCheckpoint(const Case& c, const RunContext& ctx)
      : m_file(ctx.out_dir.empty() ? std::filesystem::path{} : ctx.out_dir / "checkpoint-levels.json") {
    nlohmann::json f = checkpointFingerprintJson(c);
    if (f.contains("numerics"))
      for (const char* key : {"cells_per_pixel_levels", "linear_solver"}) f["numerics"].erase(key);
    if (f.contains("run"))
      for (const char* key : {"max_memory", "threads"}) f["run"].erase(key);
    m_fingerprint = f.dump();
    if (!ctx.resume || m_file.empty() || !std::filesystem::exists(m_file)) return;
    try {
      const nlohmann::json j = nlohmann::json::parse(readBinaryFile(m_file));
      if (j.at("format") != kFormat) throw std::runtime_error("not an image-permeability ladder checkpoint");
      if (j.at("fingerprint") != m_fingerprint) throw std::runtime_error("it belongs to another version of this case");
      m_rows = j.at("rows");
      if (!m_rows.is_array()) throw std::runtime_error("its rows are not a list");
    } catch (const std::exception& e) {
      throw InputError(c.where("numerics.cells_per_pixel_levels"), fmt::format("cannot resume from {}: {}", m_file.string(), e.what()), {},
                       "delete the .partial folder to start afresh");
    }
  }
  /// The row the stopped run solved for `model` at `cells_per_pixel`, or null.
  const nlohmann::json* find(const std::string& model, double cells_per_pixel) const {
    for (const auto& r : m_rows)
      if (r.value("depth_model", "") == model && r.value("cells_per_pixel", -1.0) == cells_per_pixel) return &r;
    return nullptr;
  }
  /// Records a solved level (rank 0 writes the file, replacing it whole).
  void add(const nlohmann::json& row) {
    m_rows.push_back(row);
    if (m_file.empty() || PetscSession::rank() != 0) return;
    writeFileAtomic(m_file, nlohmann::json{{"format", kFormat}, {"fingerprint", m_fingerprint}, {"rows", m_rows}}.dump());
  }
  const std::filesystem::path& file() const { return m_file; }
  void remove() const {
    std::error_code ec;
    if (!m_file.empty() && PetscSession::rank() == 0) std::filesystem::remove(m_file, ec);
  }

 private:
  static constexpr const char* kFormat = "mmval-image-permeability-levels-1";
  std::filesystem::path m_file;
  std::string m_fingerprint;
  nlohmann::json m_rows = nlohmann::json::array();
};

/// The coarse 3D model of image-permeability: the (isolated-pore-free) mask block-averaged onto
/// the 3D grid and extruded between no-slip plates; one solve per cells_z level. Adds
/// permeability_3d (last level), its z-extrapolation (with a ladder), the 3D grid's porosity,
/// k_3d / k_depth_averaged, and details.runs_3d (cells, unknowns, iterations, wall time).
void run3d(const Case& c, const RunContext& ctx, const BoolArray& solid, double px, double depth, double mu, double dp, std::map<std::string, double>& k_of,
           RunOutput& out) {
  const double cpp = c.real("numerics.cells_per_pixel_3d");
  std::vector<int> levels{static_cast<int>(c.integer("numerics.cells_z"))};
  if (c.has("numerics.cells_z_levels")) {
    levels.clear();
    for (const auto v : c.integers("numerics.cells_z_levels")) {
      if (v < 2 || v > 256) throw InputError(c.where("numerics.cells_z_levels"), "a cells_z level is out of range", fmt::format("{}", v), "integers in [2, 256]");
      levels.push_back(static_cast<int>(v));
    }
    if (levels.empty()) throw InputError(c.where("numerics.cells_z_levels"), "the ladder is empty", "[]", "e.g. [4, 8, 16]");
  }
  Stokes3DProblem p = maskStokes3DProblem(solid, px, depth, mu, dp, cpp);
  const int nx = p.nx, ny = p.ny;
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
  if (const auto kx = extrapolateInDepthCells(levels, ks)) {
    out.metrics["permeability_3d_extrapolated"] = *kx;
    out.units["permeability_3d_extrapolated"] = "D";
  }
  out.metrics["porosity_3d_grid"] = last.porosity_connected;
  if (k_of.count("depth-averaged")) out.metrics["k_3d_over_depth_averaged"] = k_of["3d"] / k_of["depth-averaged"];
}

/// numerics.cells_per_pixel_levels (strictly increasing) if given, else numerics.cells_per_pixel.
std::vector<double> cellsPerPixelLevels(const Case& c) {
  if (!c.has("numerics.cells_per_pixel_levels")) return {c.real("numerics.cells_per_pixel")};
  const std::vector<double> levels = c.reals("numerics.cells_per_pixel_levels");
  if (levels.empty()) throw InputError(c.where("numerics.cells_per_pixel_levels"), "the ladder is empty", "[]", "e.g. [0.5, 1, 2, 4]");
  for (std::size_t i = 1; i < levels.size(); ++i)
    if (!(levels[i] > levels[i - 1] * 1.05))
      throw InputError(c.where("numerics.cells_per_pixel_levels"), "the levels must grow, coarse to fine, by more than 5 % each",
                       fmt::format("{} after {}", levels[i], levels[i - 1]), "e.g. [0.5, 1, 2, 4]");
  return levels;
}

/// The key that set the resolution: the ladder if given.
std::string resolutionKey(const Case& c) {
  return c.has("numerics.cells_per_pixel_levels") ? "numerics.cells_per_pixel_levels" : "numerics.cells_per_pixel";
}

/// The grains the solver sees (geometry.boundary) and the pixel mask the throat check reads.
struct ImageGeometry {
  std::shared_ptr<const Shape> grains;
  std::shared_ptr<const MaskShape> pixels;
  double width_m = 0, height_m = 0;
  double formal_order = 1;  ///< of the permeability in the grid spacing: 1 on the staircase, 2 on a smooth boundary
  std::string label;        ///< result.json's details.boundary
};

ImageGeometry imageGeometry(const Case& c, const BoolArray& solid, double px) {
  ImageGeometry g;
  g.pixels = std::make_shared<MaskShape>(solid, px);
  g.width_m = g.pixels->width();
  g.height_m = g.pixels->height();
  if (c.text("geometry.boundary") == "smooth") {
    const double sigma = c.real("geometry.smoothing");
    g.grains = std::make_shared<SmoothMaskShape>(solid, px, sigma);
    g.formal_order = 2;
    g.label = fmt::format("smooth (1/2 level of the mask smoothed by a Gaussian of {:g} px, cubic interpolation)", sigma);
  } else {
    g.grains = g.pixels;
    g.label = "pixels (the mask's staircase)";
  }
  return g;
}

/// Pressure-driven flow left to right through the image at `cpp` cells per pixel, slip sides;
/// depth 0: plane 2D.
FlowProblem imageProblem(const ImageGeometry& g, double cpp, double mu, double dp, double depth) {
  FlowProblem p;
  p.x = uniformAxis(0, g.width_m, std::max(4, static_cast<int>(std::lround(g.pixels->cols() * cpp))));
  p.y = uniformAxis(0, g.height_m, std::max(4, static_cast<int>(std::lround(g.pixels->rows() * cpp))));
  p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
  p.boundary[0].pressure = dp;
  p.boundary[2].type = p.boundary[3].type = BoundaryType::slip;
  p.viscosity = mu;
  p.depth = depth;
  p.shape = g.grains;
  return p;
}

/// result.json's details.grid_convergence entry of one depth model (permeabilities in darcy).
nlohmann::json convergenceJson(const GridConvergence& g, const nlohmann::json& rows) {
  auto darcy = [](double v) { return finiteOrNull(v / kDarcy); };
  nlohmann::json j = {{"status", g.status},
                      {"note", g.note},
                      {"levels", rows.size()},
                      {"permeability_fine_D", darcy(g.fine)},
                      {"permeability_extrapolated_D", darcy(g.extrapolated)},
                      {"gci", finiteOrNull(g.gci)},
                      {"band_D", {darcy(g.band_lo), darcy(g.band_hi)}},
                      {"safety_factor", finiteOrNull(g.safety_factor)},
                      {"order_used", finiteOrNull(g.order_used)},
                      {"method", "Celik et al. 2008 (J. Fluids Eng. 130, 078001): observed order from the three finest levels, Richardson "
                                 "extrapolation, GCI = Fs |e21| / (r21^p - 1), Fs = 1.25 (3 without an observed order); four or more levels: the "
                                 "least-squares fit below stands for the ladder (status \"least squares\")"}};
  j["observed_order"] = g.has_order ? nlohmann::json(g.observed_order) : nlohmann::json(g.status);
  if (g.has_fit)
    j["least_squares"] = {{"levels", g.fit_levels},
                          {"order", g.fit_order},
                          {"permeability_extrapolated_D", darcy(g.fit_extrapolated)},
                          {"scatter_D", darcy(g.fit_scatter)},
                          {"uncertainty", finiteOrNull(g.fit_uncertainty)},
                          {"order_used", g.fit_order_used},
                          {"method", "Eca & Hoekstra 2014 (J. Comput. Phys. 262, 104): f = f0 + a h^p fitted to every level; uncertainty of "
                                     "the finest Fs |f1 - f0| + scatter + |f1 - fit(h1)|, Fs 1.25 for 0.5 <= p <= 2.1, else the formal "
                                     "order's fit with Fs 3"}};
  return j;
}

/// The ladder's metrics of one depth model: extrapolated permeability and observed order when
/// the convergence is monotone, the finest level's GCI always.
void addConvergenceMetrics(const std::string& m, const GridConvergence& g, RunOutput& out, bool quiet) {
  const bool two_d = m == "2d";
  if (std::isfinite(g.extrapolated)) {
    if (two_d) {
      out.metrics["permeability_2d_extrapolated"] = g.extrapolated;
      out.units["permeability_2d_extrapolated"] = "D";
    } else {
      out.metrics["permeability_depth_averaged_extrapolated"] = g.extrapolated;
      out.units["permeability_depth_averaged_extrapolated"] = "D";
    }
  }
  if (g.has_order) {
    if (two_d) out.metrics["permeability_2d_observed_order"] = g.observed_order;
    else out.metrics["permeability_depth_averaged_observed_order"] = g.observed_order;
  }
  if (std::isfinite(g.gci)) {
    if (two_d) out.metrics["permeability_2d_gci"] = g.gci;
    else out.metrics["permeability_depth_averaged_gci"] = g.gci;
  }
  if (!g.has_order) {
    const std::string w = fmt::format("{} permeability: {}", m, g.note);
    if (!out.details.contains("warnings")) out.details["warnings"] = nlohmann::json::array();
    out.details["warnings"].push_back(w);
    if (!quiet && PetscSession::rank() == 0) std::fprintf(stderr, "mmval: warning: %s\n", w.c_str());
  }
}
/// Above this excess of the depth-averaged model over exact duct flow at the narrowest throat, the
/// image kind warns: on two generated chips the whole chip's depth-averaged k exceeded coarse 3D
/// Stokes by about what its narrowest throat's duct excess says (docs/validation/depth-model.md).
constexpr double kWarnDepthModelExcess = 0.03;

/// The narrowest throat on the flow path as a rectangular duct of the chip's depth: how much more
/// flow the depth-averaged model carries through it than Stokes does (details.depth_model_throat),
/// and a warning above kWarnDepthModelExcess unless the 3D model runs beside it.
void checkDepthModelAtThroat(const Throat& t, double depth, bool with_3d, RunOutput& out, bool quiet) {
  if (!t.path || !std::isfinite(t.width_m) || !(depth > 0)) return;
  const double excess = depthAveragedDuctExcess(t.width_m, depth);
  out.details["depth_model_throat"] = {{"width_m", t.width_m},
                                       {"depth_m", depth},
                                       {"width_over_depth", t.width_m / depth},
                                       {"duct_excess", excess},
                                       {"definition", "the depth-averaged (Brinkman-Hele-Shaw) model's flow through a straight duct of the "
                                                      "narrowest throat's width and the chip's depth over the exact Stokes duct flow, minus 1"}};
  if (excess <= kWarnDepthModelExcess || with_3d) return;
  const std::string w = fmt::format(
      "depth model: the flow path's tightest throat is {:.3g} um wide in a {:.3g} um deep chip; through a duct of that shape the "
      "depth-averaged model carries {:.1f} % more flow than exact Stokes, so its permeability is likely high by up to about that; "
      "numerics.depth_model = \"all\" adds the coarse 3D model to measure it",
      t.width_m * 1e6, depth * 1e6, 100 * excess);
  if (!out.details.contains("warnings")) out.details["warnings"] = nlohmann::json::array();
  out.details["warnings"].push_back(w);
  if (!quiet && PetscSession::rank() == 0) std::fprintf(stderr, "mmval: warning: %s\n", w.c_str());
}
}  // namespace

CaseKind periodicArrayKind() {
  CaseKind k;
  k.name = "periodic-array";
  k.summary = "Periodic square array of cylinders in creeping flow: dimensionless drag F* = F / (mu U) and permeability";
  k.declare = [](Schema& s) {
    s.quantity("geometry.cell", "um", "Side L of the square unit cell").def("100 um").positive();
    s.quantity("geometry.solid_fraction", "1", "Solid area fraction phi = pi a^2 / L^2").min(0.0, true).max(0.75);
    declareFluid(s, {.viscosity = 1e-3, .density = 1000.0});
    s.quantity("flow.mean_velocity", "m/s", "Mean velocity scale (keep Re << 1; mmval solves Stokes, so F* does not depend on it)").def("1e-4 m/s").positive();
    s.integer("numerics.cells_per_side",
              "Resolution: cells along the unit-cell side L, so the grid spacing is h = L / cells_per_side in both solvers (mmval: "
              "uniform square cells of side h; OpenFOAM: an O-grid whose cells around the cylinder are pi D / h rounded to a multiple "
              "of 4, at least 8, so that its surface spacing is h too; result.json's ladder records both numbers)")
        .def(64)
        .min(8)
        .max(4096);
    s.integerList("numerics.levels", "Resolution ladder (cells_per_side per level); absent: one run at cells_per_side").optional();
    s.renamed("numerics.cells_around", "numerics.cells_per_side",
              "the array's resolution is the cells along the unit-cell side in both solvers (the OpenFOAM peer derives its cells "
              "around the cylinder from it); the value is not carried over, because cells_around meant cells around the cylinder to the peer");
    s.integer("numerics.supersample", "Penalized method: samples per face control volume and direction").def(6).min(1).max(32);
    declareSolverKeys(s, true);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    // The scene the OpenFOAM peer reads too (one reader; it refuses touching cylinders).
    const PeriodicArrayScene scene = readPeriodicArrayScene(c);
    const double L = scene.cell_m, phi = scene.solid_fraction, mu = scene.viscosity_pa_s;
    const std::vector<int> levels = levelsOf(c, "numerics.cells_per_side", 8, 4096);
    const std::string res_key = c.has("numerics.levels") ? "numerics.levels" : "numerics.cells_per_side";
    for (const int n : levels)  // before the first level runs: the finest must fit too
      requireSteadyFlowMemory(c, n, n, 0.0, res_key, "fewer cells along the unit cell (256 give F* within 1 % at phi 0.2)");
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
      const LevelClock clock;
      FlowProblem p = squareArrayProblem(L, levels[li], phi, mu, G);
      setImmersed(c, p);
      p.supersample = static_cast<int>(c.integer("numerics.supersample"));
      checkThroats(p, res_key, levels[li], out, ctx.quiet);
      last = std::make_unique<SteadyFlowSolver>(p, solverOptions(c, ctx.quiet));
      solveNamingKey(*last, res_key);
      // Sangani & Acrivos: F = G L^2 per unit length, F* = F / (mu U_darcy).
      fstar = G * L * L / (mu * last->superficialVelocity());
      force_check = last->bodyLoads()[0].force.x() / (G * L * L);
      auto row = ladderRow(li, levels[li], *last, clock, fstar, primary);
      row["cells_per_side"] = levels[li];
      row["spacing_m"] = L / levels[li];
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
    declareMask(s, {.mask_doc = "Binary image of the geometry"});
    s.quantity("geometry.depth", "um", "Chip depth h (depth-averaged model: friction 12 mu u / h^2)").def("20 um").positive();
    declareFluid(s, {.viscosity = 1e-3, .density = 1000.0});
    s.quantity("flow.pressure_drop", "Pa", "Inlet minus outlet pressure (keep Re << 1)").def("1 Pa").positive();
    s.choice("geometry.boundary", {"pixels", "smooth"},
             "Grain boundary the 2D and depth-averaged models cut their cells against: pixels (the mask's staircase: the permeability "
             "converges at about first order in cells per pixel, and on disc packings rendered to pixels it settled 17-41 % below the "
             "discs' own) or smooth (reconstructed below pixel resolution: the 1/2 level of the mask smoothed by geometry.smoothing, cubic "
             "interpolation, every pixel centre kept on its side: second order, 1-3 % above the discs'). pixels is the default because the "
             "coarse 3D model still meshes the pixels; the OpenFOAM peer meshes whichever boundary is chosen")
        .def("pixels");
    s.real("geometry.smoothing", "Smooth boundary: Gaussian width in pixels applied to the mask before its 1/2 level is taken (0.75 removes the "
                                 "staircase's pixel-period steps; wider rounds corners more and narrows gaps of 1-2 pixels)")
        .def(0.75)
        .min(0)
        .max(4);
    s.real("numerics.cells_per_pixel", "Grid cells per image pixel").def(0.5).min(0.05).max(4);
    s.realList("numerics.cells_per_pixel_levels",
               "Ladder of grid cells per image pixel, coarse to fine (e.g. [0.5, 1, 2, 4]): every depth model is solved at each level; "
               "result.json gets each level's permeability, cells and time, the observed order, the Richardson-extrapolated permeability and "
               "the finest level's grid convergence index (GCI). Absent: one run at cells_per_pixel")
        .optional()
        .min(0.05)
        .max(8);
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
    s.integer("run.stop_after_levels",
              "Stop (as if killed) after this many solved levels, keeping them in checkpoint-levels.json; `mmval run --resume` "
              "continues with the next level and a resumed run does not stop again (0: run to the end; tests)")
        .def(0)
        .min(0);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    const std::filesystem::path file = c.path("geometry.mask");
    const std::vector<double> levels = cellsPerPixelLevels(c);
    const std::string res_key = resolutionKey(c);
    // Sizes from the image header, before anything is decoded: the mask's own processing, then the
    // grid the solver builds from it at the finest level (the 3D model is checked in run3d).
    if (const auto header = requireImageWithin(file, c.where("geometry.mask"), maxMemoryBytes(c), kMaskBytesPerPixel,
                                               "a smaller image: crop or downscale it")) {
      const double cpp = levels.back();
      const std::string model = c.text("numerics.depth_model");
      if (model != "3d")
        requireSteadyFlowMemory(c, std::max(4.0, std::round(header->width * cpp)), std::max(4.0, std::round(header->height * cpp)),
                                kMaskKeptBytesPerPixel * header->pixels(), res_key,
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
    const ImageGeometry geo = imageGeometry(c, pores.solid_connected, px);
    RunOutput out;
    out.details["solver"] = kSolverName;
    out.details["immersed"] = immersedLabel(c);
    out.details["boundary"] = geo.label;
    out.details["image_pixels"] = {geo.pixels->cols(), geo.pixels->rows()};
    out.details["pore_components"] = pores.components;
    out.details["spanning_components"] = pores.spanning_components;
    out.details["boundaries"] = "pressure inlet (left), pressure outlet (right), slip sides";
    nlohmann::json runs = nlohmann::json::array(), convergence = nlohmann::json::object();
    std::map<std::string, double> k_of;
    std::unique_ptr<SteadyFlowSolver> last;
    const Acceptance* primary = c.acceptanceFor("permeability");
    Progress progress("fluid " + c.name(), levels.size() * ((want_2d ? 1 : 0) + (want_da ? 1 : 0)), ctx.quiet);
    std::size_t done = 0, solved = 0;
    int resumed_levels = 0;
    LadderCheckpoint checkpoint(c, ctx);
    const long long stop_after = c.integer("run.stop_after_levels");
    for (const std::string m : {"2d", "depth-averaged"}) {
      if ((m == "2d" && !want_2d) || (m == "depth-averaged" && !want_da)) continue;
      const bool first_model = runs.empty();
      nlohmann::json rows = nlohmann::json::array();
      std::vector<double> h, ks;
      std::vector<int> nxs;
      for (std::size_t li = 0; li < levels.size(); ++li) {
        const LevelClock clock;
        FlowProblem p = imageProblem(geo, levels[li], mu, dp, m == "2d" ? 0.0 : depth);
        setImmersed(c, p);
        ThroatFound throat;
        if (first_model) {
          // The throat of the image (its pixels), on this level's grid.
          FlowProblem pc = p;
          pc.shape = geo.pixels;
          checkThroats(pc, res_key, levels[li], out, ctx.quiet, kWarnImageThroatCells, px, &throat);
        }
        // The final level of the final model is always solved: its solver writes the fields.
        const bool final_solve = li + 1 == levels.size() && (m == "depth-averaged" || !want_da);
        if (const nlohmann::json* kept = final_solve ? nullptr : checkpoint.find(m, levels[li])) {
          nlohmann::json row = *kept;
          row["level"] = li;
          rows.push_back(row);
          runs.push_back(row);
          const int nx = row.at("nx").get<int>();
          h.push_back(geo.width_m / nx);
          ks.push_back(row.at("value").get<double>());
          nxs.push_back(nx);
          ++resumed_levels;
          progress.update(++done);
          continue;
        }
        last = std::make_unique<SteadyFlowSolver>(p, solverOptions(c, ctx.quiet));
        solveNamingKey(*last, res_key);
        // Darcy: k = mu Q L / (A dp), per unit depth in 2D (Q per depth, A = height).
        const double q = last->flowRate(Side::east);
        const double kk = mu * q * geo.width_m / (geo.height_m * dp);
        auto row = ladderRow(li, last->nx(), *last, clock, kk, primary);
        row["depth_model"] = m;
        row["cells_per_pixel"] = levels[li];
        row["permeability_D"] = kk / kDarcy;
        row["mass_balance"] = last->flowRate(Side::west) != 0 ? q / last->flowRate(Side::west) : 0.0;
        if (first_model && std::isfinite(throat.cells) && throat.throat.path) row["throat_cells"] = throat.cells;
        rows.push_back(row);
        runs.push_back(row);
        h.push_back(geo.width_m / last->nx());
        ks.push_back(kk);
        nxs.push_back(last->nx());
        progress.update(++done);
        checkpoint.add(row);
        if (stop_after > 0 && resumed_levels == 0 && ++solved == static_cast<std::size_t>(stop_after) && !final_solve)
          throw RunStopped(fmt::format("stopped after {} solved levels as asked (run.stop_after_levels); {} holds them, continue with `mmval run --resume`",
                                       stop_after, checkpoint.file().string()));
      }
      addObservedOrder(rows, nxs);
      k_of[m] = ks.back();
      // In darcy, so that the notes read in the unit of the results; back to m2 for the metrics.
      std::vector<double> ks_darcy;
      for (const double v : ks) ks_darcy.push_back(v / kDarcy);
      GridConvergence g = gridConvergence(h, ks_darcy, geo.formal_order);
      for (double* v : {&g.fine, &g.extrapolated, &g.band_lo, &g.band_hi, &g.fit_extrapolated, &g.fit_scatter}) *v *= kDarcy;
      convergence[m] = convergenceJson(g, rows);
      if (levels.size() >= 2) addConvergenceMetrics(m, g, out, ctx.quiet);
      if ((m == "depth-averaged" || !want_da) && levels.size() >= 2) out.details["ladder"] = rows;
    }
    progress.finish();
    out.details["runs"] = runs;
    setDetail(out.details, DetailField::resumed_levels, resumed_levels);
    if (levels.size() >= 2) out.details["grid_convergence"] = convergence;
    if (last) out.details["cells"] = last->stats().cells;
    const Throat narrowest = narrowestThroat(geo.pixels->mask(), px);
    if (narrowest.path && std::isfinite(narrowest.width_m))
      out.details["narrowest_throat"] = {{"x_px", std::floor(narrowest.x_m / px)}, {"y_px", std::floor((geo.height_m - narrowest.y_m) / px)},
                                         {"width_px", narrowest.width_m / px}, {"width_m", narrowest.width_m}};
    if (want_da) checkDepthModelAtThroat(narrowest, depth, want_3d, out, ctx.quiet);
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
    checkpoint.remove();  // complete: the results replace it
    return out;
  };
  return k;
}

}  // namespace mmval::simulate
