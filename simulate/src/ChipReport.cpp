// Statistics and output files of a generated chip (see ChipGenerator.hpp, docs/chip-generator.md).
#include <algorithm>
#include <cmath>
#include <fstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/JsonNumbers.hpp"
#include "mmval/simulate/ChipGenerator.hpp"

namespace mmval::simulate {

namespace {

constexpr int kHistogramBins = 20;
/// The picture is downscaled to at most this many columns (a viewer's scale; chip.png keeps every pixel).
constexpr int kPictureMaxCols = 4000;
/// Throats narrower than this multiple of the minimum gap are marked on the picture.
constexpr double kMarkedThroatFactor = 1.5;

nlohmann::json histogram(const std::vector<double>& v) {
  const double hi = v.empty() ? 1.0 : *std::max_element(v.begin(), v.end()) * (1 + 1e-9);
  std::vector<double> edges(kHistogramBins + 1);
  std::vector<int> counts(kHistogramBins, 0);
  for (int i = 0; i <= kHistogramBins; ++i) edges[i] = hi * i / kHistogramBins;
  for (const double x : v) counts[std::min(kHistogramBins - 1, static_cast<int>(x / hi * kHistogramBins))]++;
  return {{"edges_um", edges}, {"counts", counts}};
}

struct Moments {
  double mean = 0, cv = 0, min = 0, median = 0;
};
Moments moments(std::vector<double> v) {
  Moments m;
  if (v.empty()) return m;
  double s = 0, s2 = 0;
  for (const double x : v) s += x, s2 += x * x;
  const double n = static_cast<double>(v.size());
  m.mean = s / n;
  m.cv = m.mean > 0 ? std::sqrt(std::max(0.0, s2 / n - m.mean * m.mean)) / m.mean : 0;
  std::sort(v.begin(), v.end());
  m.min = v.front();
  m.median = v[v.size() / 2];
  return m;
}

/// The 10th, 25th, 75th and 90th percentiles (nearest rank) of `v`: the spread of a skewed distribution, with its mean and median.
nlohmann::json quantiles(std::vector<double> v) {
  if (v.empty()) return nullptr;
  std::sort(v.begin(), v.end());
  nlohmann::json q = nlohmann::json::object();
  for (const auto& [name, p] : {std::pair{"p10", 0.10}, std::pair{"p25", 0.25}, std::pair{"p75", 0.75}, std::pair{"p90", 0.90}})
    q[name] = v[std::min(v.size() - 1, static_cast<std::size_t>(p * static_cast<double>(v.size())))];
  return q;
}

nlohmann::json ladderJson(const ChipLadder& l) {
  nlohmann::json runs = nlohmann::json::array();
  for (std::size_t i = 0; i < l.runs.size(); ++i)
    runs.push_back({{"cells_per_pixel", l.cells_per_pixel[i]},
                    {"cells_xy", {l.runs[i].nx, l.runs[i].ny}},
                    {"permeability_D", l.runs[i].permeability_m2 / kDarcyM2},
                    {"wall_seconds", l.runs[i].seconds}});
  const GridConvergence& g = l.convergence;
  return {{"runs", runs},
          {"status", g.status},
          {"note", g.note},
          {"observed_order", finiteOrNull(g.observed_order)},
          {"extrapolated_D", finiteOrNull(g.extrapolated)},
          {"gci", finiteOrNull(g.gci)},
          {"band_D", {finiteOrNull(g.band_lo), finiteOrNull(g.band_hi)}},
          {"method", "Celik et al. 2008 (J. Fluids Eng. 130, 078001): observed order from the three finest levels, Richardson extrapolation, GCI"}};
}

std::vector<double> grainDiametersUm(const ChipResult& r) {
  std::vector<double> d;
  for (const auto& c : r.packing.discs) d.push_back(2 * c.r * r.spec.pixel_um);
  return d;
}

std::vector<ChipThroat> throatsOf(const ChipResult& r) {
  return chipThroats(r.packing.discs, static_cast<int>(r.packing.solid.rows()), r.spec.wall_px, r.mean_grain_um / r.spec.pixel_um);
}

nlohmann::json target(double want, double tol, double got, bool relative) {
  nlohmann::json j = {{"achieved", got}};
  if (want > 0) {
    j["target"] = want;
    j["tolerance"] = tol;
    j["tolerance_kind"] = relative ? "relative" : "absolute";
    j["met"] = relative ? std::abs(got / want - 1) <= tol : std::abs(got - want) <= tol;
  } else {
    j["target"] = nullptr;
  }
  return j;
}

void writeHistogramCsv(const nlohmann::json& h, const std::string& quantity, const std::filesystem::path& file) {
  std::ofstream f(file);
  f << quantity << "_lo_um," << quantity << "_hi_um,count\n";
  for (std::size_t i = 0; i < h["counts"].size(); ++i)
    f << fmt::format("{:.6g},{:.6g},{}\n", h["edges_um"][i].get<double>(), h["edges_um"][i + 1].get<double>(), h["counts"][i].get<int>());
  if (!f) throw std::runtime_error("cannot write " + file.string());
}

/// The chip's own windows against the tile at the ladder's coarsest level: mean, SD, and whether
/// the mean is within the k tolerance of the tile (else the chip's k is not the tile's).
nlohmann::json tileSamplesJson(const ChipResult& r) {
  const double tile_k = r.ladder_da.runs.front().permeability_m2 / kDarcyM2;
  nlohmann::json samples = nlohmann::json::array();
  std::vector<double> ks;
  for (const auto& t : r.tile_samples) {
    nlohmann::json e = {{"col", t.col}, {"row", t.row}, {"porosity", t.porosity}};
    e["k_D"] = finiteOrNull(t.k_D);
    if (!t.error.empty()) e["error"] = t.error;
    if (std::isfinite(t.k_D)) ks.push_back(t.k_D);
    samples.push_back(e);
  }
  nlohmann::json j = {{"cells_per_pixel", r.spec.ladder.front()}, {"tile_k_D", tile_k}, {"windows", samples},
                      {"method", "tile-sized windows of the chip itself at 1/4 and 3/4 of its free range in x and y, framed as the tile is "
                                 "(grain-free inlet and outlet columns, solid wall rows), depth-averaged, at the ladder's coarsest level, "
                                 "against the tuned tile at that level"}};
  if (ks.empty()) {
    j["representative"] = false;
    return j;
  }
  double mean = 0, sd = 0;
  for (const double k : ks) mean += k / static_cast<double>(ks.size());
  for (const double k : ks) sd += (k - mean) * (k - mean) / static_cast<double>(std::max<std::size_t>(ks.size() - 1, 1));
  sd = std::sqrt(sd);
  j["mean_D"] = mean;
  j["sd_D"] = sd;
  j["mean_over_tile"] = mean / tile_k;
  j["representative"] = std::abs(mean / tile_k - 1) <= r.spec.permeability_tolerance;
  return j;
}

/// permeability_model "3d": every 3D measurement, and the k that met the target.
nlohmann::json model3DJson(const ChipResult& r) {
  const ChipSpec& s = r.spec;
  nlohmann::json steps = nlohmann::json::array();
  for (const auto& st : r.model_3d) {
    nlohmann::json levels = nlohmann::json::array();
    for (std::size_t i = 0; i < st.run_3d.permeability_m2.size(); ++i)
      levels.push_back({{"cells_z", st.run_3d.cells_z[i]}, {"cells", st.run_3d.cells[i]}, {"iterations", st.run_3d.iterations[i]},
                        {"permeability_D", st.run_3d.permeability_m2[i] / kDarcyM2}});
    steps.push_back({{"where", st.where}, {"mean_grain_um", st.mean_grain_um}, {"depth_averaged_target_D", st.da_target_D},
                     {"k_depth_averaged_D", st.k_da_D}, {"k_depth_averaged_pixels_D", st.k_da_pixels_D},
                     {"cells_xy_3d", {st.run_3d.nx, st.run_3d.ny}}, {"levels_3d", levels},
                     {"k_3d_extrapolated_dz_D", st.run_3d.extrapolated_m2 / kDarcyM2}, {"ratio", st.ratio}, {"k_3d_D", st.k_3d_D},
                     {"seconds", st.seconds}, {"seconds_3d", st.run_3d.seconds}});
  }
  nlohmann::json j = {{"steps", steps},
                      {"cells_per_pixel_3d", s.cells_per_pixel_3d},
                      {"cells_z_levels", s.cells_z},
                      {"extrapolation", s.cells_z.size() >= 2 ? "Richardson in dz over the two finest cells_z levels, order 2 (the plate closure's, "
                                                                "exact for plane Poiseuille: Stokes3D.hpp)"
                                                              : "none (one cells_z level)"},
                      {"method", "ratio = k_3d / k_depth_averaged_pixels, both on the pixel staircase at cells_per_pixel_3d (image-permeability's "
                                 "3d and depth-averaged models with geometry.boundary = pixels); k_3d = ratio x the depth-averaged k at "
                                 "cells_per_pixel (the generator's boundary). The ratio is the depth model's error and moves little with the "
                                 "in-plane grid (docs/validation/depth-model.md), while each k moves with it. While k_3d misses the target the "
                                 "grain scale is re-tuned to the depth-averaged target = target / ratio and k_3d measured again"}};
  if (r.model_3d.empty()) return j;
  const ChipModel3DStep& last = r.model_3d.back();
  j["ratio"] = last.ratio;
  j["k_3d_D"] = last.ratio * r.k_target_level_D;
  if (const double x = r.ladder_da.convergence.extrapolated; r.ladder_da.convergence.has_order && std::isfinite(x)) j["k_3d_extrapolated_D"] = last.ratio * x;
  return j;
}

/// Porosity of non-overlapping windows of ~10 mean grain diameters over the chip's grain region,
/// against the SD the same grains would give placed independently (ChipPacking.hpp).
nlohmann::json homogeneityJson(const ChipResult& r) {
  const ChipWindowPorosity& w = r.packing.homogeneity;
  nlohmann::json j = {{"window_um", w.side_px * r.spec.pixel_um}, {"window_px", w.side_px}, {"window_mean_grains", kHomogeneityWindowDiameters},
                      {"count", w.count},
                      {"definition", "porosity (pore pixels / window pixels) of non-overlapping square windows tiling the region between the "
                                     "inlet and outlet columns and the wall rows, centred in it"}};
  if (w.count == 0) return j;
  j["porosity"] = {{"mean", w.mean}, {"sd", w.sd}, {"min", w.min}, {"max", w.max}};
  j["poisson_sd"] = w.poisson_sd;
  j["sd_over_poisson"] = w.count > 1 && w.poisson_sd > 0 ? nlohmann::json(w.sd / w.poisson_sd) : nlohmann::json(nullptr);
  if (w.count < 2) j["porosity"]["sd"] = nullptr;
  j["poisson_definition"] = "SD if the same grains were placed independently: sqrt(p (1 - p) sum (pi r^2)^2) / window area, p = window / region "
                            "area (binomial; cut grains and overlaps neglected)";
  return j;
}

}  // namespace

nlohmann::json chipStatistics(const ChipResult& r) {
  const ChipSpec& s = r.spec;
  const PoreSpaceReport pores = analysePoreSpace(r.packing.solid);
  const Moments g = moments(grainDiametersUm(r));
  std::vector<double> tw;
  const std::vector<ChipThroat> throats = throatsOf(r);
  for (const auto& t : throats) tw.push_back(t.width_px * s.pixel_um);
  const Moments t = moments(tw);
  // The same throats as rendered: the grains' pixel squares, which the solvers and particles see.
  std::vector<double> tr;
  int rendered_under = 0;
  for (const double w : renderedThroatWidths(throats, r.packing.labels, s.wall_px))
    if (std::isfinite(w)) {
      tr.push_back(w * s.pixel_um);
      if (w < s.min_throat_px - 1e-9) ++rendered_under;
    }
  const Moments tm = moments(tr);
  nlohmann::json j;
  j["schema"] = "mmval chip statistics 1";
  j["seed"] = s.seed;
  j["image"] = {{"file", "chip.png"}, {"cols", r.packing.solid.cols()}, {"rows", r.packing.solid.rows()}, {"pixel_um", s.pixel_um},
                {"grains", "dark"}, {"wall_px", s.wall_px}, {"port_um", s.port_um > 0 ? s.port_um : r.mean_grain_um}};
  if (s.wall_px == 0)
    j["image"]["sides"] = "mirror planes (no wall rows): grains at least half the minimum gap from the top and bottom edges; flow solves slip there";
  j["targets"] = {{"length_mm", s.length_mm},
                  {"width_mm", s.width_mm},
                  {"depth_um", s.fit_depth ? nlohmann::json("fit") : nlohmann::json(s.depth_um)},
                  {"porosity", target(s.porosity, s.porosity_tolerance, pores.porosity_connected, false)},
                  {"permeability_model", s.permeability_model},
                  {"permeability_depth_averaged_D", target(r.da_target_D, s.permeability_tolerance, r.k_target_level_D, true)},
                  {"permeability_at_cells_per_pixel", s.cells_per_pixel},
                  {"mean_throat_um", target(s.mean_throat_um, s.permeability_D > 0 && !s.fit_depth ? 0.0 : kChipThroatTolerance, t.mean, true)},
                  {"mean_grain_um", target(s.permeability_D > 0 || s.mean_throat_um > 0 ? 0.0 : s.mean_grain_um, 0.05, g.mean, true)},
                  {"grain_cv", target(s.grain_cv, 0.05, g.cv, false)}};
  if (s.permeability_model == kChipModel3D && !r.model_3d.empty()) {
    j["targets"]["permeability_3d_D"] = target(s.permeability_D, s.permeability_tolerance, r.model_3d.back().ratio * r.k_target_level_D, true);
    j["targets"]["permeability_depth_averaged_D"]["note"] = "the depth-averaged k the grain scale was tuned to: the k target over the 3D model's ratio";
  }
  j["targets"]["permeability_met_by"] = s.permeability_D > 0 && !s.fit_depth ? nlohmann::json(s.permeability_model) : nlohmann::json(nullptr);
  if (s.permeability_D > 0 && s.mean_throat_um > 0 && !s.fit_depth)
    j["targets"]["mean_throat_um"]["note"] = "not tuned: at fixed porosity and grain-size distribution the grain scale that sets k also sets the throats";
  j["porosity"] = {{"total", pores.porosity_total}, {"connected", pores.porosity_connected}, {"components", pores.components},
                   {"spanning_components", pores.spanning_components},
                   {"definition", "pore pixels / all pixels, walls included; connected: isolated pores closed (image-permeability's rule)"}};
  const double gci = r.ladder_da.convergence.gci;
  j["permeability"] = {{"2d", ladderJson(r.ladder_2d)},
                       {"depth_averaged", ladderJson(r.ladder_da)},
                       {"depth_um", s.depth_um},
                       {"solved_on", {{"what", r.spec.solve_on_tile && (r.solved_cols != r.packing.solid.cols() || r.solved_rows != r.packing.solid.rows())
                                                  ? "tile (same generator and scale, its own packing)" : "chip"},
                                        {"cols", r.solved_cols}, {"rows", r.solved_rows}}},
                       {"converged", r.ladder_da.convergence.has_order && std::isfinite(gci) && gci <= s.permeability_tolerance},
                       {"converged_rule", "depth-averaged ladder monotone with an observed order and GCI of the finest level within the k tolerance"},
                       {"boundary", s.smooth_boundary ? "smooth (image-permeability geometry.boundary = smooth, smoothing 0.75 px)" : "pixels"}};
  if (!r.tile_samples.empty()) j["permeability"]["tile_samples"] = tileSamplesJson(r);
  if (s.permeability_model == kChipModel3D) j["permeability"]["model_3d"] = model3DJson(r);
  if (s.fit_depth) {
    nlohmann::json steps = nlohmann::json::array();
    for (const auto& st : r.depth_fit) steps.push_back({{"where", st.where}, {"depth_um", st.depth_um}, {"k_D", st.k_D}, {"seconds", st.seconds}});
    j["depth_fit"] = {{"depth_um", s.depth_um},
                      {"steps", steps},
                      {"searched_um", {kFitDepthMinUm, kFitDepthMaxUm}},
                      {"k_plane_2d_tile_D", r.k_plane_2d_tile_D},
                      {"method", "secant on ln k against ln h (k ~ h^2 to start), each step a depth-averaged solve at the target's cells per pixel on "
                                 "the tuning tile at the final grain scale, then on the chip when the ladder solves the chip"},
                      {"why", "the depth was fitted (--depth-um fit) because the source states porosity, permeability and mean throat size but no "
                              "depth: the throat target sets the grain scale, and the depth-averaged k (Hele-Shaw friction 12 mu u / h^2) then "
                              "depends on h alone"}};
  }
  j["homogeneity"] = homogeneityJson(r);
  j["grains"] = {{"count", r.packing.discs.size()}, {"mean_diameter_um", g.mean}, {"cv", g.cv}, {"min_diameter_um", g.min},
                 {"median_diameter_um", g.median}, {"histogram", histogram(grainDiametersUm(r))},
                 {"distribution", fmt::format("lognormal, clipped to [{:g}, {:g}] x the mean", kMinDiameterFactor, kMaxDiameterFactor)}};
  j["throats"] = {{"count", tw.size()}, {"mean_width_um", t.mean}, {"mean_radius_um", 0.5 * t.mean}, {"min_width_um", t.min},
                  {"median_width_um", t.median}, {"quantiles_width_um", quantiles(tw)}, {"histogram", histogram(tw)},
                  {"definition", std::string("gap between two neighbouring grains (or a grain and a wall) along their line of centres, counted when its midpoint "
                                 "is nearer to those two than to any other solid (a saddle of the distance map on the medial axis); widths up to "
                                 "one mean grain diameter; from the disc geometry, not the pixels") +
                                     (s.wall_px == 0 ? "; mirror sides: the grains' mirror images across the edges are solids too, so a "
                                                       "throat between a grain and an edge is twice its distance to it"
                                                     : "")}};
  j["throats_rendered"] = {{"count", tr.size()}, {"mean_width_um", tm.mean}, {"min_width_um", tm.min}, {"median_width_um", tm.median},
                           {"quantiles_width_um", quantiles(tr)}, {"min_gap_um", s.min_throat_px * s.pixel_um},
                           {"under_min_gap", rendered_under},
                           {"grain_pairs_under_min_gap", renderedGapViolations(r.packing.labels, s.wall_px, s.min_throat_px)},
                           {"cleared_px", r.packing.cleared_px}, {"grow_px", r.packing.render_grow_px},
                           {"definition", std::string("the throats of `throats` as rendered in chip.png: the smallest distance between the pixel squares of "
                                                      "the two grains (or from the grain's squares to the wall rows); under_min_gap counts them below "
                                                      "--min-throat-px, grain_pairs_under_min_gap every pair of grains (or grain and wall) whose squares "
                                                      "are closer than that, throats or not; cleared_px: grain pixels the rendering cleared to keep the "
                                                      "gap, grow_px: the growth of every disc in the rendering that gives their area back "
                                                      "(docs/chip-generator.md)") +
                                              (s.wall_px == 0 ? "; mirror sides: to the grains' mirror images, so to an edge twice the distance" : "")}};
  if (const Throat n = narrowestThroat(pores.solid_connected, s.pixel_um * 1e-6, false, false, 0, 0, s.wall_px == 0); n.path && std::isfinite(n.width_m))
    j["narrowest_spanning_throat"] = {{"width_um", n.width_m * 1e6}, {"x_px", std::floor(n.x_m / (s.pixel_um * 1e-6))},
                                      {"y_px", std::floor(r.packing.solid.rows() - n.y_m / (s.pixel_um * 1e-6))},
                                      {"definition", std::string("narrowest cross-section of the widest inlet-to-outlet path of the mask (PoreSpace.hpp)") +
                                                         (s.wall_px == 0 ? "; mirror sides: a cross-section to an edge reaches the grain's image, twice its distance" : "")}};
  nlohmann::json tuning = nlohmann::json::array();
  for (const auto& st : r.tuning)
    tuning.push_back({{"where", st.where}, {"mean_grain_um", st.mean_grain_um}, {"value", st.value}, {"target", st.target}, {"seconds", st.seconds}});
  j["tuning"] = tuning;
  j["tuning_quantity"] = s.permeability_D > 0 && !s.fit_depth ? "depth-averaged k (D; with the 3d model its target is the k target over the 3D ratio)" : s.mean_throat_um > 0 ? "mean throat width (um)" : "none";
  j["generation"] = {{"mean_grain_um", r.mean_grain_um}, {"min_throat_px", s.min_throat_px}, {"relax_sweeps", r.packing.relax_sweeps},
                     {"porosity_rounds", r.packing.porosity_rounds}, {"tile_mm", s.tile_mm}, {"wall_seconds", r.seconds},
                     {"placement", "random sequential addition with the minimum gap, largest grain first; grains that find no room (and all "
                                   "after 50 such in a row) on a jittered grid; then overlap removal (ChipPacking.hpp)"},
                     {"sequentially_added", r.packing.sequentially_added}};
  return j;
}

void writeChipOutputs(const ChipResult& r, const std::filesystem::path& dir) {
  const BoolArray& solid = r.packing.solid;
  cv::Mat mask(static_cast<int>(solid.rows()), static_cast<int>(solid.cols()), CV_8UC1);
  for (int j = 0; j < mask.rows; ++j)
    for (int i = 0; i < mask.cols; ++i) mask.at<std::uint8_t>(j, i) = solid(j, i) ? 0 : 255;
  if (!cv::imwrite((dir / "chip.png").string(), mask)) throw std::runtime_error("cannot write " + (dir / "chip.png").string());
  // Picture: grains grey, pores white, narrow throats red, the spanning path's narrowest circled blue.
  cv::Mat pic;
  cv::cvtColor(mask, pic, cv::COLOR_GRAY2BGR);
  pic.setTo(cv::Scalar(110, 110, 110), mask == 0);
  // Throats wider than the minimum gap by kMarkedThroatFactor or less are most of them (the
  // relaxation leaves neighbours at the gap, as grains of a sand pack touch): one red pixel each.
  const double mark = kMarkedThroatFactor * r.spec.min_throat_px;
  const int radius = std::max(2, static_cast<int>(std::lround(r.spec.min_throat_px)));
  // The pixel under the midpoint; with mirror sides a throat to a grain's own image has its
  // midpoint on the edge itself (y = rows at the bottom), drawn in the edge row.
  for (const auto& t : throatsOf(r))
    if (t.width_px <= mark)
      pic.at<cv::Vec3b>(std::clamp(static_cast<int>(t.y), 0, pic.rows - 1), std::clamp(static_cast<int>(t.x), 0, pic.cols - 1)) = cv::Vec3b(0, 0, 230);
  if (r.stats.contains("narrowest_spanning_throat")) {
    const auto& n = r.stats["narrowest_spanning_throat"];
    cv::circle(pic, cv::Point(n["x_px"].get<int>(), n["y_px"].get<int>()), 4 * radius, cv::Scalar(230, 80, 0), std::max(1, radius / 2));
  }
  if (pic.cols > kPictureMaxCols) {
    const double f = static_cast<double>(kPictureMaxCols) / pic.cols;
    cv::resize(pic, pic, cv::Size(), f, f, cv::INTER_AREA);
  }
  if (!cv::imwrite((dir / "chip-picture.png").string(), pic)) throw std::runtime_error("cannot write chip-picture.png");
  writeHistogramCsv(r.stats["grains"]["histogram"], "diameter", dir / "grain-sizes.csv");
  writeHistogramCsv(r.stats["throats"]["histogram"], "width", dir / "throat-sizes.csv");
  std::ofstream f(dir / "chip.json");
  f << r.stats.dump(2) << "\n";
  if (!f) throw std::runtime_error("cannot write chip.json");
}

}  // namespace mmval::simulate
