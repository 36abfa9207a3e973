// The chip-generator kind: `mmval chip` (ChipGenerator.hpp, docs/chip-generator.md) as a case, so
// that a validation can generate a chip from its statistics and report what it achieved.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "KindsCommon.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/ChipGenerator.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::simulate {

namespace {
constexpr double kDarcy = 9.869233e-13;  // m2

/// The case key behind each `mmval chip` option that validateChipSpec / generateChip name in their errors.
const std::map<std::string, std::string, std::less<>>& keyOfOption() {
  static const std::map<std::string, std::string, std::less<>> m = {
      {"--length-mm", "geometry.length"},
      {"--width-mm", "geometry.width"},
      {"--pixel-size-um", "geometry.pixel_size"},
      {"--depth-um", "geometry.depth"},
      {"--min-throat-px", "geometry.min_throat_px"},
      {"--porosity", "target.porosity"},
      {"--porosity-tolerance", "target.porosity_tolerance"},
      {"--permeability-D", "target.permeability"},
      {"--permeability-tolerance", "target.permeability_tolerance"},
      {"--permeability-model", "target.permeability_model"},
      {"--cells-per-pixel-3d", "numerics.cells_per_pixel_3d"},
      {"--cells-z-levels", "numerics.cells_z_levels"},
      {"--mean-throat-um", "target.mean_throat"},
      {"--mean-grain-um", "grains.mean_diameter"},
      {"--grain-cv", "grains.cv"},
      {"--tile-mm", "numerics.tile"},
      {"--cells-per-pixel", "numerics.cells_per_pixel"},
      {"--ladder", "numerics.ladder"},
      {"--solve-on", "numerics.solve_on"},
      {"--boundary", "geometry.boundary"},
      {"--seed", "generator.seed"},
  };
  return m;
}

/// `text` with the generator's option names replaced by the case keys behind them.
std::string inCaseKeys(std::string text) {
  // Longest options first, so that --porosity does not eat --porosity-tolerance.
  std::vector<std::pair<std::string, std::string>> pairs(keyOfOption().begin(), keyOfOption().end());
  std::sort(pairs.begin(), pairs.end(), [](const auto& a, const auto& b) { return a.first.size() > b.first.size(); });
  for (const auto& p : pairs)
    for (std::size_t at = text.find(p.first); at != std::string::npos; at = text.find(p.first, at + p.second.size())) {
      const std::size_t end = at + p.first.size();
      if (end < text.size() && (std::isalnum(static_cast<unsigned char>(text[end])) || text[end] == '-')) {
        at = end;  // a longer option that starts the same
        continue;
      }
      text.replace(at, p.first.size(), p.second);
    }
  return text;
}

/// The generator's error, located at the case key of the option it names (the option when none maps).
[[noreturn]] void rethrowAtKey(const Case& c, const InputError& e) {
  const auto it = keyOfOption().find(e.where().key);
  if (it == keyOfOption().end()) throw e;
  throw InputError(c.where(it->second), inCaseKeys(e.problem()), e.got(), inCaseKeys(e.expected()));
}

ChipSpec specOf(const Case& c) {
  ChipSpec s;
  s.length_mm = c.quantity("geometry.length") * 1e3;
  s.width_mm = c.quantity("geometry.width") * 1e3;
  s.pixel_um = c.quantity("geometry.pixel_size") * 1e6;
  s.depth_um = c.quantity("geometry.depth") * 1e6;
  s.min_throat_px = c.real("geometry.min_throat_px");
  s.smooth_boundary = c.text("geometry.boundary") == "smooth";
  s.porosity = c.real("target.porosity");
  s.porosity_tolerance = c.real("target.porosity_tolerance");
  s.permeability_D = c.quantity("target.permeability") / kDarcy;
  s.permeability_tolerance = c.real("target.permeability_tolerance");
  s.mean_throat_um = c.quantity("target.mean_throat") * 1e6;
  s.mean_grain_um = c.quantity("grains.mean_diameter") * 1e6;
  s.grain_cv = c.real("grains.cv");
  s.tile_mm = c.quantity("numerics.tile") * 1e3;
  s.cells_per_pixel = c.real("numerics.cells_per_pixel");
  s.ladder = c.reals("numerics.ladder");
  s.solve_on_tile = c.text("numerics.solve_on") == "tile";
  s.permeability_model = c.text("target.permeability_model");
  s.cells_per_pixel_3d = c.real("numerics.cells_per_pixel_3d");
  if (c.has("numerics.cells_z_levels")) {
    s.cells_z.clear();
    for (const auto v : c.integers("numerics.cells_z_levels")) s.cells_z.push_back(static_cast<int>(v));
  }
  s.seed = static_cast<std::uint64_t>(c.integer("generator.seed"));
  return s;
}

void chipGeneratorMetrics(Schema& s) {
  s.metric("porosity_connected", "1", "Pore pixels connected inlet to outlet over all pixels of the generated chip (walls included)");
  s.metric("permeability_depth_averaged", "D", "Depth-averaged permeability at numerics.cells_per_pixel, the level the k target is met at");
  s.metric("permeability_depth_averaged_extrapolated", "D",
           "Depth-averaged permeability Richardson-extrapolated over numerics.ladder with the observed order (monotone convergence only)");
  s.metric("permeability_depth_averaged_observed_order", "1", "Observed order of the depth-averaged permeability from the three finest ladder levels");
  s.metric("permeability_depth_averaged_gci", "1", "Grid convergence index of the finest depth-averaged permeability, relative (Celik et al. 2008)");
  s.metric("permeability_2d_extrapolated", "D", "Plane 2D permeability Richardson-extrapolated over numerics.ladder (monotone convergence only)");
  s.metric("mean_throat_radius", "um", "Mean throat radius: half the mean gap between neighbouring grains (or grain and wall) of the disc geometry");
  s.metric("median_throat_radius", "um", "Median throat radius: half the median gap");
  s.metric("grains", "1", "Number of grains of the chip");
  s.metric("mean_grain_diameter", "um", "Mean grain diameter of the chip");
  s.metric("permeability_3d", "D",
           "target.permeability_model = 3d: the 3D model's k that meets the target, the depth-averaged k at numerics.cells_per_pixel times the "
           "ratio of coarse 3D Stokes to depth-averaged k on the pixel staircase at numerics.cells_per_pixel_3d");
  s.metric("permeability_3d_extrapolated", "D", "target.permeability_model = 3d: the same ratio times the extrapolated depth-averaged k of the ladder");
  s.metric("k_3d_over_depth_averaged", "1", "target.permeability_model = 3d: that ratio (cells_z Richardson-extrapolated 3D over depth-averaged)");
  s.metric("tile_window_over_tile", "1",
           "numerics.solve_on = tile: mean depth-averaged k of tile-sized windows of the chip over the tile's, at the ladder's coarsest level "
           "(1: the tile stands for the chip)");
}
}  // namespace

