// Micromodel generator: validation, grain-scale tuning and the full chip (see ChipGenerator.hpp).
#include "mmval/simulate/ChipGenerator.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/Resources.hpp"

#include "MemoryBudget.hpp"

namespace mmval::simulate {

namespace {

/// Evaluations of the tile in the secant search.
constexpr int kMaxTuneSteps = 10;
/// A secant step changes the grain scale by at most this factor (k ~ d^2 at most: 4x in k).
constexpr double kMaxStepFactor = 2.0;
/// d ln k / d ln d before two evaluations exist (between the Hele-Shaw-limited 0 and the plane 2D 2).
constexpr double kStartSlope = 1.5;
/// Grains smaller than this (px) are too coarsely rendered to be sand-like.
constexpr double kMinGrainPx = 6;
/// Kept below the packer's kMaxInflatedFraction: polydisperse discs inflate more than their mean.
constexpr double kInflationMargin = 0.05;
/// Pixel budget of a chip mask (the mask, its pore analysis and picture: ~10 B/px; the solve is
/// the larger cost and is bounded by the ladder the user asks for).
constexpr double kMaxChipPixels = 2.0e8;

InputLocation opt(const char* name) { return InputLocation{"", 0, 0, name}; }

double seconds(std::chrono::steady_clock::time_point t0) { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); }

/// Open Hele-Shaw limit of the depth-averaged permeability: porosity x h^2 / 12, darcy (with
/// fit_depth at the deepest depth searched).
double hsLimitDarcy(const ChipSpec& s) {
  const double h_um = s.fit_depth ? kFitDepthMaxUm : s.depth_um;
  return s.porosity * std::pow(h_um * 1e-6, 2) / 12 / kDarcyM2;
}

/// The grain scale is tuned on k (else on the mean throat, or not tuned). With fit_depth the
/// throat sets the grain scale and k sets the depth.
bool tunesK(const ChipSpec& s) { return s.permeability_D > 0 && !s.fit_depth; }

/// Porosity of a cols x rows pattern (the chip or a tile of it) whose grain region (between the
/// ports and the walls) is as dense as the chip's. The chip's porosity counts its solid walls and
/// grain-free ports; a tile has relatively more of both, so packed at the chip's porosity its
/// grain region would be denser than the chip's (a 0.5 mm tile of the paper's statistics at 2 um/px
/// with 29.2 um grains: porosity 0.535 against 0.572 in the grain region, and k 31 % below the
/// 2 x 1 mm chip's; docs/chip-generator.md). The chip itself: s.porosity.
double patternPorosity(const ChipSpec& s, int cols, int rows, double port_px) {
  const int chip_cols = static_cast<int>(std::lround(s.length_mm * 1e3 / s.pixel_um));
  const int chip_rows = static_cast<int>(std::lround(s.width_mm * 1e3 / s.pixel_um));
  if (cols == chip_cols && rows == chip_rows) return s.porosity;
  auto region = [&](int c, int r) { return (c - 2 * port_px) * (r - 2.0 * s.wall_px); };
  auto walls = [&](int c) { return 2.0 * s.wall_px * c; };
  const double grain_fraction = ((1 - s.porosity) * chip_cols * chip_rows - walls(chip_cols)) / region(chip_cols, chip_rows);
  return 1 - (walls(cols) + grain_fraction * region(cols, rows)) / (static_cast<double>(cols) * rows);
}

ChipPackingSpec packingSpec(const ChipSpec& s, int cols, int rows, double d_um, std::uint64_t seed) {
  ChipPackingSpec p;
  p.cols = cols;
  p.rows = rows;
  p.wall_px = s.wall_px;
  p.mean_diameter_px = d_um / s.pixel_um;
  p.port_px = (s.port_um > 0 ? s.port_um : d_um) / s.pixel_um;
  p.diameter_cv = s.grain_cv;
  p.min_gap_px = s.min_throat_px;
  p.porosity = patternPorosity(s, cols, rows, p.port_px);
  p.porosity_tolerance = s.porosity_tolerance;
  p.seed = seed;
  return p;
}

/// Packs, turning the packer's refusals into InputErrors that say which option to change.
ChipPacking pack(const ChipSpec& s, int cols, int rows, double d_um) {
  try {
    return packChip(packingSpec(s, cols, rows, d_um, s.seed));
  } catch (const std::invalid_argument& e) {
    throw InputError(opt("--porosity"), fmt::format("no pattern of mean grain {:.4g} um on {} x {} px: {}", d_um, cols, rows, e.what()),
                     fmt::format("{:g}", s.porosity), "a higher porosity, a smaller --min-throat-px, a larger chip or smaller grains");
  }
}

/// Mean throat width (um) of a packing.
double meanThroatUm(const ChipPacking& p, const ChipSpec& s, double d_um) {
  const auto t = chipThroats(p.discs, static_cast<int>(p.solid.rows()), s.wall_px, d_um / s.pixel_um);
  if (t.empty()) return 0;
  double sum = 0;
  for (const auto& x : t) sum += x.width_px;
  return sum / static_cast<double>(t.size()) * s.pixel_um;
}

ChipFlowSettings flowSettings(const ChipSpec& s) {
  ChipFlowSettings f;
  f.pixel_m = s.pixel_um * 1e-6;
  f.depth_m = s.depth_um * 1e-6;
  f.smooth_boundary = s.smooth_boundary;
  return f;
}

/// Depth-averaged k (darcy) of a packing at the target resolution.
double kDarcyOf(const ChipPacking& p, const ChipSpec& s) {
  const PoreSpaceReport pores = analysePoreSpace(p.solid);
  return chipPermeability(pores.solid_connected, flowSettings(s), s.cells_per_pixel).permeability_m2 / kDarcyM2;
}

/// Starting grain diameter (um) for a k target: the plane 2D part from Kozeny-Carman
/// (k = d^2 phi^3 / (180 (1 - phi)^2), Carman 1937) in series with the Hele-Shaw limit. Only a
/// start: the secant search corrects it.
double startDiameterUm(const ChipSpec& s) {
  if (s.mean_grain_um > 0) return s.mean_grain_um;
  const double phi = s.porosity;
  if (tunesK(s)) {
    const double k2d = 1.0 / (1.0 / s.permeability_D - 1.0 / hsLimitDarcy(s)) * kDarcyM2;
    return std::sqrt(k2d * 180 * (1 - phi) * (1 - phi) / (phi * phi * phi)) * 1e6;
  }
  if (s.mean_throat_um > 0) return 3 * s.mean_throat_um;
  return 12 * s.pixel_um;
}

/// The smallest mean grain diameter (um) whose discs, inflated by half the minimum gap, stay
/// below kMaxInflatedFraction - kInflationMargin of the pattern (solid fraction ~ 1 - porosity):
/// (1 + g / d)^2 (1 - phi) <= that.
double minDiameterUm(const ChipSpec& s) {
  const double room = std::sqrt((kMaxInflatedFraction - kInflationMargin) / (1 - s.porosity)) - 1;
  if (room <= 0)
    throw InputError(opt("--porosity"), "grains separated by a throat cannot be packed this densely", fmt::format("{:g}", s.porosity),
                     fmt::format("a porosity above {:.3f}", 1 - (kMaxInflatedFraction - kInflationMargin)));
  return std::max(kMinGrainPx, s.min_throat_px / room) * s.pixel_um;
}

struct Secant {
  double x0 = std::nan(""), f0 = std::nan("");
  /// Next ln d from (x1, f1) = (ln d, ln(value / target)); value grows with d.
  double next(double x1, double f1) {
    double slope = kStartSlope;
    if (std::isfinite(x0) && std::abs(x1 - x0) > 1e-9) slope = (f1 - f0) / (x1 - x0);
    if (!(slope > 0.2) || !std::isfinite(slope)) slope = kStartSlope;
    x0 = x1;
    f0 = f1;
    return x1 - std::clamp(f1 / slope, -std::log(kMaxStepFactor), std::log(kMaxStepFactor));
  }
};

/// The tile's grain scale for the k (or mean throat) target; returns the mean diameter in um.
double tuneOnTile(const ChipSpec& s, int cols, int rows, ChipResult& r, const std::function<void(const std::string&)>& log) {
  const bool by_k = tunesK(s);
  const double target = by_k ? s.permeability_D : s.mean_throat_um;
  const double d_min = minDiameterUm(s);
  // Just inside the packer's bound (ChipPacking.cpp: the largest grains fit between the walls), so rounding cannot refuse d_max itself.
  const double d_max = (1 - 1e-9) * (rows - 2 * s.wall_px - 2 * s.min_throat_px) / kMaxDiameterFactor * s.pixel_um;
  double x = std::log(std::clamp(startDiameterUm(s), d_min, d_max));
  Secant sec;
  double best_x = x, best_err = INFINITY;
  for (int step = 1; step <= kMaxTuneSteps; ++step) {
    const auto t0 = std::chrono::steady_clock::now();
    const double d = std::exp(x);
    const ChipPacking p = pack(s, cols, rows, d);
    const double v = by_k ? kDarcyOf(p, s) : meanThroatUm(p, s, d);
    r.tuning.push_back({"tile", d, v, seconds(t0), target});
    if (log) log(fmt::format("chip: tile {} x {} px, step {}: mean grain {:.4g} um -> {} {:.4g} {} (target {:.4g})", cols, rows, step, d,
                             by_k ? "k" : "mean throat", v, by_k ? "D" : "um", target));
    const double f = std::log(v / target);
    if (std::abs(f) < best_err) best_err = std::abs(f), best_x = x;
    // Half the tolerance on the tile, so the full chip has room for its own scatter.
    if (std::abs(v / target - 1) <= 0.5 * (by_k ? s.permeability_tolerance : kChipThroatTolerance)) return d;
    const double xn = sec.next(x, f);
    if (xn < std::log(d_min) - 1e-9 && x <= std::log(d_min) + 1e-9)
      throw InputError(opt(by_k ? "--permeability-D" : "--mean-throat-um"),
                       fmt::format("the target needs grains smaller than {:.3g} um ({:.3g} px), the smallest that keep --min-throat-px between "
                                   "grains at this porosity; the smallest gives {:.4g}", d_min, d_min / s.pixel_um, v),
                       fmt::format("{:g}", target), "a larger target, a smaller --pixel-size-um or a smaller --min-throat-px");
    if (xn > std::log(d_max) + 1e-9 && x >= std::log(d_max) - 1e-9)
      throw InputError(opt(by_k ? "--permeability-D" : "--mean-throat-um"),
                       fmt::format("the target needs grains larger than {:.4g} um, the largest that fit the tile (the largest gives {:.4g})", d_max, v),
                       fmt::format("{:g}", target),
                       by_k ? fmt::format("a smaller k (the open Hele-Shaw limit at this depth is {:.4g} D) or a larger --tile-mm", hsLimitDarcy(s))
                            : std::string("a smaller mean throat or a larger --tile-mm"));
    x = std::clamp(xn, std::log(d_min), std::log(d_max));
  }
  if (log) log(fmt::format("chip: the tile did not settle within {} steps; keeping the closest ({:.2f} % off)", kMaxTuneSteps, 100 * (std::exp(best_err) - 1)));
  return std::exp(best_x);
}

/// The 3D model's options, and its largest solve (finest cells_z on the solved region) against the
/// memory limit (kStokes3DBytesPerCell, measured: MemoryBudget.hpp, as image-permeability checks it).
void validateModel3D(const ChipSpec& s, double side_cols, double side_rows) {
  if (s.permeability_model != kChipModelDepthAveraged && s.permeability_model != kChipModel3D)
    throw InputError(opt("--permeability-model"), "unknown permeability model", s.permeability_model,
                     fmt::format("{} or {}", kChipModelDepthAveraged, kChipModel3D));
  if (s.permeability_model != kChipModel3D) return;
  if (!(s.permeability_D > 0) || s.fit_depth)
    throw InputError(opt("--permeability-model"), "the 3d model meets a k target at a given depth",
                     fmt::format("--permeability-model 3d with --permeability-D {:g}{}", s.permeability_D, s.fit_depth ? " and --depth-um fit" : ""),
                     "--permeability-D > 0 and a fixed --depth-um (the depth fit is depth-averaged only)");
  if (!(s.cells_per_pixel_3d >= 0.25 && s.cells_per_pixel_3d <= 4))
    throw InputError(opt("--cells-per-pixel-3d"), "value out of range", fmt::format("{:g}", s.cells_per_pixel_3d), "cells per pixel in [0.25, 4]");
  if (s.cells_z.empty()) throw InputError(opt("--cells-z-levels"), "the ladder is empty", "", "e.g. 4,8");
  for (std::size_t i = 0; i < s.cells_z.size(); ++i)
    if (s.cells_z[i] < 2 || s.cells_z[i] > 256 || (i > 0 && s.cells_z[i] <= s.cells_z[i - 1]))
      throw InputError(opt("--cells-z-levels"), "a cells_z level is out of range or out of order", fmt::format("{}", s.cells_z[i]),
                       "integers in [2, 256], growing (e.g. 4,8)");
  const double cells = side_cols * side_rows * s.cells_per_pixel_3d * s.cells_per_pixel_3d * s.cells_z.back();
  const double bytes = detail::kStartupBytes + detail::kStokes3DBytesPerCell * cells;
  if (bytes > defaultMaxMemoryBytes())
    throw InputError(opt("--cells-per-pixel-3d"),
                     fmt::format("the 3D solve on {:.3g} cells needs ~{:.1f} GB ({:.1f} kB per cell measured), {:.1f} GB available", cells, bytes / 1e9,
                                 detail::kStokes3DBytesPerCell / 1e3, defaultMaxMemoryBytes() / 1e9),
                     fmt::format("{:g}", s.cells_per_pixel_3d), "fewer 3D cells per pixel or across the depth (--cells-z-levels), or --solve-on tile");
}

}  // namespace

