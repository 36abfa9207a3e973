#include "mmval/core/JsonNumbers.hpp"
#include "mmval/openfoam/Kinds.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/openfoam/Peer.hpp"
#include "mmval/simulate/CylinderScene.hpp"
#include "mmval/simulate/GridConvergence.hpp"
#include "mmval/simulate/PeriodicArrayScene.hpp"

namespace mmval::openfoam {

namespace {

constexpr double kDarcy = 9.869233e-13;  // m2 per darcy
constexpr int kSmoothSurfaceLevel = 1;
constexpr int kCellsBetweenLevels = 3;
/// Largest relative difference between the meshed pore fraction and the boundary's before the
/// peer warns: a peer compared with mmval to 2 % in permeability must mesh the same pore space
/// to a fraction of that (docs/validation/peer-smooth.md).
constexpr double kMeshPorosityTolerance = 0.005;

/// The peer's scene of a cylinder-channel case: the solver-neutral scene mmval's own solver also
/// builds from (simulate::readCylinderScene), plus the peer's numerics.
Scene cylinderScene(const Case& c) {
  Scene s = peerScene(simulate::readCylinderScene(c));
  s.unsteady = c.text("numerics.mode") == "unsteady";
  if (s.unsteady) {
    s.end_time = c.quantity("numerics.end_time");
    s.dt = c.quantity("numerics.time_step");
    // The same statistics window and start as mmval's own run of the case (KindsCylinderUnsteady.cpp).
    s.statistics_from = c.has("numerics.statistics_from") ? c.quantity("numerics.statistics_from") : 0.5 * s.end_time;
    s.initial_perturbation = c.real("numerics.initial_perturbation");
  }
  s.max_iterations = static_cast<int>(c.integer("numerics.max_iterations"));
  s.residual = c.real("numerics.residual");
  return s;
}

/// The peer's scene of a periodic-array case: the solver-neutral scene (simulate::readPeriodicArrayScene)
/// at the case's numerics.cells_per_side, plus the peer's numerics.
Scene arrayScene(const Case& c) {
  Scene s = peerScene(simulate::readPeriodicArrayScene(c), static_cast<int>(c.integer("numerics.cells_per_side")));
  s.max_iterations = static_cast<int>(c.integer("numerics.max_iterations"));
  s.residual = c.real("numerics.residual");
  return s;
}

/// One depth model of an image ladder: its name (numerics.depth_model's word, a metric's infix)
/// and the chip depth its friction uses (0: plane 2D).
struct DepthModel {
  std::string name;
  double depth_m = 0;
};

/// The depth models the peer solves for an image case, in mmval's order (2d first): 2d,
/// depth-averaged (geometry.depth), or both for "both" and "all" (the peer has no 3D model; "3d"
/// alone is refused naming the key).
std::vector<DepthModel> imageDepthModels(const Case& c) {
  const std::string model = c.text("numerics.depth_model");
  if (model == "3d")
    throw InputError(c.where("numerics.depth_model"), "the OpenFOAM peer solves no 3D model of a chip", model,
                     "\"2d\", \"depth-averaged\", \"both\" or \"all\" (the peer then runs its 2d and depth-averaged parts)");
  std::vector<DepthModel> out;
  if (model != "depth-averaged") out.push_back({"2d", 0.0});
  if (model != "2d") out.push_back({"depth-averaged", c.quantity("geometry.depth")});
  return out;
}

Scene imageScene(const Case& c) {
  Scene s;
  s.kind = Scene::Kind::image;
  s.mask = c.path("geometry.mask");
  s.pixel = c.quantity("geometry.pixel_size");
  s.grain_dark = c.text("geometry.grains") == "dark";
  s.cells_per_pixel = c.real("numerics.cells_per_pixel");
  s.smooth_boundary = c.text("geometry.boundary") == "smooth";
  s.smoothing_px = c.real("geometry.smoothing");
  // The smooth route refines once at the grains (cells there at cells_per_pixel, the background
  // at half of it) with three cells per band: the narrowest throats (4-5 px) lie wholly in the
  // refined band at 1 cell per pixel and more, and each ladder level scales both sizes alike.
  s.surface_level = s.smooth_boundary ? kSmoothSurfaceLevel : 0;
  s.cells_between_levels = kCellsBetweenLevels;
  s.rho = c.quantity("fluid.density");
  s.nu = c.quantity("fluid.viscosity") / s.rho;
  s.pressure_drop = c.quantity("flow.pressure_drop") / s.rho;
  s.max_iterations = static_cast<int>(c.integer("numerics.max_iterations"));
  s.residual = c.real("numerics.residual");
  s.hele_shaw_depth = imageDepthModels(c).back().depth_m;  // the model of the case's `permeability`, as mmval's
  return s;
}

/// The case's first acceptance entry on `metric` with a single, nonzero reference value: what a
/// ladder row's error is taken against (an interval gives no relative error).
const Acceptance* pointReference(const Case& c, const std::string& metric) {
  for (const Acceptance& a : c.acceptance())
    if (a.metric == metric && !a.reference.isInterval() && a.reference.value != 0) return &a;
  return nullptr;
}

/// The primary metric of a kind: the one whose error the ladder records. An unsteady cylinder's
/// last instant's c_D is a phase of the shedding, not a result: its primary metric is c_D max when
/// the case judges that against a single value (Schaefer-Turek 2D-2 against FEATFLOW level 6), as
/// mmval's own unsteady ladder does (KindsCylinderUnsteady.cpp), else the time-mean c_D.
std::string primaryMetric(const Case& c, bool unsteady) {
  if (c.kind() == "cylinder-channel") {
    if (!unsteady) return "c_D";
    return pointReference(c, "c_D_max") != nullptr ? "c_D_max" : "c_D_mean";
  }
  if (c.kind() == "periodic-array") return "F_star";
  return "permeability";
}

void addMetrics(const Scene& s, const Result& r, RunOutput& out) {
  auto put = [&](const char* name, const std::optional<double>& v, const char* unit = "1") {
    if (v) {
      out.metrics[name] = *v;
      out.units[name] = unit;
    }
  };
  put("c_D", r.c_d);
  put("c_L", r.c_l);
  put("dp", r.dp, "Pa");
  put("c_D_max", r.c_d_max);
  put("c_D_mean", r.c_d_mean);
  put("c_L_max", r.c_l_max);
  put("St", r.strouhal);
  put("F_star", r.f_star);
  if (s.kind == Scene::Kind::periodic_array && r.permeability) {
    put("k_over_L2", *r.permeability / (s.cell * s.cell));
    put("permeability", r.permeability, "m2");
  }
  if (s.kind == Scene::Kind::image) {
    put("permeability", r.permeability, "D");
    put("porosity_total", r.porosity_total);
    put("porosity_connected", r.porosity_connected);
    put("porosity_mesh", r.porosity_mesh);
    put(s.hele_shaw_depth > 0 ? "permeability_depth_averaged" : "permeability_2d", r.permeability, "D");
  }
}

/// A run's warnings: kept for details.warnings and, unless quiet, printed as they arise.
struct Warnings {
  std::string case_name;
  bool quiet = false;
  nlohmann::json list = nlohmann::json::array();

