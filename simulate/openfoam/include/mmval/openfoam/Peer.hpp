// The OpenFOAM peer: writes a complete, self-contained OpenFOAM v1912 case
// (system/, constant/, 0/) for a scene, runs blockMesh and simpleFoam or
// pimpleFoam (serially or decomposed over N ranks), and reads back forces,
// pressure probes and fluxes. The generated case stays on disk so a user can
// rerun or change it by hand.
//
// Environment facts this relies on (Debian's OpenFOAM v1912 packages): WM_PROJECT_DIR
// must point at /usr/share/openfoam; mpirun needs --allow-run-as-root as
// root; scotch/metis are stubs, so decomposition is "simple"; nothing
// compiled at run time works, so inlet profiles use exprFixedValue.
//
// Image geometries are solved in plane 2D or with mmval's depth-averaged
// (Brinkman-Hele-Shaw) model: the friction -12 nu u / h^2 of a parabolic profile
// across the chip depth h (docs/validation/depth-model.md) as an
// explicitPorositySource (Darcy, d = 12 / h^2 in x and y) on a cellZone of every
// cell, which topoSet makes after meshing. The porosity model puts the friction on
// the momentum matrix's diagonal (twice it, with the surplus taken back
// explicitly), so SIMPLEC converges as in plane flow. An earlier
// vectorSemiImplicitSource did not converge (it diverged with SIMPLEC on snapped
// meshes, stalled with relaxed SIMPLE). docs/validation/peer-smooth.md has the
// measurements.
#pragma once
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "mmval/openfoam/BlockMesh.hpp"