CaseKind chipGeneratorKind() {
  CaseKind k;
  k.name = "chip-generator";
  k.summary = "Sand-pack-like micromodel generated from its statistics (porosity, depth-averaged permeability, grain sizes), with its "
              "achieved statistics and grid convergence (the `mmval chip` generator, docs/chip-generator.md)";
  k.declare = [](Schema& s) {
    s.quantity("geometry.length", "mm", "Chip length along the flow (x)").def("4 mm").positive();
    s.quantity("geometry.width", "mm", "Chip width across the flow (y)").def("2 mm").positive();
    s.quantity("geometry.pixel_size", "um", "Pixel size of the mask").def("5 um").positive();
    s.quantity("geometry.depth", "um", "Channel depth h (Hele-Shaw friction 12 mu u / h^2 of the depth-averaged model)").def("20 um").positive();
    s.real("geometry.min_throat_px", "Smallest gap between grains and from a grain to the walls, in pixels").def(3.0).min(2).max(100);
    s.choice("geometry.boundary", {"smooth", "pixels"}, "Grain boundary of the permeability solves (image-permeability's geometry.boundary)").def("smooth");
    s.real("target.porosity", "Target porosity (walls included), met by construction within target.porosity_tolerance").def(0.58).min(kMinPorosity, true).max(kMaxPorosity, true);
    s.real("target.porosity_tolerance", "Absolute porosity tolerance").def(0.005).min(1e-4).max(0.05);
    s.quantity("target.permeability", "D", "Target depth-averaged permeability at numerics.cells_per_pixel (the grain scale is tuned to it); 0: none")
        .def("0 D")
        .nonNegative();
    s.real("target.permeability_tolerance", "Relative tolerance of the permeability target").def(0.05).min(1e-3).max(0.5);
    const ChipSpec defaults;
    s.choice("target.permeability_model", {kChipModelDepthAveraged, kChipModel3D},
             "Which model's k meets target.permeability: depth-averaged (Brinkman-Hele-Shaw), or 3d (the depth-averaged k times the measured ratio of "
             "coarse 3D Stokes to depth-averaged k on the same pixel staircase and grid, docs/chip-generator.md)")
        .def(defaults.permeability_model);
    s.real("numerics.cells_per_pixel_3d", "target.permeability_model = 3d: in-plane cells per pixel of the 3D model (the mask block-averaged)")
        .def(defaults.cells_per_pixel_3d)
        .min(0.25)
        .max(4);
    s.integerList("numerics.cells_z_levels",
                  fmt::format("target.permeability_model = 3d: cells across the depth, coarse to fine (Richardson in dz over the last two, order 2); "
                              "absent: {}",
                              fmt::join(defaults.cells_z, ", ")))
        .optional();
    s.quantity("target.mean_throat", "um", "Target mean throat width, tuned when there is no permeability target; 0: none").def("0 um").nonNegative();
    s.quantity("grains.mean_diameter", "um", "Mean grain diameter: fixed without targets, else the tuning's start; 0: estimated").def("0 um").nonNegative();
    s.real("grains.cv", "Coefficient of variation of the (lognormal) grain diameter").def(0.3).min(0).max(1);
    s.integer("generator.seed", "Random seed (same keys and seed: the same chip.png, byte for byte)").def(1).min(0);
    s.quantity("numerics.tile", "mm", "Side of the square tile the grain scale is tuned on (capped at the chip)").def("1.5 mm").positive();
    s.real("numerics.cells_per_pixel", "Solver resolution at which the permeability target is met").def(1.0).min(0.25).max(8);
    s.realList("numerics.ladder", "Grid ladder in cells per pixel, coarse to fine (must contain numerics.cells_per_pixel)")
        .def(std::vector<double>{0.5, 1, 2})
        .min(0.1)
        .max(8);
    s.choice("numerics.solve_on", {"chip", "tile"},
             "Where k is confirmed and the ladder solved: the chip, or the tuning tile at the final grain scale (chips too large to solve)")
        .def("chip");
  };
  k.metrics = chipGeneratorMetrics;
  k.run = [](const Case& c, const RunContext& ctx) {
    const ChipSpec spec = specOf(c);
    const bool quiet = ctx.quiet;
    ChipResult r;
    try {
      validateChipSpec(spec);  // before anything is generated
      r = generateChip(spec, [quiet](const std::string& line) {
        if (!quiet && PetscSession::rank() == 0) std::fprintf(stderr, "%s\n", line.c_str());
      });
    } catch (const InputError& e) {
      rethrowAtKey(c, e);
    }
    RunOutput out;
    if (!ctx.out_dir.empty()) {
      if (PetscSession::rank() == 0) writeChipOutputs(r, ctx.out_dir);
      for (const char* f : {"chip.png", "chip.json", "chip-picture.png", "grain-sizes.csv", "throat-sizes.csv"}) out.files.emplace_back(f);
    }
    // Every metric is read from chip.json's document, so the report and the file cannot disagree.
    const nlohmann::json& j = r.stats;
    out.details["solver"] = detail::kSolverName;
    // Literal names (the metric-contract test reads them); a ladder without an observed order has
    // no extrapolation, and its metrics are left out rather than written as NaN.
    const nlohmann::json& da = j["permeability"]["depth_averaged"];
    out.metrics["porosity_connected"] = j["porosity"]["connected"].get<double>();
    out.metrics["permeability_depth_averaged"] = r.k_target_level_D * kDarcy;
    if (da["extrapolated_D"].is_number()) out.metrics["permeability_depth_averaged_extrapolated"] = da["extrapolated_D"].get<double>() * kDarcy;
    if (da["observed_order"].is_number()) out.metrics["permeability_depth_averaged_observed_order"] = da["observed_order"].get<double>();
    if (da["gci"].is_number()) out.metrics["permeability_depth_averaged_gci"] = da["gci"].get<double>();
    if (const auto& x2 = j["permeability"]["2d"]["extrapolated_D"]; x2.is_number()) out.metrics["permeability_2d_extrapolated"] = x2.get<double>() * kDarcy;
    out.metrics["mean_throat_radius"] = j["throats"]["mean_radius_um"].get<double>() * 1e-6;
    out.metrics["median_throat_radius"] = 0.5 * j["throats"]["median_width_um"].get<double>() * 1e-6;
    out.metrics["grains"] = j["grains"]["count"].get<double>();
    out.metrics["mean_grain_diameter"] = j["grains"]["mean_diameter_um"].get<double>() * 1e-6;
    if (j["permeability"].contains("model_3d") && j["permeability"]["model_3d"].contains("ratio")) {
      const nlohmann::json& m = j["permeability"]["model_3d"];
      out.metrics["permeability_3d"] = m["k_3d_D"].get<double>() * kDarcy;
      if (m.contains("k_3d_extrapolated_D")) out.metrics["permeability_3d_extrapolated"] = m["k_3d_extrapolated_D"].get<double>() * kDarcy;
      out.metrics["k_3d_over_depth_averaged"] = m["ratio"].get<double>();
      out.units["permeability_3d"] = out.units["permeability_3d_extrapolated"] = "D";
    }
    if (j["permeability"].contains("tile_samples"))
      if (const auto& ts = j["permeability"]["tile_samples"]; ts.contains("mean_over_tile") && ts["mean_over_tile"].is_number())
        out.metrics["tile_window_over_tile"] = ts["mean_over_tile"].get<double>();
    for (const char* m : {"permeability_depth_averaged", "permeability_depth_averaged_extrapolated", "permeability_2d_extrapolated"}) out.units[m] = "D";
    for (const char* m : {"mean_throat_radius", "median_throat_radius", "mean_grain_diameter"}) out.units[m] = "um";
    std::vector<std::string> warnings;
    if (!j["permeability"]["converged"].get<bool>())
      warnings.push_back(fmt::format("depth-averaged permeability ladder not converged within the {:g} % tolerance ({}): see chip.json",
                                     100 * spec.permeability_tolerance, da["status"].get<std::string>()));
    if (const auto& t3 = j["targets"]; t3.contains("permeability_3d_D") && !t3["permeability_3d_D"]["met"].get<bool>())
      warnings.push_back(fmt::format("the 3D model's k {:.4g} D misses the target after {} re-tunings: see chip.json permeability.model_3d",
                                     t3["permeability_3d_D"]["achieved"].get<double>(), kMaxChip3DRetunes));
    if (!warnings.empty()) out.details["warnings"] = warnings;
    for (const auto& w : warnings)
      if (!ctx.quiet && PetscSession::rank() == 0) std::fprintf(stderr, "mmval: warning: %s\n", w.c_str());
    return out;
  };
  return k;
}

}  // namespace mmval::simulate
