// A micromodel generator from statistics (docs/chip-generator.md): a
// sand-pack-like chip mask for a target porosity, depth-averaged permeability at a given depth,
// grain-size distribution (and optionally mean throat size), over a given size and pixel size.
//
// Stages: validate -> tune the grain scale on a tile (secant on ln k against ln d, mmval's own
// depth-averaged solve at cells_per_pixel) -> generate the full chip and confirm k there (up to
// kMaxChipCorrections corrections of d) -> with fit_depth, the depth for the k target (secant on
// ln k against ln h on the tile at the final scale, confirmed on the chip when the ladder solves it)
// -> statistics and a grid-convergence ladder on the full chip. Porosity is met by construction (ChipPacking.hpp). Same spec and seed: the same mask,
// byte for byte.
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/simulate/ChipFlow.hpp"
#include "mmval/simulate/ChipPacking.hpp"

namespace mmval::simulate {

/// User-facing targets, in the units of the command's options (names carry them).
struct ChipSpec {
  double length_mm = 4, width_mm = 2;  ///< along the flow (x) and across (y)
  double pixel_um = 5;
  double depth_um = 20;                ///< channel depth; with fit_depth, the fitted depth is written here in ChipResult::spec
  /// Solve for depth_um instead: the grain scale is set by mean_throat_um, then the depth that gives
  /// the depth-averaged permeability_D at cells_per_pixel is found (both targets required).
  bool fit_depth = false;
  double porosity = 0.58;
  double porosity_tolerance = 0.005;
  double permeability_D = 0;           ///< depth-averaged target; 0: none
  double permeability_tolerance = 0.05;  ///< relative
  double mean_throat_um = 0;           ///< mean throat width target (used without a k target, or with fit_depth); 0: none
  double mean_grain_um = 0;            ///< mean grain diameter: fixed without k / throat targets, else the start; 0: estimated
  double grain_cv = 0.3;               ///< coefficient of variation of the grain diameter
  double min_throat_px = 3;            ///< smallest gap between grains (and grain to wall)
  int wall_px = 2;                     ///< solid rows at top and bottom; 0: none, mirror sides (ChipPackingSpec::wall_px)
  double port_um = 0;                  ///< open inlet / outlet columns; 0: one mean grain diameter
  double tile_mm = 1.5;                ///< side of the tuning tile (capped at the chip)
  double cells_per_pixel = 1;          ///< resolution at which the k target is met
  std::vector<double> ladder{0.5, 1, 2};  ///< full-chip ladder, coarse to fine; must contain cells_per_pixel
  bool smooth_boundary = true;
  /// Where the k target is confirmed and the ladder solved: the full chip, or (when the full chip
  /// is too large to solve) the tuning tile at the final grain scale.
  bool solve_on_tile = false;
  /// The model whose k meets permeability_D: kChipModelDepthAveraged (the grain scale is tuned to
  /// the depth-averaged k at cells_per_pixel) or kChipModel3D (the same k times the measured ratio
  /// of coarse 3D Stokes to depth-averaged k: ChipModel3DStep).
  std::string permeability_model = "depth-averaged";
  double cells_per_pixel_3d = 1;       ///< 3D model: in-plane cells per pixel (the mask block-averaged, as image-permeability)
  std::vector<int> cells_z{4, 8};      ///< 3D model: cells across the depth, coarse to fine (Richardson in dz over the last two)
  std::uint64_t seed = 1;
};

inline constexpr const char* kChipModelDepthAveraged = "depth-averaged";
inline constexpr const char* kChipModel3D = "3d";
/// 3D model: at most this many re-tunings of the depth-averaged target after the first 3D measurement.
inline constexpr int kMaxChip3DRetunes = 2;

/// Throws InputError naming the option (--porosity, --permeability-D, ...) and its limit:
/// porosity outside (kMinPorosity, kMaxPorosity), k not below the open Hele-Shaw limit
/// porosity x h^2 / 12 (with fit_depth: at kFitDepthMaxUm), fit_depth without both a k and a
/// mean-throat target, sizes that are not positive or too large, a ladder without
/// cells_per_pixel, a ladder whose finest level would not fit in memory (direct solver, 8.8 kB per
/// cell measured: simulate/src/MemoryBudget.hpp) on the chip (or tile) it is solved on.
void validateChipSpec(const ChipSpec& s);
inline constexpr double kMinPorosity = 0.2, kMaxPorosity = 0.95;
/// Relative tolerance of a mean-throat target (a statistic of the geometry: no solver error to allow for).
inline constexpr double kChipThroatTolerance = 0.02;
/// At most this many corrections of the grain scale on the full chip after tuning on the tile.
inline constexpr int kMaxChipCorrections = 2;
/// Depths (um) the depth fit searches. k grows with h towards the plane-2D k (no wall friction),
/// which bounds it at every depth; a target above k(200 um) is refused as unreachable.
inline constexpr double kFitDepthMinUm = 1, kFitDepthMaxUm = 200;

/// One permeability solve of the depth fit.
struct ChipDepthStep {
  std::string where;   ///< "tile" or "chip"
  double depth_um = 0;
  double k_D = 0;      ///< depth-averaged k at cells_per_pixel, darcy
  double seconds = 0;
};

/// One evaluation of the tuning loop.
struct ChipTuneStep {
  std::string where;   ///< "tile" or "chip"
  double mean_grain_um = 0;
  double value = 0;    ///< k in darcy (or mean throat in um)
  double seconds = 0;
  double target = 0;   ///< what the step aimed at (with the 3D model, the re-tuned depth-averaged k)
};

/// A tile-sized window of the chip solved at the ladder's coarsest level (solve-on tile only):
/// how well the tuned tile stands for the chip it was tuned for.
struct ChipTileSample {
  int col = 0, row = 0;    ///< top-left pixel of the window in the chip
  double porosity = 0;     ///< pore pixels / all pixels of the window
  double k_D = 0;          ///< depth-averaged k, darcy (NaN with `error`)
  std::string error;       ///< why the window gave no k (no spanning path), empty otherwise
};

/// One measurement of the 3D model (permeability_model "3d") on the solved region (chip or tile):
/// the ratio r = k_3d / k_da,pixels of coarse 3D Stokes (Richardson in dz) to the depth-averaged
/// model on the same pixel staircase and in-plane grid (cells_per_pixel_3d), which is the depth
/// model's error without the in-plane grid error (0.930 / 0.931 at 1 / 2 cells per pixel on the
/// paper's chip statistics, docs/validation/depth-model.md), applied to the depth-averaged k at
/// cells_per_pixel: k_3d = r k_da.
struct ChipModel3DStep {
  std::string where;               ///< "chip" or "tile"
  double mean_grain_um = 0;
  double da_target_D = 0;          ///< the depth-averaged target the grain scale was tuned to before this step
  double k_da_D = 0;               ///< depth-averaged k at cells_per_pixel (the generator's boundary)
  double k_da_pixels_D = 0;        ///< depth-averaged k on the pixel staircase at cells_per_pixel_3d
  ChipFlow3DResult run_3d;         ///< coarse 3D Stokes at cells_per_pixel_3d, per cells_z level and extrapolated
  double ratio = 0;                ///< run_3d.extrapolated / k_da_pixels
  double k_3d_D = 0;               ///< ratio x k_da_D: the k that meets the target
  double seconds = 0;
};

/// Windows sampled at these fractions of the free range along x and y (four, one per quadrant).
inline constexpr double kTileSampleFractions[] = {0.25, 0.75};

struct ChipResult {
  ChipSpec spec;
  ChipPacking packing;             ///< the full chip
  double mean_grain_um = 0;        ///< scale used
  std::vector<ChipTuneStep> tuning;
  std::vector<ChipDepthStep> depth_fit;  ///< fit_depth: every (h, k) solve, in order
  double k_plane_2d_tile_D = 0;    ///< fit_depth: the tile's plane-2D k at cells_per_pixel (the bound of k at any depth)
  ChipLadder ladder_2d, ladder_da; ///< ladders on the chip (or the tile: spec.solve_on_tile)
  int solved_cols = 0, solved_rows = 0;  ///< size of what the ladder solved, px
  double k_target_level_D = 0;     ///< depth-averaged k at spec.cells_per_pixel (what the target is met at with the depth-averaged model)
  std::vector<ChipModel3DStep> model_3d;  ///< permeability_model "3d": every 3D measurement, in order (the last is the chip's)
  double da_target_D = 0;          ///< the depth-averaged k the grain scale was finally tuned to (permeability_D with the depth-averaged model)
  std::vector<ChipTileSample> tile_samples;  ///< solve-on tile: windows of the chip at the ladder's coarsest level
  nlohmann::json stats;            ///< chip.json (see docs/chip-generator.md)
  double seconds = 0;
  nlohmann::json stage_seconds = nlohmann::json::object();  ///< wall time per stage (tune, pack, confirm, ladder, statistics)
};

/// Runs every stage; `log` receives progress lines (may be empty). Throws InputError for targets
/// the generator cannot reach (naming the option), NumericalFailure when the solver fails.
ChipResult generateChip(const ChipSpec& s, const std::function<void(const std::string&)>& log = {});

/// The chip.json document of a result (also in result.stats).
nlohmann::json chipStatistics(const ChipResult& r);

/// Writes chip.png (grains 0, pores 255), chip.json, chip-picture.png, grain-sizes.csv and
/// throat-sizes.csv into `dir` (which exists).
void writeChipOutputs(const ChipResult& r, const std::filesystem::path& dir);

}  // namespace mmval::simulate