namespace mmval::openfoam {

struct Installation {
  bool available = false;
  std::string version;  ///< e.g. "v1912"
  std::string reason;   ///< why not available
  std::filesystem::path project_dir;
};

/// Looks for the OpenFOAM binaries and etc/ folder.
Installation detect();

/// The version of the OpenFOAM in `project_dir`: $WM_PROJECT_VERSION, else its
/// etc/bashrc's `export WM_PROJECT_VERSION=...`, else "unknown".
std::string installedVersion(const std::filesystem::path& project_dir);

/// One scene, in SI units, as the peer needs it.
struct Scene {
  enum class Kind { channel, cylinder_channel, periodic_array, image } kind = Kind::cylinder_channel;
  double rho = 1.0, nu = 1e-3;
  // channel and cylinder channel
  double length = 2.2, height = 0.41, depth = 0.1;
  double inflow_max = 0.3;          ///< peak of the parabolic inflow (cylinder channel), or the uniform inflow
  bool uniform_inflow = false;      ///< uniform instead of parabolic inflow
  bool slip_walls = false;          ///< slip (free-stream) instead of no-slip channel walls
  double pressure_drop = 0.0;       ///< inlet - outlet, kinematic (channel)
  /// Depth-averaged (Brinkman-Hele-Shaw) model: the chip depth h (m) whose friction -12 nu u / h^2
  /// every cell gets (channel and image scenes; the velocity is then the depth-averaged one).
  /// 0: plane 2D, no friction. Not the mesh thickness (`depth` above, or one cell for images).
  double hele_shaw_depth = 0.0;
  double cx = 0.2, cy = 0.2, diameter = 0.1;
  double u_ref = 0.2, l_ref = 0.1;  ///< for force coefficients: c = 2F / (rho u_ref^2 l_ref depth)
  std::vector<std::array<double, 2>> pressure_probes;  ///< dp = p(first) - p(second)
  // periodic array
  double cell = 1.0, radius = 0.25;
  double mean_velocity = 1e-3;      ///< interstitial mean velocity the source enforces
  // image geometry (pressure-driven left to right, slip sides, the paper's set-up)
  std::filesystem::path mask;
  double pixel = 1e-6;              ///< m per pixel
  bool grain_dark = true;
  double cells_per_pixel = 0.5;     ///< mesh resolution at the grain surface (the background is coarser by 2^surface_level)
  /// geometry.boundary = "smooth": the STL is the 1/2 level of the mask smoothed by a Gaussian of
  /// smoothing_px pixels (smoothGrainPolygons), mmval's smooth boundary; else the pixel outlines.
  bool smooth_boundary = false;
  double smoothing_px = 0.75;
  /// snappyHexMesh refinement level on the grain surface (level (n n)): cells there are 2^n times
  /// finer than the background; nCellsBetweenLevels sets the width of each refinement band.
  int surface_level = 0;
  int cells_between_levels = 3;
  /// Image scenes: mmval meshes the image itself and writes constant/polyMesh; no blockMesh or
  /// snappyHexMesh runs. On the smooth boundary directImageMesh (a Cartesian grid at
  /// cells_per_pixel, wall vertices moved onto the level); on the pixels, at a whole number of
  /// cells per pixel, pixelImageMesh (the staircase exactly). The mesh is one cell (dx) thick.
  bool direct_mesh = false;
  // numerics
  /// Resolution: cells around the cylinder (cylinder channel and periodic array; a periodic-array
  /// case sets it from numerics.cells_per_side, arrayCellsAround), cells across (channel).
  int cells_around = 64;
  bool unsteady = false;
  double end_time = 0, dt = 0;      ///< unsteady
  /// Unsteady: start of the statistics window (s); the metrics come from the last whole c_L periods
  /// (up to 4) after it, as mmval's own (simulate::ForceHistory::analyse). Negative: half the end time.
  double statistics_from = -1;
  /// Unsteady: strength eps of the Gaussian vortex 1.5 D behind the cylinder in the initial
  /// velocity, mmval's numerics.initial_perturbation and the same field (peak speed eps u_ref / 2);
  /// set by setExprFields after blockMesh. 0: none, the flow starts from rest.
  double initial_perturbation = 0;
  int max_iterations = 2000;        ///< steady
  double residual = 1e-7;           ///< steady convergence target (p and U)
};

struct StepTiming {
  std::string command;
  double wall_seconds = 0;
  int exit_code = 0;
};

/// What mmval's own image mesher did for a level (Scene::direct_mesh), for result.json's ladder.
struct MesherReport {
  bool direct = false;
  double seconds = 0;             ///< meshing and writing constant/polyMesh
  int wall_vertices = 0, snapped = 0, pulled_back = 0, pinned = 0;  ///< DirectMesh2D's counts
  int dropped_disconnected = 0;
  double max_move_cells = 0, min_cell_area_ratio = 0;
};

struct Result {
  bool ok = false;
  std::string failure;               ///< OpenFOAM's own message when a step failed
  long long cells = 0;
  int ranks = 1;
  double mesh_seconds = 0, solve_seconds = 0;
  /// The solver's own CPU time: the last "ExecutionTime" of its log (rank 0's in a parallel run);
  /// absent when the log has none. solve_seconds is the wall time of the same step.
  std::optional<double> cpu_seconds;
  std::vector<StepTiming> steps;
  int iterations = 0;
  /// Steady: simpleFoam met its residualControl (numerics.residual) before its iteration cap
  /// (numerics.max_iterations). When false the outputs below are those of the last iteration, not a
  /// solution: they must not be reported as values (runPeer reports "not converged" instead).
  /// Always true for unsteady runs.
  bool converged = true;
  std::map<std::string, double> residuals;  ///< steady: initial residual of each field (Ux, Uy, p) in the last iteration
  /// Steady channel and image scenes: how far the outlet flux still is from its limit, relative
  /// (fluxChange of its history): that the measured quantity itself has settled, beside the
  /// residuals. Absent without a flux history.
  std::optional<double> flux_change;
  // outputs (SI, kinematic pressures multiplied by rho)
  double porosity_total = 0, porosity_connected = 0, porosity_mesh = 0;
  /// Image: the pore fraction of the boundary the STL describes (the smooth field's fluid side, or
  /// the connected-pore mask for the pixel outlines), against which porosity_mesh (total cell
  /// volume / (image area x mesh thickness), checkMesh's "Total volume") is judged.
  double porosity_boundary = 0;
  double snappy_seconds = 0;  ///< image: snappyHexMesh's own wall time (within mesh_seconds)
  MesherReport mesher;        ///< image on the direct mesher (its seconds are within mesh_seconds)
  /// checkMesh's "Mesh non-orthogonality Max" (degrees) and "Max skewness"; NaN when not reported.
  double max_non_orthogonality = 0, max_skewness = 0;
  int shedding_periods = 0;         ///< unsteady: whole c_L periods the statistics span (0: no shedding found)
  std::optional<double> c_d_mean;  ///< unsteady: time mean over the last whole c_L periods after Scene::statistics_from
  std::optional<double> c_d, c_l, c_d_max, c_l_max, strouhal, dp, flow_rate, permeability, drag_per_length, f_star;
};

/// The background (blockMesh) grid of an image scene: cells along x and y, and its cell size,
/// which is also the thickness of the one-cell-deep 2D mesh (m).
struct ImageBackground {
  int nx = 4, ny = 4;
  double cell = 0;
};
ImageBackground imageBackground(const Scene& s, int image_cols, int image_rows, double image_width);

/// The thickness (m) of an image scene's one-cell-deep mesh: the direct mesher's cell size along x
/// (image width / round(cols x cells_per_pixel), at least 4 cells), else imageBackground's cell.
double imageMeshThickness(const Scene& s, int image_cols, int image_rows, double image_width);

/// Writes the case into `dir` (which is created); returns the cell count. An image scene with
/// direct_mesh gets its constant/polyMesh here, and `mesher` (if given) what the mesher did.
long long writeCase(const Scene& scene, const std::filesystem::path& dir, int ranks = 1, MesherReport* mesher = nullptr);

/// Runs blockMesh (+ decomposePar) and the solver in `dir`, then reads the results; an image scene
/// with direct_mesh is meshed by writeCase instead, and that time counts as meshing.
Result runCase(const Scene& scene, const std::filesystem::path& dir, int ranks = 1);

/// Runs a case already written into `dir` (possibly edited by hand).
Result runWrittenCase(const Scene& scene, const std::filesystem::path& dir, int ranks = 1);

/// Reads the last line of a forceCoeffs coefficient.dat (Time Cd Cs Cl ...), or
/// the whole history when `history` is given.
struct Coefficients {
  double time = 0, cd = 0, cl = 0;
};
std::vector<Coefficients> readCoefficients(const std::filesystem::path& file);

/// An unsteady cylinder's c_D max / mean, c_L max and St from its force history, as mmval's own
/// unsteady kind computes them: over the last (up to 4) whole c_L periods after
/// scene.statistics_from (half the end time when negative), St = f D / u_ref; no St without a
/// whole period (Result::shedding_periods 0).
void addSheddingStatistics(const Scene& scene, const std::vector<Coefficients>& history, Result& r);

/// The last "ExecutionTime = X s" of an OpenFOAM solver's log: the CPU seconds the solver had used
/// by its last time step or iteration; nothing when the log has no such line.
std::optional<double> executionTime(const std::string& solver_log);

/// How a steady SIMPLE solve ended, read from simpleFoam's log: converged when the log says
/// "SIMPLE solution converged" (residualControl met) or every field's initial residual in the last
/// iteration is at or below `target` (met on the very last iteration, where simpleFoam stops without
/// saying so); `residuals` holds those initial residuals (the first solve of each field in the
/// iteration, which is what residualControl compares), `iterations` the iterations run.
struct SimpleConvergence {
  bool converged = false;
  int iterations = 0;
  std::map<std::string, double> residuals;
};
SimpleConvergence simpleConvergence(const std::string& log, double target);

/// The iterations over which fluxChange falls back to the plain change.
constexpr int kFluxChangeIterations = 20;

/// The change still to come in the last value Q_n of an iterated quantity's `history`, relative
/// to it: SIMPLE converges geometrically, so with the last change d_n = Q_n - Q_(n-1) and the ratio
/// r = |d_n / d_(n-1)| < 1 of the last two, the rest of the series is |d_n| r / (1 - r). When the
/// changes do not shrink (r >= 1, or only two entries), the change over the last
/// kFluxChangeIterations entries (all of them when fewer) instead, |Q_n - Q_(n-k)|. Nothing for
/// fewer than two entries or Q_n = 0.
std::optional<double> fluxChange(const std::vector<double>& history);

/// "Ux 0.91, Uy 0.88, p 0.93": residuals for messages.
std::string residualText(const std::map<std::string, double>& residuals);

/// The first "FOAM FATAL ERROR" block of a log, or its last lines.
std::string fatalMessage(const std::string& log);

}  // namespace mmval::openfoam