void validateChipSpec(const ChipSpec& s) {
  auto need = [](bool ok, const char* name, double v, const std::string& expected) {
    if (!ok || !std::isfinite(v)) throw InputError(opt(name), "value out of range", fmt::format("{:g}", v), expected);
  };
  need(s.porosity > kMinPorosity && s.porosity < kMaxPorosity, "--porosity", s.porosity,
       fmt::format("a porosity in ({:g}, {:g}) (below, grains separated by a throat cannot be packed; above, there is no pattern)", kMinPorosity, kMaxPorosity));
  need(s.porosity_tolerance >= 1e-4 && s.porosity_tolerance <= 0.05, "--porosity-tolerance", s.porosity_tolerance, "an absolute tolerance in [1e-4, 0.05]");
  need(s.length_mm > 0 && s.length_mm <= 1000, "--length-mm", s.length_mm, "a chip length in mm, > 0");
  need(s.width_mm > 0 && s.width_mm <= 1000, "--width-mm", s.width_mm, "a chip width in mm, > 0");
  need(s.pixel_um > 0 && s.pixel_um <= 1000, "--pixel-size-um", s.pixel_um, "a pixel size in um, > 0");
  need(s.fit_depth || (s.depth_um > 0 && s.depth_um <= 1e4), "--depth-um", s.depth_um, "a channel depth in um, > 0");
  need(s.grain_cv >= 0 && s.grain_cv <= 1, "--grain-cv", s.grain_cv, "a coefficient of variation in [0, 1]");
  need(s.min_throat_px >= 2 && s.min_throat_px <= 100, "--min-throat-px", s.min_throat_px,
       "at least 2 px (a throat of 1 px is under one cell at 1 cell per pixel and off by ~200 % at that)");
  need(s.wall_px >= 0 && s.wall_px <= 100, "--wall-px", s.wall_px, "a wall thickness in px, 1 to 100, or 0 for mirror sides (no walls)");
  if (s.fit_depth && !(s.permeability_D > 0 && s.mean_throat_um > 0))
    throw InputError(opt("--depth-um"), "--depth-um fit solves for the depth that gives the k target at the grain scale set by the throat target",
                     fmt::format("fit with --permeability-D {:g} and --mean-throat-um {:g}", s.permeability_D, s.mean_throat_um),
                     "both --permeability-D (the depth-averaged k to fit) and --mean-throat-um (the throat width that sets the grain scale), > 0");
  need(s.permeability_D >= 0, "--permeability-D", s.permeability_D, "a permeability in darcy, > 0 (0 or absent: no target)");
  need(s.permeability_tolerance >= 0.005 && s.permeability_tolerance <= 0.5, "--permeability-tolerance", s.permeability_tolerance,
       "a relative tolerance in [0.005, 0.5] (below the tile's scatter of ~1 % the search cannot settle)");
  need(s.mean_throat_um >= 0, "--mean-throat-um", s.mean_throat_um, "a mean throat width in um, > 0 (0 or absent: no target)");
  need(s.mean_grain_um >= 0, "--mean-grain-um", s.mean_grain_um, "a mean grain diameter in um, > 0 (0 or absent: estimated)");
  need(s.tile_mm > 0, "--tile-mm", s.tile_mm, "a tile side in mm, > 0");
  need(s.port_um >= 0 && s.port_um * 4e-3 < s.length_mm, "--port-um", s.port_um, "inlet / outlet columns >= 0 um (0: one mean grain), under a quarter of the length");
  need(s.cells_per_pixel >= 0.25 && s.cells_per_pixel <= 8, "--cells-per-pixel", s.cells_per_pixel, "cells per pixel in [0.25, 8]");
  const double pixels = s.length_mm * 1e3 / s.pixel_um * s.width_mm * 1e3 / s.pixel_um;
  need(pixels <= kMaxChipPixels, "--pixel-size-um", s.pixel_um, fmt::format("a pixel size that keeps the mask under {:g} pixels (got {:.3g})", kMaxChipPixels, pixels));
  if (s.permeability_D > 0) {
    const double lim = hsLimitDarcy(s);
    need(s.permeability_D < lim, "--permeability-D", s.permeability_D,
         fmt::format("a depth-averaged k below the open Hele-Shaw limit porosity x h^2 / 12 = {:.4g} D for --depth-um {} and --porosity {:g} (grains only "
                     "lower it)", lim, s.fit_depth ? fmt::format("fit (deepest searched: {:g} um)", kFitDepthMaxUm) : fmt::format("{:g}", s.depth_um),
                     s.porosity));
  }
  const double side_cols = (s.solve_on_tile ? std::min(s.tile_mm, s.length_mm) : s.length_mm) * 1e3 / s.pixel_um;
  const double side_rows = (s.solve_on_tile ? std::min(s.tile_mm, s.width_mm) : s.width_mm) * 1e3 / s.pixel_um;
  if (!s.ladder.empty()) {
    const double finest = std::max(s.ladder.back(), s.cells_per_pixel);
    const double bytes = detail::steadyFlowBytes(side_cols * side_rows * finest * finest, false);
    need(bytes <= defaultMaxMemoryBytes(), "--ladder", finest,
         fmt::format("a finest level whose direct solve fits in memory: {:.3g} cells need ~{:.1f} GB, {:.1f} GB available (coarser levels, a larger "
                     "--pixel-size-um, or --solve-on tile)", side_cols * side_rows * finest * finest, bytes / 1e9, defaultMaxMemoryBytes() / 1e9));
  }
  validateModel3D(s, side_cols, side_rows);
  bool has_level = false;
  for (std::size_t i = 0; i < s.ladder.size(); ++i) {
    need(s.ladder[i] >= 0.1 && s.ladder[i] <= 8, "--ladder", s.ladder[i], "cells per pixel in [0.1, 8]");
    if (i > 0) need(s.ladder[i] > 1.05 * s.ladder[i - 1], "--ladder", s.ladder[i], "levels growing coarse to fine by more than 5 % each");
    has_level = has_level || std::abs(s.ladder[i] - s.cells_per_pixel) < 1e-12;
  }
  need(has_level, "--ladder", s.cells_per_pixel, "a ladder that contains --cells-per-pixel (the level the k target is met at)");
}