  void add(const std::string& text) {
    list.push_back(text);
    if (!quiet) std::fprintf(stderr, "mmval: warning: %s: %s\n", case_name.c_str(), text.c_str());
  }
};

/// An image level's mesh in its ladder row: the meshed pore fraction against the boundary's (the
/// STL's) and the mask's, snappyHexMesh's time; a warning when the mesh misses the boundary's
/// pore fraction by more than kMeshPorosityTolerance.
void addImageMeshRow(const Scene& s, const Result& r, const std::string& sub, nlohmann::json& row, Warnings& warnings) {
  row["mesher"] = s.direct_mesh ? "direct" : "snappyHexMesh";
  if (s.direct_mesh) {
    const MesherReport& m = r.mesher;
    row["mesher_seconds"] = m.seconds;
    row["mesher_vertices"] = {{"wall", m.wall_vertices}, {"snapped", m.snapped}, {"pulled_back", m.pulled_back}, {"pinned", m.pinned}};
    row["mesher_max_move_cells"] = m.max_move_cells;
    row["mesher_min_cell_area_ratio"] = m.min_cell_area_ratio;
    row["mesher_dropped_disconnected_cells"] = m.dropped_disconnected;
  } else {
    row["snappy_seconds"] = r.snappy_seconds;
    row["surface_level"] = s.surface_level;
  }
  row["max_non_orthogonality_deg"] = finiteOrNull(r.max_non_orthogonality);
  row["max_skewness"] = finiteOrNull(r.max_skewness);
  row["porosity_mesh"] = r.porosity_mesh;
  row["porosity_boundary"] = r.porosity_boundary;
  row["porosity_mask"] = r.porosity_connected;
  if (r.porosity_boundary <= 0) return;
  const double miss = r.porosity_mesh / r.porosity_boundary - 1;
  row["porosity_mesh_error"] = miss;
  if (std::abs(miss) > kMeshPorosityTolerance)
    warnings.add(fmt::format("the mesh in {} has pore fraction {:.4f}, {:+.2f} % from the {} boundary's {:.4f} (more than {:.1f} %): "
                             "{}; refine (numerics.cells_per_pixel_levels)",
                             sub, r.porosity_mesh, 100 * miss, s.smooth_boundary ? "smooth" : "pixel", r.porosity_boundary, 100 * kMeshPorosityTolerance,
                             s.direct_mesh ? "the mesher's grid misses grains or throats under a cell" : "snappyHexMesh did not hold the grains (see log.snappyHexMesh)"));
}

/// The image ladder's grid convergence of one depth model (Celik et al. 2008 via
/// simulate::gridConvergence, spacing 1 / cells_per_pixel): details.grid_convergence.<model> and the
/// permeability_<model>_* metrics (model 2d or depth_averaged), as mmval's own image kind reports
/// them. Formal order 2 on the smooth (snapped) boundary, 1 on the staircase.
void addImageConvergence(const Scene& s, const std::string& model, const std::vector<double>& cpp, const nlohmann::json& ladder, RunOutput& out,
                         Warnings& warnings) {
  std::vector<double> h, k;
  for (std::size_t i = 0; i < ladder.size(); ++i)
    if (ladder[i].contains("value")) {
      h.push_back(1.0 / cpp[i]);
      k.push_back(ladder[i]["value"].get<double>() / kDarcy);
    }
  if (h.size() < 2) return;
  const simulate::GridConvergence g = simulate::gridConvergence(h, k, s.smooth_boundary ? 2.0 : 1.0);
  nlohmann::json& gc = out.details["grid_convergence"][model];
  gc = {{"status", g.status}, {"note", g.note}, {"levels", h.size()},
                                     {"permeability_fine_D", finiteOrNull(g.fine)}, {"permeability_extrapolated_D", finiteOrNull(g.extrapolated)},
                                     {"observed_order", g.has_order ? nlohmann::json(g.observed_order) : nlohmann::json(g.status)},
                                     {"gci", finiteOrNull(g.gci)}, {"order_used", finiteOrNull(g.order_used)},
                                     {"method", "Celik et al. 2008 (J. Fluids Eng. 130, 078001): observed order from the three finest levels, "
                                                "Richardson extrapolation, GCI = Fs |e21| / (r21^p - 1); four or more levels: the least-squares "
                                                "fit stands for the ladder (status \"least squares\")"}};
  if (g.has_fit)
    gc["least_squares"] = {{"levels", g.fit_levels}, {"order", g.fit_order},
                                                        {"permeability_extrapolated_D", finiteOrNull(g.fit_extrapolated)}, {"scatter_D", finiteOrNull(g.fit_scatter)},
                                                        {"uncertainty", finiteOrNull(g.fit_uncertainty)}, {"order_used", g.fit_order_used},
                                                        {"method", "Eca & Hoekstra 2014 (J. Comput. Phys. 262, 104), as mmval's image kind"}};
  // Literal names, one branch per model, so that tests/apps/MetricContractTest.cpp sees each one.
  const bool extrapolated = std::isfinite(g.extrapolated), gci = std::isfinite(g.gci);
  if (model == "2d") {
    if (extrapolated) out.metrics["permeability_2d_extrapolated"] = g.extrapolated * kDarcy;
    if (g.has_order) out.metrics["permeability_2d_observed_order"] = g.observed_order;
    if (gci) out.metrics["permeability_2d_gci"] = g.gci;
    if (extrapolated) out.units["permeability_2d_extrapolated"] = "D";
  } else {
    if (extrapolated) out.metrics["permeability_depth_averaged_extrapolated"] = g.extrapolated * kDarcy;
    if (g.has_order) out.metrics["permeability_depth_averaged_observed_order"] = g.observed_order;
    if (gci) out.metrics["permeability_depth_averaged_gci"] = g.gci;
    if (extrapolated) out.units["permeability_depth_averaged_extrapolated"] = "D";
  }
  if (!g.has_order) warnings.add(model + " permeability (OpenFOAM): " + g.note);
}

/// A case's resolution ladder as the peer solves it. `levels` are the O-grid's cells around a
/// cylinder, the cells along a periodic array's unit-cell side (mmval's h = L / n), or for an
/// image the indices 0, 1, ... of `cells_per_pixel` (numerics.cells_per_pixel_levels, cells per
/// pixel at the grains, as mmval's own image ladder).
struct Ladder {
  std::vector<int> levels;
  std::vector<double> cells_per_pixel;  ///< image only
};

/// Stage 1, the ladder: --levels, else numerics.levels, else the kind's single resolution key; an
/// image's numerics.cells_per_pixel_levels or numerics.cells_per_pixel. A level out of range is an
/// InputError naming the key it came from.
Ladder readLadder(const Case& c, const PeerRunOptions& options) {
  const bool image = c.kind() == "image-permeability";
  const bool array = c.kind() == "periodic-array";
  Ladder ladder;
  if (options.levels) {
    ladder.levels = *options.levels;
  } else if (!image && c.has("numerics.levels")) {
    for (auto v : c.integers("numerics.levels")) ladder.levels.push_back(static_cast<int>(v));
  }
  if (image) {
    ladder.cells_per_pixel = c.has("numerics.cells_per_pixel_levels") ? c.reals("numerics.cells_per_pixel_levels")
                                                                      : std::vector<double>{c.real("numerics.cells_per_pixel")};
    ladder.levels.clear();
    for (std::size_t i = 0; i < ladder.cells_per_pixel.size(); ++i) ladder.levels.push_back(static_cast<int>(i));
  }
  const char* single_key = array ? "numerics.cells_per_side" : "numerics.cells_around";
  if (ladder.levels.empty()) ladder.levels.push_back(static_cast<int>(c.integer(single_key)));
  if (image) return ladder;
  const std::string level_key = c.has("numerics.levels") || options.levels ? "numerics.levels" : single_key;
  for (int l : ladder.levels) {
    if (array && (l < 8 || l > 4096))
      throw InputError(c.where(level_key), "a resolution level (cells along the unit-cell side) must be from 8 to 4096", std::to_string(l), "8 ... 4096");
    if (!array && (l < 8 || l > 4096 || l % 4 != 0))
      throw InputError(c.where(level_key), "a resolution level must be a multiple of 4 from 8 to 4096", std::to_string(l), "8, 12, 16, ... 4096");
  }
  return ladder;
}

/// Stage 2, an image's mesher: mmval's direct mesher unless options.snappy_image_mesh, for the
/// smooth boundary always (wall vertices moved onto the level, no refinement band) and for the
/// pixel staircase when every level puts a whole number of cells on a pixel edge (then meshed
/// exactly); otherwise snappyHexMesh snaps to the boundary's STL.
void chooseImageMesher(Scene& scene, const Ladder& ladder, const PeerRunOptions& options) {
  if (scene.kind != Scene::Kind::image || options.snappy_image_mesh) return;
  const std::vector<double>& cpp = ladder.cells_per_pixel;
  const bool whole = std::all_of(cpp.begin(), cpp.end(), [](double v) { return v >= 1 && std::abs(v - std::round(v)) < 1e-9; });
  if (scene.smooth_boundary) {
    scene.direct_mesh = true;
    scene.surface_level = 0;
  } else if (whole) {
    scene.direct_mesh = true;
  }
}

/// What a ladder row's `value` and `error` are: the kind's primary metric (primaryMetric) and the
/// reference it is judged against, if the case has one. An unsteady cylinder's error is against
/// the first single-value reference (2D-2 lists the 1996 interval first); the steady kinds keep
/// the first entry's, as mmval's own ladders do.
struct RowValue {
  std::string metric;
  const Acceptance* reference = nullptr;
};

RowValue rowValue(const Case& c, bool unsteady) {
  RowValue v;
  v.metric = primaryMetric(c, unsteady);
  v.reference = unsteady ? pointReference(c, v.metric) : c.acceptanceFor(v.metric);
  return v;
}

/// A level's case folder under the output folder: openfoam[-<model>][-level<i>], the model's name
/// when the case solves two depth models, the level's when the ladder has more than one.
std::string levelFolder(const std::string& model, bool several_models, std::size_t level, bool several_levels) {
  const std::string prefix = several_models ? "openfoam-" + model : "openfoam";
  return several_levels ? fmt::format("{}-level{}", prefix, level) : prefix;
}

/// Runs one level (options.runner, else openfoam::runCase) into ctx.out_dir / sub; a run that
/// failed (Result::ok false) stops the whole run naming the case folder kept.
Result solveLevel(const Case& c, const RunContext& ctx, const PeerRunOptions& options, const Scene& scene, const std::string& sub) {
  Result r = options.runner ? options.runner(scene, ctx.out_dir / sub, options.ranks) : runCase(scene, ctx.out_dir / sub, options.ranks);
  if (!r.ok) throw std::runtime_error(fmt::format("OpenFOAM run of '{}' failed (case kept in {}): {}", c.name(), (ctx.out_dir / sub).string(), r.failure));
  return r;
}

/// Stage 3, a level's ladder row from its result: cells, ranks, times, iterations, folder; an
/// array's two resolutions, an unsteady cylinder's periodic statistics, an image's mesh
/// (addImageMeshRow) and depth model; `value` and `error` (against value.reference) of a
/// converged level, "not converged" and the residuals (and a warning) of one that is not.
nlohmann::json levelRow(const Scene& scene, const Result& r, const Ladder& ladder, std::size_t i, const std::string& model, const std::string& sub,
                        const RowValue& value, Warnings& warnings) {
  const int level = ladder.levels[i];
  nlohmann::json row = {{"level", i}, {"cells_around", level}, {"cells", r.cells}, {"ranks", r.ranks},
                        {"mesh_seconds", r.mesh_seconds}, {"solve_seconds", r.solve_seconds},
                        {"wall_seconds", r.mesh_seconds + r.solve_seconds}, {"iterations", r.iterations}, {"case_dir", sub}};
  // The solver's own CPU seconds (its ExecutionTime; meshing is not in it): on a shared machine
  // the wall time depends on the load, the CPU time much less.
  if (r.cpu_seconds) row["cpu_seconds"] = *r.cpu_seconds;
  if (r.flux_change) row["flux_change"] = *r.flux_change;
  if (scene.kind == Scene::Kind::periodic_array) {
    // Both numbers of one resolution: mmval's cells along the side and the O-grid's around the
    // cylinder, with the spacings they give (h = L / n; pi D / cells_around at the surface).
    row["cells_per_side"] = level;
    row["cells_around"] = scene.cells_around;
    row["spacing_m"] = scene.cell / level;
    row["surface_spacing_m"] = 2 * M_PI * scene.radius / scene.cells_around;
  }
  if (scene.unsteady) {
    // Each level's periodic statistics (the primary c_D is the last instant's): the ladder of an
    // unsteady case compares levels on these.
    row["shedding_periods"] = r.shedding_periods;
    for (const auto& [name, v] : {std::pair{"c_D_mean", r.c_d_mean}, {"c_D_max", r.c_d_max}, {"c_L_max", r.c_l_max}, {"St", r.strouhal}})
      if (v) row[name] = *v;
  }
  if (scene.kind == Scene::Kind::image) {
    row.erase("cells_around");
    row["cells_per_pixel"] = ladder.cells_per_pixel[i];
    row["depth_model"] = model;  // as mmval's image rows
    addImageMeshRow(scene, r, sub, row, warnings);
  }
  if (!r.converged) {
    // The last iterate of a SIMPLE loop that ran out of iterations is no solution: no value, no
    // error, so the row stays out of the observed order and of the speed-against-error plot.
    row["status"] = "not converged";
    row["residuals"] = r.residuals;
    warnings.add(notConvergedText(scene, r, sub));
    return row;
  }
  RunOutput level_out;
  addMetrics(scene, r, level_out);
  const auto it = level_out.metrics.find(value.metric);
  if (it == level_out.metrics.end()) return row;
  row["value"] = it->second;
  const Acceptance* ref = value.reference;
  if (ref != nullptr && !ref->reference.isInterval() && ref->reference.value != 0) row["error"] = (it->second - ref->reference.value) / ref->reference.value;
  return row;
}

/// One depth model's ladder as solved: its rows and the finest level's result and case folder.
struct ModelLadder {
  nlohmann::json rows = nlohmann::json::array();
  Result finest;
  std::string finest_folder;
};

/// Stage 4, one depth model's ladder: every level solved in turn (scene.cells_per_pixel or
/// scene.cells_around set per level; scene.hele_shaw_depth is the model's), its row made, and
/// then the ladder's grid convergence: an image's details.grid_convergence.<model> and
/// permeability_<model>_* metrics (addImageConvergence), else each row's observed order on the
/// O-grid's refinement (addObservedOrder).
ModelLadder runModelLadder(const Case& c, const RunContext& ctx, const PeerRunOptions& options, Scene& scene, const Ladder& ladder,
                           const std::string& model, bool several_models, const RowValue& value, Progress& progress, RunOutput& out,
                           Warnings& warnings) {
  const bool image = scene.kind == Scene::Kind::image;
  const bool array = scene.kind == Scene::Kind::periodic_array;
  ModelLadder result;
  std::vector<int> cells_around;  // the O-grid's refinement, for the observed order
  for (std::size_t i = 0; i < ladder.levels.size(); ++i) {
    if (image) scene.cells_per_pixel = ladder.cells_per_pixel[i];
    else scene.cells_around = array ? arrayCellsAround(scene, ladder.levels[i]) : ladder.levels[i];
    cells_around.push_back(scene.cells_around);
    result.finest_folder = levelFolder(model, several_models, i, ladder.levels.size() > 1);
    result.finest = solveLevel(c, ctx, options, scene, result.finest_folder);
    result.rows.push_back(levelRow(scene, result.finest, ladder, i, model, result.finest_folder, value, warnings));
    progress.advance();
  }
  if (image) addImageConvergence(scene, model, ladder.cells_per_pixel, result.rows, out, warnings);
  else addObservedOrder(result.rows, cells_around);
  return result;
}

/// How an image case's grain boundary was meshed, for details.boundary.
std::string imageBoundaryText(const Scene& s) {
  if (s.direct_mesh && !s.smooth_boundary)
    return "pixels (mmval's direct mesher: Cartesian cells, a whole number per pixel edge, the mask's staircase exactly, as mmval's solver sees it)";
  if (s.direct_mesh)
    return fmt::format("smooth (1/2 level of the mask smoothed by a Gaussian of {:g} px, as mmval's; mmval's direct mesher: "
                       "Cartesian cells at cells_per_pixel, wall vertices moved onto the level)", s.smoothing_px);
  if (s.smooth_boundary)
    return fmt::format("smooth (1/2 level of the mask smoothed by a Gaussian of {:g} px, as mmval's; snapped, surface level {} "
                       "with {} cells per band)", s.smoothing_px, s.surface_level, s.cells_between_levels);
  return "pixels (outlines of the mask's grain pixels)";
}

/// Stage 5, a run that did not converge (the finest level of some depth model): reported as "not
/// converged", never as a value: every metric is null but the porosities (the geometry's and the
/// mesh's, not the flow's; acceptance entries on the others fail: nothing was measured); the
/// status and the last level's residuals and iterations are in details.
void markNotConverged(const Result& finest, RunOutput& out) {
  out.details["status"] = "not converged";
  out.details["residuals"] = finest.residuals;
  out.details["iterations"] = finest.iterations;
  for (auto& [name, value] : out.metrics)
    if (name.rfind("porosity", 0) != 0) value = std::nan("");
}

}  // namespace

std::string notConvergedText(const Scene& s, const Result& r, const std::string& case_dir) {
  return fmt::format("simpleFoam did not converge in {} ({} iterations, the cap numerics.max_iterations = {}): initial residuals {}, "
                     "target numerics.residual = {:g}; its last iterate is not reported as a value (raise numerics.max_iterations)",
                     case_dir, r.iterations, s.max_iterations, residualText(r.residuals), s.residual);
}

Scene peerScene(const simulate::CylinderScene& cyl) {
  Scene s;
  s.kind = Scene::Kind::cylinder_channel;
  s.length = cyl.length_m;
  s.height = cyl.height_m;
  s.cx = cyl.centre_x_m;
  s.cy = cyl.centre_y_m;
  s.diameter = cyl.diameter_m;
  s.depth = cyl.depth_m;
  s.rho = cyl.density_kg_m3;
  s.nu = cyl.kinematicViscosity();
  s.inflow_max = cyl.inflow_max_m_s;
  s.uniform_inflow = cyl.uniform_inflow;
  s.slip_walls = cyl.slip_walls;
  s.u_ref = cyl.u_ref_m_s;
  s.l_ref = cyl.l_ref_m;
  s.pressure_probes = cyl.pressure_probes;
  return s;
}

Scene peerScene(const simulate::PeriodicArrayScene& arr, int cells_per_side) {
  Scene s;
  s.kind = Scene::Kind::periodic_array;
  s.cell = arr.cell_m;
  s.radius = arr.radius();
  s.depth = s.cell / 10;
  s.rho = arr.density_kg_m3;
  s.nu = arr.kinematicViscosity();
  s.mean_velocity = arr.mean_velocity_m_s;
  s.cells_around = arrayCellsAround(s, cells_per_side);
  return s;
}

int arrayCellsAround(const Scene& s, int cells_per_side) { return cellsAroundForSpacing(2 * s.radius, s.cell / cells_per_side); }

Scene peerScene(const Case& c) {
  if (c.kind() == "cylinder-channel") return cylinderScene(c);
  if (c.kind() == "periodic-array") return arrayScene(c);
  if (c.kind() == "image-permeability") return imageScene(c);
  throw InputError(c.where("case.kind"), "the OpenFOAM peer does not run this kind", c.kind(), "cylinder-channel, periodic-array or image-permeability");
}

RunOutput runPeer(const Case& c, const RunContext& ctx, const PeerRunOptions& options) {
  const Installation inst = options.runner ? Installation{true, "(test runner)", {}, {}} : detect();
  if (!inst.available) throw InputError({c.file().string(), 0, 0, "case.kind"}, "cannot run this case: " + inst.reason, {}, "OpenFOAM v1912 installed");
  Scene scene = peerScene(c);
  const Ladder ladder = readLadder(c, options);
  chooseImageMesher(scene, ladder, options);
  const bool image = scene.kind == Scene::Kind::image;
  // An image case solves each of its depth models (2d, depth-averaged) on the whole ladder, as
  // mmval's own image kind does; the other kinds have one model.
  const std::vector<DepthModel> models = image ? imageDepthModels(c) : std::vector<DepthModel>{{"", 0.0}};
  const RowValue value = rowValue(c, scene.unsteady);

  RunOutput out;
  out.details["solver"] = "openfoam " + inst.version;
  // On the diameter, as simulate::CylinderScene::reynolds (mmval's details.Re), whatever l_ref is.
  if (scene.kind == Scene::Kind::cylinder_channel) out.details["Re"] = scene.u_ref * scene.diameter / scene.nu;
  out.details["ranks"] = options.ranks;
  Warnings warnings{c.name(), ctx.quiet};
  Progress progress("openfoam " + c.name(), ladder.levels.size() * models.size(), ctx.quiet);
  nlohmann::json runs = nlohmann::json::array();  // every model's rows
  ModelLadder last;                               // the last model's ladder
  bool all_converged = true;
  std::map<std::string, double> k_of;  // each depth model's finest permeability (m2)
  for (const DepthModel& model : models) {
    scene.hele_shaw_depth = model.depth_m;
    last = runModelLadder(c, ctx, options, scene, ladder, model.name, models.size() > 1, value, progress, out, warnings);
    for (const auto& row : last.rows) runs.push_back(row);
    all_converged = all_converged && last.finest.converged;
    addMetrics(scene, last.finest, out);  // the last model's `permeability` stays: depth-averaged when run, as mmval's
    if (last.finest.permeability) k_of[model.name] = *last.finest.permeability;
  }
  progress.finish();

  out.details["ladder"] = last.rows;  // the last depth model's, as mmval's; `runs` holds every model's
  out.details["cells"] = last.finest.cells;
  if (image) {
    out.details["runs"] = runs;
    out.details["boundary"] = imageBoundaryText(scene);
    out.details["mesh_seconds"] = last.finest.mesh_seconds;
    // Not a metric: the image kind's schema (mmval's) declares no such metric; the finest level's value.
    out.details["porosity_boundary"] = last.finest.porosity_boundary;
    if (k_of.count("2d") && k_of.count("depth-averaged") && all_converged) out.metrics["depth_model_ratio"] = k_of["depth-averaged"] / k_of["2d"];
  }
  if (!warnings.list.empty()) out.details["warnings"] = warnings.list;
  if (!all_converged) markNotConverged(last.finest, out);
  out.files.push_back(last.finest_folder);
  return out;
}

}  // namespace mmval::openfoam
