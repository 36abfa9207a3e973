// `mmval chip` (see ChipCommand.hpp): parses options, calls the generator, stages the folder.
#include "ChipCommand.hpp"

#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/simulate/ChipGenerator.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::app {

namespace {

struct ChipCli {
  std::string out;
  std::string boundary = "smooth";
  std::string solve_on = "chip";
  std::string depth = "20";
  bool quiet = false;
  simulate::ChipSpec spec;
};

void printSummary(const simulate::ChipResult& r, const std::string& out) {
  const auto& j = r.stats;
  const auto& t = j["targets"];
  std::printf("chip: %lld x %lld px at %g um/px (%g x %g mm), seed %llu, %zu grains -> %s\n", static_cast<long long>(j["image"]["cols"].get<int>()),
              static_cast<long long>(j["image"]["rows"].get<int>()), r.spec.pixel_um, r.spec.length_mm, r.spec.width_mm,
              static_cast<unsigned long long>(r.spec.seed), r.packing.discs.size(), out.c_str());
  std::printf("  k solved on        %s, %d x %d px\n", j["permeability"]["solved_on"]["what"].get<std::string>().c_str(), r.solved_cols, r.solved_rows);
  std::printf("  porosity            total %.4f, connected %.4f (target %.4f +- %.4f)\n", j["porosity"]["total"].get<double>(),
              j["porosity"]["connected"].get<double>(), r.spec.porosity, r.spec.porosity_tolerance);
  for (const auto& [name, key] : {std::pair{"2d", "2d"}, std::pair{"depth-averaged", "depth_averaged"}}) {
    const auto& l = j["permeability"][key];
    std::string runs;
    for (const auto& run : l["runs"]) runs += fmt::format(" {:.4g}", run["permeability_D"].get<double>());
    std::printf("  k %-16s D at cells/px ladder:%s; %s, extrapolated %s D, GCI %s\n", name, runs.c_str(), l["status"].get<std::string>().c_str(),
                l["extrapolated_D"].is_null() ? "-" : fmt::format("{:.4g}", l["extrapolated_D"].get<double>()).c_str(),
                l["gci"].is_null() ? "-" : fmt::format("{:.2f} %", 100 * l["gci"].get<double>()).c_str());
  }
  if (j.contains("depth_fit")) {
    std::string steps;
    for (const auto& st : j["depth_fit"]["steps"])
      steps += fmt::format(" {} {:.4g} um: {:.4g} D;", st["where"].get<std::string>(), st["depth_um"].get<double>(), st["k_D"].get<double>());
    std::printf("  depth fitted        %.4g um (k at%s plane-2D bound %.4g D): %s\n", r.spec.depth_um, steps.c_str(),
                j["depth_fit"]["k_plane_2d_tile_D"].get<double>(), j["depth_fit"]["why"].get<std::string>().c_str());
  }
  const bool model_3d = t.contains("permeability_3d_D");
  if (r.spec.permeability_D > 0 && !model_3d)
    std::printf("  k target            %.4g D +- %.1f %% at %g cells/px: achieved %.4g D (%s)%s\n", r.spec.permeability_D, 100 * r.spec.permeability_tolerance,
                r.spec.cells_per_pixel, r.k_target_level_D, t["permeability_depth_averaged_D"]["met"].get<bool>() ? "met" : "NOT met",
                j["permeability"]["converged"].get<bool>() ? "" : "; the ladder is not converged within the tolerance (see chip.json)");
  if (model_3d) {
    const auto& m = j["permeability"]["model_3d"];
    std::string steps;
    for (const auto& st : m["steps"])
      steps += fmt::format(" {} {:.4g} um: depth-averaged {:.4g} D, ratio {:.4f}, 3D {:.4g} D;", st["where"].get<std::string>(),
                           st["mean_grain_um"].get<double>(), st["k_depth_averaged_D"].get<double>(), st["ratio"].get<double>(), st["k_3d_D"].get<double>());
    std::printf("  3D model steps     %s\n", steps.c_str());
    std::printf("  k target (3D model) %.4g D +- %.1f %% at %g cells/px: achieved %.4g D (%s) = depth-averaged %.4g D x 3D ratio %.4f (3D at %g cells/px, "
                "cells_z extrapolated)%s%s\n",
                r.spec.permeability_D, 100 * r.spec.permeability_tolerance, r.spec.cells_per_pixel, t["permeability_3d_D"]["achieved"].get<double>(),
                t["permeability_3d_D"]["met"].get<bool>() ? "met" : "NOT met", r.k_target_level_D, m["ratio"].get<double>(), r.spec.cells_per_pixel_3d,
                m.contains("k_3d_extrapolated_D") ? fmt::format("; extrapolated in-plane {:.4g} D", m["k_3d_extrapolated_D"].get<double>()).c_str() : "",
                j["permeability"]["converged"].get<bool>() ? "" : "; the ladder is not converged within the tolerance (see chip.json)");
  }
  if (j["permeability"].contains("tile_samples") && j["permeability"]["tile_samples"].contains("mean_D")) {
    const auto& ts = j["permeability"]["tile_samples"];
    std::printf("  chip windows        depth-averaged k %.4g D +- %.2g (SD of %zu) at %g cells/px against the tile's %.4g D (x %.3f)%s\n",
                ts["mean_D"].get<double>(), ts["sd_D"].get<double>(), ts["windows"].size(), ts["cells_per_pixel"].get<double>(),
                ts["tile_k_D"].get<double>(), ts["mean_over_tile"].get<double>(),
                ts["representative"].get<bool>() ? "" : "; the tile does not represent the chip within the tolerance");
  }
  if (const auto& h = j["homogeneity"]; h.contains("porosity") && h["sd_over_poisson"].is_number())
    std::printf("  homogeneity         porosity of %d windows of %.0f um: SD %.4f (%.2f x that of independently placed grains), range %.4f-%.4f\n",
                h["count"].get<int>(), h["window_um"].get<double>(), h["porosity"]["sd"].get<double>(), h["sd_over_poisson"].get<double>(),
                h["porosity"]["min"].get<double>(), h["porosity"]["max"].get<double>());
  std::printf("  grains              mean diameter %.4g um, cv %.3f (asked %.3f)\n", j["grains"]["mean_diameter_um"].get<double>(), j["grains"]["cv"].get<double>(),
              r.spec.grain_cv);
  std::printf("  throats             %d, mean width %.4g um (radius %.4g um), min %.4g um, median %.4g um\n", j["throats"]["count"].get<int>(),
              j["throats"]["mean_width_um"].get<double>(), j["throats"]["mean_radius_um"].get<double>(), j["throats"]["min_width_um"].get<double>(),
              j["throats"]["median_width_um"].get<double>());
  if (const auto& q = j["throats"]["quantiles_width_um"]; q.is_object())
    std::printf("  throat widths       percentiles 10/25/75/90: %.4g / %.4g / %.4g / %.4g um\n", q["p10"].get<double>(), q["p25"].get<double>(),
                q["p75"].get<double>(), q["p90"].get<double>());
  if (const auto& tr = j["throats_rendered"]; tr.is_object())
    std::printf("  throats as rendered min %.4g um, median %.4g um, mean %.4g um; %d under the minimum gap %.4g um (%d pixels cleared)\n",
                tr["min_width_um"].get<double>(), tr["median_width_um"].get<double>(), tr["mean_width_um"].get<double>(),
                tr["grain_pairs_under_min_gap"].get<int>(), tr["min_gap_um"].get<double>(), tr["cleared_px"].get<int>());
  if (j.contains("narrowest_spanning_throat"))
    std::printf("  spanning path       narrowest %.4g um at (%g, %g) px\n", j["narrowest_spanning_throat"]["width_um"].get<double>(),
                j["narrowest_spanning_throat"]["x_px"].get<double>(), j["narrowest_spanning_throat"]["y_px"].get<double>());
  std::printf("chip: generated in %.1f s\n", r.seconds);
}

}  // namespace