namespace {

/// Stage 3: the full chip packed at scale d, its target checked there and d corrected with a secant
/// (up to kMaxChipCorrections times). Returns the final d; `known` gets the last solve at
/// cells_per_pixel for the ladder to reuse.
double confirmOnChip(const ChipSpec& s, double d, ChipResult& r, std::vector<std::pair<double, ChipFlowResult>>& known,
                     const std::function<void(const std::string&)>& log) {
  Secant sec;
  const bool by_k = tunesK(s);
  const double target = by_k ? s.permeability_D : s.mean_throat_um;
  const double tol = by_k ? s.permeability_tolerance : kChipThroatTolerance;
  const int cols = static_cast<int>(r.packing.solid.cols()), rows = static_cast<int>(r.packing.solid.rows());
  for (int round = 0; round <= kMaxChipCorrections; ++round) {
    const auto t1 = std::chrono::steady_clock::now();
    double v = 0;
    if (by_k) {
      const ChipFlowResult f = chipPermeability(analysePoreSpace(r.packing.solid).solid_connected, flowSettings(s), s.cells_per_pixel);
      known = {{s.cells_per_pixel, f}};
      v = f.permeability_m2 / kDarcyM2;
    } else {
      v = meanThroatUm(r.packing, s, d);
    }
    r.tuning.push_back({"chip", d, v, seconds(t1), target});
    if (log) log(fmt::format("chip: full chip {} x {} px: mean grain {:.4g} um -> {:.4g} (target {:.4g}, {:.1f} s)", cols, rows, d, v, target, seconds(t1)));
    if (std::abs(v / target - 1) <= tol || round == kMaxChipCorrections) break;
    d = std::exp(sec.next(std::log(d), std::log(v / target)));
    r.packing = pack(s, cols, rows, d);
    known.clear();
  }
  return d;
}

/// Solves of the depth fit on one pattern.
constexpr int kMaxDepthSteps = 12;
/// A depth step changes h by at most this factor.
constexpr double kMaxDepthStepFactor = 4.0;
/// d ln k / d ln h where the Hele-Shaw friction 12 mu u / h^2 dominates (throats much wider than h).
constexpr double kDepthStartSlope = 2.0;

/// Stage 3b (fit_depth): the depth h (um) whose depth-averaged k at cells_per_pixel meets the
/// target on `connected` (isolated pores closed): a secant on ln k against ln h from `h_um`, k(h)
/// being monotone, within [kFitDepthMinUm, kFitDepthMaxUm]. Every solve goes into r.depth_fit;
/// `known` gets the solve at the returned depth. Throws InputError (--permeability-D, --depth-um)
/// when the search ends at a bound with the target still beyond it.
double fitDepth(const ChipSpec& s, const BoolArray& connected, const std::string& where, double h_um, double tol, int max_steps, ChipResult& r,
                std::vector<std::pair<double, ChipFlowResult>>& known, const std::function<void(const std::string&)>& log) {
  const double lo = std::log(kFitDepthMinUm), hi = std::log(kFitDepthMaxUm), max_step = std::log(kMaxDepthStepFactor);
  double x = std::clamp(std::log(h_um), lo, hi), x0 = std::nan(""), f0 = std::nan("");
  double best_x = x, best_err = INFINITY;
  ChipFlowResult best;
  for (int step = 1; step <= max_steps; ++step) {
    const auto t0 = std::chrono::steady_clock::now();
    ChipFlowSettings fs = flowSettings(s);
    fs.depth_m = std::exp(x) * 1e-6;
    const ChipFlowResult res = chipPermeability(connected, fs, s.cells_per_pixel);
    const double k = res.permeability_m2 / kDarcyM2;
    r.depth_fit.push_back({where, std::exp(x), k, seconds(t0)});
    if (log) log(fmt::format("chip: depth fit on the {} ({} x {} px), step {}: h {:.4g} um -> k {:.4g} D (target {:.4g} D, {:.1f} s)", where, connected.cols(),
                             connected.rows(), step, std::exp(x), k, s.permeability_D, seconds(t0)));
    const double f = std::log(k / s.permeability_D);
    if (std::abs(f) < best_err) best_err = std::abs(f), best_x = x, best = res;
    if (std::abs(k / s.permeability_D - 1) <= tol) break;
    if ((f < 0 && x >= hi - 1e-9) || (f > 0 && x <= lo + 1e-9))
      throw InputError(opt("--permeability-D"),
                       fmt::format("--depth-um fit: no depth in [{:g}, {:g}] um gives this k with grains set by --mean-throat-um {:g}; at {:g} um k is {:.4g} D",
                                   kFitDepthMinUm, kFitDepthMaxUm, s.mean_throat_um, std::exp(x), k),
                       fmt::format("{:g}", s.permeability_D),
                       f < 0 ? "a smaller --permeability-D or a larger --mean-throat-um" : "a larger --permeability-D or a smaller --mean-throat-um");
    double slope = kDepthStartSlope;
    if (std::isfinite(x0) && std::abs(x - x0) > 1e-9) slope = (f - f0) / (x - x0);
    if (!(slope > 0) || !std::isfinite(slope)) slope = kDepthStartSlope;
    x0 = x;
    f0 = f;
    x = std::clamp(x - std::clamp(f / slope, -max_step, max_step), lo, hi);
  }
  if (best_err > std::log1p(tol) && log)
    log(fmt::format("chip: the depth fit did not settle within {} steps; keeping the closest ({:.2f} % off)", max_steps, 100 * (std::exp(best_err) - 1)));
  known = {{s.cells_per_pixel, best}};
  return std::exp(best_x);
}

/// Stage 3b: the depth for the k target, fitted on the tile at the final grain scale (the chip's
/// own pattern when the tile is the chip), then confirmed on the chip when the ladder solves the
/// chip. Refuses a target at or above the tile's plane-2D k, which bounds k at any depth.
double fitChipDepth(const ChipSpec& s, const BoolArray& tile, bool confirm_on_chip, ChipResult& r, std::vector<std::pair<double, ChipFlowResult>>& known,
                    const std::function<void(const std::string&)>& log) {
  const BoolArray tile_connected = analysePoreSpace(tile).solid_connected;
  ChipFlowSettings plane = flowSettings(s);
  plane.depth_m = 0;
  r.k_plane_2d_tile_D = chipPermeability(tile_connected, plane, s.cells_per_pixel).permeability_m2 / kDarcyM2;
  if (log) log(fmt::format("chip: depth fit: the tile's plane-2D k (the bound at any depth) is {:.4g} D", r.k_plane_2d_tile_D));
  if (s.permeability_D >= r.k_plane_2d_tile_D)
    throw InputError(opt("--permeability-D"),
                     fmt::format("--depth-um fit: the target is not below {:.4g} D, the plane-2D k of the pattern set by --mean-throat-um {:g}, which bounds the "
                                 "depth-averaged k at any depth", r.k_plane_2d_tile_D, s.mean_throat_um),
                     fmt::format("{:g}", s.permeability_D), "a smaller --permeability-D or a larger --mean-throat-um");
  // Start where the open Hele-Shaw channel would give the target (h = sqrt(12 k / porosity)), a
  // lower bound of h, times 1.5: the grains' side walls add friction.
  const double h0 = 1.5 * std::sqrt(12 * s.permeability_D * kDarcyM2 / s.porosity) * 1e6;
  const double tol = s.permeability_tolerance;
  double h = fitDepth(s, tile_connected, "tile", h0, confirm_on_chip ? 0.5 * tol : 0.25 * tol, kMaxDepthSteps, r, known, log);
  if (confirm_on_chip) {
    ChipSpec at = s;
    at.depth_um = h;
    h = fitDepth(at, analysePoreSpace(r.packing.solid).solid_connected, "chip", h, tol, kMaxChipCorrections + 1, r, known, log);
  }
  return h;
}

/// One 3D measurement on `solved` (the chip or the tile at scale d): the depth-averaged k at
/// cells_per_pixel (from `known` when that solve was done), the same model on the pixel staircase at
/// cells_per_pixel_3d, and coarse 3D Stokes there; `known` gets the depth-averaged solve.
ChipModel3DStep measure3D(const ChipSpec& s, const BoolArray& solved, const std::string& where, double d, double da_target,
                          std::vector<std::pair<double, ChipFlowResult>>& known, const std::function<void(const std::string&)>& log) {
  const auto t0 = std::chrono::steady_clock::now();
  ChipModel3DStep st;
  st.where = where;
  st.mean_grain_um = d;
  st.da_target_D = da_target;
  const BoolArray connected = analysePoreSpace(solved).solid_connected;
  ChipFlowResult da;
  if (!known.empty() && std::abs(known.front().first - s.cells_per_pixel) < 1e-12) da = known.front().second;
  else da = chipPermeability(connected, flowSettings(s), s.cells_per_pixel);
  known = {{s.cells_per_pixel, da}};
  st.k_da_D = da.permeability_m2 / kDarcyM2;
  ChipFlowSettings pixels = flowSettings(s);
  pixels.smooth_boundary = false;
  st.k_da_pixels_D = !s.smooth_boundary && std::abs(s.cells_per_pixel_3d - s.cells_per_pixel) < 1e-12
                         ? st.k_da_D
                         : chipPermeability(connected, pixels, s.cells_per_pixel_3d).permeability_m2 / kDarcyM2;
  st.run_3d = chipPermeability3D(connected, flowSettings(s), s.cells_per_pixel_3d, s.cells_z);
  st.ratio = st.run_3d.extrapolated_m2 / kDarcyM2 / st.k_da_pixels_D;
  st.k_3d_D = st.ratio * st.k_da_D;
  st.seconds = seconds(t0);
  if (log) {
    std::string ks, zs;
    for (std::size_t i = 0; i < s.cells_z.size(); ++i) {
      ks += fmt::format("{}{:.4g}", i ? " / " : "", st.run_3d.permeability_m2[i] / kDarcyM2);
      zs += fmt::format("{}{}", i ? "/" : "", s.cells_z[i]);
    }
    log(fmt::format("chip: 3D model on the {} ({} x {} px, mean grain {:.4g} um): depth-averaged {:.4g} D; at {:g} cells/px on pixels depth-averaged "
                    "{:.4g} D, 3D (cells_z {}) {} D, extrapolated {:.4g} D; ratio {:.4f} -> k_3d {:.4g} D (target {:.4g} D, {:.1f} s)",
                    where, connected.cols(), connected.rows(), d, st.k_da_D, s.cells_per_pixel_3d, st.k_da_pixels_D,
                    zs, ks, st.run_3d.extrapolated_m2 / kDarcyM2, st.ratio, st.k_3d_D, s.permeability_D, st.seconds));
  }
  return st;
}

/// Stage 3c (permeability_model "3d"): measures k_3d = r k_da on the solved region; while it misses
/// the target, re-tunes the grain scale to the depth-averaged target permeability_D / r (tile, then
/// chip as in stages 3-4) and measures again, up to kMaxChip3DRetunes times. The re-tuning runs at
/// half the k tolerance so that the ratio's drift between scales has room. Returns the final d.
double tuneTo3D(const ChipSpec& s, double d, int tile_cols, int tile_rows, bool confirm_on_chip, ChipResult& r,
                std::vector<std::pair<double, ChipFlowResult>>& known, const std::function<void(const std::string&)>& log) {
  const int cols = static_cast<int>(r.packing.solid.cols()), rows = static_cast<int>(r.packing.solid.rows());
  const bool on_tile = s.solve_on_tile && !(tile_cols == cols && tile_rows == rows);
  double da_target = s.permeability_D;
  for (int round = 0;; ++round) {
    const BoolArray solved = on_tile ? pack(s, tile_cols, tile_rows, d).solid : r.packing.solid;
    r.model_3d.push_back(measure3D(s, solved, on_tile ? "tile" : "chip", d, da_target, known, log));
    const ChipModel3DStep& st = r.model_3d.back();
    if (std::abs(st.k_3d_D / s.permeability_D - 1) <= s.permeability_tolerance) break;
    if (round == kMaxChip3DRetunes) {
      if (log) log(fmt::format("chip: the 3D model's k did not settle within {} re-tunings ({:.2f} % off)", kMaxChip3DRetunes, 100 * (st.k_3d_D / s.permeability_D - 1)));
      break;
    }
    ChipSpec sd = s;
    da_target = s.permeability_D / st.ratio;
    sd.permeability_D = da_target;
    sd.permeability_tolerance = std::max(0.005, 0.5 * s.permeability_tolerance);
    sd.mean_grain_um = d;
    if (log) log(fmt::format("chip: re-tuning to the depth-averaged target {:.4g} D (= {:.4g} D / ratio {:.4f})", da_target, s.permeability_D, st.ratio));
    d = tuneOnTile(sd, tile_cols, tile_rows, r, log);
    r.packing = pack(s, cols, rows, d);
    known.clear();
    if (confirm_on_chip) d = confirmOnChip(sd, d, r, known, log);
  }
  r.da_target_D = da_target;
  return d;
}

/// Stage 4: both depth models on the ladder, on `solved` (the chip or a tile).
void solveLadders(const ChipSpec& s, const BoolArray& solved, const std::vector<std::pair<double, ChipFlowResult>>& known, ChipResult& r,
                  const std::function<void(const std::string&)>& log) {
  r.solved_cols = static_cast<int>(solved.cols());
  r.solved_rows = static_cast<int>(solved.rows());
  const PoreSpaceReport pores = analysePoreSpace(solved);
  if (log) log(fmt::format("chip: ladder of {} levels on {} x {} px, depth-averaged, then plane 2D", s.ladder.size(), solved.cols(), solved.rows()));
  r.ladder_da = chipLadder(pores.solid_connected, flowSettings(s), s.ladder, "depth-averaged", known);
  r.ladder_2d = chipLadder(pores.solid_connected, flowSettings(s), s.ladder, "2d");
  for (std::size_t i = 0; i < s.ladder.size(); ++i)
    if (std::abs(s.ladder[i] - s.cells_per_pixel) < 1e-12) r.k_target_level_D = r.ladder_da.runs[i].permeability_m2 / kDarcyM2;
}

/// Stage 4b (solve-on tile): four tile-sized windows of the chip itself, framed as the tile is
/// (ports and walls), depth-averaged, at the ladder's coarsest level, to compare with the tile at
/// that level (chip.json tile_samples).
void sampleChipTiles(const ChipSpec& s, int tile_cols, int tile_rows, ChipResult& r, const std::function<void(const std::string&)>& log) {
  const BoolArray& chip = r.packing.solid;
  const double level = s.ladder.front();
  if (log) log(fmt::format("chip: 4 windows of {} x {} px of the chip at {:g} cells/px, depth-averaged (is the tile representative?)", tile_cols, tile_rows, level));
  for (const double fy : kTileSampleFractions)
    for (const double fx : kTileSampleFractions) {
      ChipTileSample t;
      t.col = static_cast<int>(std::lround(fx * static_cast<double>(chip.cols() - tile_cols)));
      t.row = static_cast<int>(std::lround(fy * static_cast<double>(chip.rows() - tile_rows)));
      // Framed as the tile is packed: grain-free inlet and outlet columns, solid wall rows (a bare
      // cut would compare entrance losses through cut grains, not the pattern).
      BoolArray window = chip.block(t.row, t.col, tile_rows, tile_cols);
      const int port = std::min(tile_cols / 4, static_cast<int>(std::lround((s.port_um > 0 ? s.port_um : r.mean_grain_um) / s.pixel_um)));
      const int wall = std::min(tile_rows / 4, s.wall_px);
      window.leftCols(port) = false;
      window.rightCols(port) = false;
      window.topRows(wall) = true;
      window.bottomRows(wall) = true;
      const PoreSpaceReport pores = analysePoreSpace(window);
      t.porosity = pores.porosity_total;
      try {
        t.k_D = chipPermeability(pores.solid_connected, flowSettings(s), level).permeability_m2 / kDarcyM2;
      } catch (const std::exception& e) {
        t.k_D = std::nan("");
        t.error = e.what();
      }
      r.tile_samples.push_back(t);
    }
}

}  // namespace

ChipResult generateChip(const ChipSpec& spec, const std::function<void(const std::string&)>& log) {
  validateChipSpec(spec);
  ChipSpec s = spec;  // with fit_depth, depth_um becomes the fitted depth
  const auto t0 = std::chrono::steady_clock::now();
  ChipResult r;
  r.spec = s;
  const int cols = static_cast<int>(std::lround(s.length_mm * 1e3 / s.pixel_um));
  const int rows = static_cast<int>(std::lround(s.width_mm * 1e3 / s.pixel_um));
  const int tile_cols = std::min(cols, static_cast<int>(std::lround(s.tile_mm * 1e3 / s.pixel_um)));
  const int tile_rows = std::min(rows, static_cast<int>(std::lround(s.tile_mm * 1e3 / s.pixel_um)));
  const bool tuned = s.permeability_D > 0 || s.mean_throat_um > 0;
  const bool tile_is_chip = tile_cols == cols && tile_rows == rows;
  auto stage = std::chrono::steady_clock::now();
  auto lap = [&](const char* name) {
    r.stage_seconds[name] = seconds(stage);
    stage = std::chrono::steady_clock::now();
  };
  double d = tuned ? tuneOnTile(s, tile_cols, tile_rows, r, log) : startDiameterUm(s);
  lap("tune");
  if (log) log(fmt::format("chip: packing the chip, {} x {} px, mean grain {:.4g} um", cols, rows, d));
  r.packing = pack(s, cols, rows, d);
  lap("pack");
  std::vector<std::pair<double, ChipFlowResult>> known;  // the last full-chip solve at cells_per_pixel
  if (tuned && !tile_is_chip && !s.solve_on_tile) d = confirmOnChip(s, d, r, known, log);
  r.mean_grain_um = d;
  r.da_target_D = s.permeability_D;
  lap("confirm");
  if (s.permeability_model == kChipModel3D) {
    d = r.mean_grain_um = tuneTo3D(s, d, tile_cols, tile_rows, !tile_is_chip && !s.solve_on_tile, r, known, log);
    lap("model_3d");
  }
  if (s.fit_depth) {
    const bool on_chip = !tile_is_chip && !s.solve_on_tile;
    s.depth_um = fitChipDepth(s, tile_is_chip ? r.packing.solid : pack(s, tile_cols, tile_rows, d).solid, on_chip, r, known, log);
    r.spec = s;
    if (log) log(fmt::format("chip: fitted depth {:.4g} um (the depth-averaged k target at {:g} cells/px; the ladder uses it)", s.depth_um, s.cells_per_pixel));
    lap("depth_fit");
  }
  if (s.solve_on_tile && !tile_is_chip) {
    solveLadders(s, pack(s, tile_cols, tile_rows, d).solid, known, r, log);
    sampleChipTiles(s, tile_cols, tile_rows, r, log);
  } else {
    solveLadders(s, r.packing.solid, known, r, log);
  }
  lap("ladder");
  if (log) log("chip: statistics (pore space, throats, narrowest spanning throat)");
  r.stats = chipStatistics(r);
  lap("statistics");
  r.seconds = seconds(t0);
  r.stats["generation"]["tile_porosity"] = patternPorosity(s, tile_cols, tile_rows, (s.port_um > 0 ? s.port_um : d) / s.pixel_um);
  r.stats["generation"]["tile_porosity_rule"] = "the tile is packed with the grain region (between ports and walls) as dense as the chip's";
  r.stats["generation"]["wall_seconds"] = r.seconds;
  r.stats["generation"]["stage_seconds"] = r.stage_seconds;
  return r;
}

}  // namespace mmval::simulate