void registerChipCommand(CLI::App& app) {
  auto c = std::make_shared<ChipCli>();
  simulate::ChipSpec& s = c->spec;
  CLI::App* cmd = app.add_subcommand("chip", "Generate a sand-pack-like micromodel mask (grains dark) for a target porosity, depth-averaged permeability "
                                             "and grain-size distribution, with its statistics (chip.png, chip.json, chip-picture.png)");
  cmd->add_option("--out", c->out, "Output folder")->required();
  cmd->add_option("--length-mm", s.length_mm, "Chip length along the flow (x)")->capture_default_str();
  cmd->add_option("--width-mm", s.width_mm, "Chip width across the flow (y)")->capture_default_str();
  // --pixel-size-um as in track, synth and compare; --pixel-um is the older spelling, hidden from --help.
  CLI::Option* pixel = cmd->add_option("--pixel-size-um", s.pixel_um, "Pixel size")->capture_default_str();
  CLI::Option* older_pixel = cmd->add_option("--pixel-um", s.pixel_um)->group("");
  cmd->add_option("--depth-um", c->depth,
                  "Channel depth h in um (Hele-Shaw friction 12 mu u / h^2), or 'fit': the depth that gives --permeability-D with the grain scale set by "
                  "--mean-throat-um (both required)")
      ->capture_default_str();
  cmd->add_option("--porosity", s.porosity, "Target porosity (walls included), in (0.2, 0.95)")->capture_default_str();
  cmd->add_option("--porosity-tolerance", s.porosity_tolerance, "Absolute porosity tolerance")->capture_default_str();
  cmd->add_option("--permeability-D", s.permeability_D, "Target depth-averaged permeability in darcy (0: none)")->capture_default_str();
  cmd->add_option("--permeability-tolerance", s.permeability_tolerance, "Relative k tolerance")->capture_default_str();
  cmd->add_option("--permeability-model", s.permeability_model,
                  "Which model's k meets --permeability-D: depth-averaged (Brinkman-Hele-Shaw), or 3d (coarse 3D Stokes: the depth-averaged k times the "
                  "measured ratio of 3D to depth-averaged k on the same staircase and grid; docs/chip-generator.md)")
      ->check(CLI::IsMember({simulate::kChipModelDepthAveraged, simulate::kChipModel3D}))
      ->capture_default_str();
  cmd->add_option("--cells-per-pixel-3d", s.cells_per_pixel_3d, "3D model: in-plane cells per pixel (the mask block-averaged)")->capture_default_str();
  cmd->add_option("--cells-z-levels", s.cells_z, "3D model: cells across the depth, coarse to fine (Richardson in dz over the last two)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--mean-throat-um", s.mean_throat_um, "Target mean throat width (used without a k target; 0: none)")->capture_default_str();
  cmd->add_option("--mean-grain-um", s.mean_grain_um, "Mean grain diameter (fixed without targets, else the start; 0: estimated)")->capture_default_str();
  cmd->add_option("--grain-cv", s.grain_cv, "Coefficient of variation of the (lognormal) grain diameter")->capture_default_str();
  cmd->add_option("--min-throat-px", s.min_throat_px, "Smallest gap between grains and to the walls, px")->capture_default_str();
  cmd->add_option("--wall-px", s.wall_px,
                  "Solid wall rows at the top and bottom; 0: none, the sides are mirror planes (grains kept half the minimum gap "
                  "from them, throats to them counted twice their distance; a strip of a wider chip, particles-micromodel's "
                  "geometry.sides = \"slip\")")
      ->capture_default_str();
  cmd->add_option("--port-um", s.port_um, "Grain-free inlet and outlet columns (0: one mean grain diameter)")->capture_default_str();
  cmd->add_option("--tile-mm", s.tile_mm, "Side of the square tile the grain scale is tuned on")->capture_default_str();
  cmd->add_option("--cells-per-pixel", s.cells_per_pixel, "Solver resolution at which the k target is met")->capture_default_str();
  cmd->add_option("--ladder", s.ladder, "Full-chip grid ladder, cells per pixel coarse to fine (must contain --cells-per-pixel)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--boundary", c->boundary, "Grain boundary of the solve: smooth or pixels (image-permeability's geometry.boundary)")
      ->check(CLI::IsMember({"smooth", "pixels"}))
      ->capture_default_str();
  cmd->add_option("--solve-on", c->solve_on, "Where k is confirmed and the ladder solved: chip, or tile (the tuning tile at the final scale, for chips too large to solve)")
      ->check(CLI::IsMember({"chip", "tile"}))
      ->capture_default_str();
  cmd->add_option("--seed", s.seed, "Random seed (same seed and options: the same chip.png, byte for byte)")->capture_default_str();
  cmd->add_flag("--quiet", c->quiet, "No progress lines on stderr");
  cmd->callback([c, pixel, older_pixel] {
    if (pixel->count() > 0 && older_pixel->count() > 0) throw CLI::ExcludesError("--pixel-size-um", "--pixel-um");
    if (older_pixel->count() > 0) std::fprintf(stderr, "mmval: note: --pixel-um is an older spelling; use --pixel-size-um\n");
    c->spec.smooth_boundary = c->boundary == "smooth";
    c->spec.solve_on_tile = c->solve_on == "tile";
    c->spec.fit_depth = c->depth == "fit";
    if (!c->spec.fit_depth) {
      std::size_t used = 0;
      try {
        c->spec.depth_um = std::stod(c->depth, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used == 0 || used != c->depth.size())
        throw InputError(InputLocation{"", 0, 0, "--depth-um"}, "not a depth", c->depth, "a channel depth in um (> 0) or 'fit'");
    }
    simulate::validateChipSpec(c->spec);  // before the folder is touched
    StagedDirectory staged(c->out);
    const bool quiet = c->quiet;
    const auto r = simulate::generateChip(c->spec, [quiet](const std::string& line) {
      if (!quiet && simulate::PetscSession::rank() == 0) std::fprintf(stderr, "%s\n", line.c_str());
    });
    simulate::writeChipOutputs(r, staged.path());
    staged.commit();
    printSummary(r, c->out);
  });
}

}  // namespace mmval::app
