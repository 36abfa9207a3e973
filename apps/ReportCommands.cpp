#include "ReportCommands.hpp"

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "mmval/compare/Compare.hpp"
#include "mmval/compare/ForeignTracks.hpp"
#include "mmval/compare/Scene.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Strings.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/reports/Report.hpp"

namespace fs = std::filesystem;

namespace mmval::app {

namespace {

struct CompareCli {
  std::string experiment, simulation, out;
  double pixel_size_um = 0;
  std::string experiment_format = "auto", simulation_format = "auto";
  double fps = 0;
  double immobile_um = 2, stuck_um = 1, stuck_window_s = 2, cell_um = 5;
  int time_bins = 20;
  std::string mask, register_frame, grains = "dark";
  double mask_pixel_size_um = 0, frame_pixel_size_um = 0, min_correlation = 0.6, throat_width_um = 0;
  bool y_up = true;
  bool y_down_older_flag = false;  ///< --mask-y-down, the older spelling of --y-up false
  std::vector<double> window_origin_um;
  double window_rotation_deg = 0, window_pixel_size_um = 0;
  /// The one rest rule for both files (compare::RestRule); defaults: the tracker's own.
  double rest_window_s = compare::RestRule{}.window, rest_um = compare::RestRule{}.distance / 1e-6;
};

struct ReportCli {
  std::vector<std::string> dirs;
  std::string out = "out/report";
  std::vector<std::string> diff;
};

/// Degrees to radians for the window rotation given on the command line.
constexpr double kRadiansPerDegree = 3.14159265358979323846 / 180;
constexpr double kMetresPerMicrometre = 1e-6;

compare::CompareOptions compareOptionsOf(const CompareCli& c) {
  compare::CompareOptions o;
  o.tracks.immobile_distance = c.immobile_um * kMetresPerMicrometre;
  o.tracks.stuck_distance = c.stuck_um * kMetresPerMicrometre;
  o.tracks.stuck_window = c.stuck_window_s;
  o.tracks.time_bins = c.time_bins;
  o.occupancy_cell = c.cell_um * kMetresPerMicrometre;
  o.rest.window = c.rest_window_s;
  o.rest.distance = c.rest_um * kMetresPerMicrometre;
  return o;
}

compare::SceneSpec sceneSpecOf(const CompareCli& c) {
  compare::SceneSpec spec;
  spec.mask = c.mask;
  spec.mask_pixel_size = c.mask_pixel_size_um * kMetresPerMicrometre;
  spec.grains_dark = c.grains == "dark";
  spec.y_up = c.y_up;
  spec.register_frame = c.register_frame;
  spec.frame_pixel_size = c.frame_pixel_size_um * kMetresPerMicrometre;
  spec.registration.min_correlation = c.min_correlation;
  spec.region_options.throat_width = c.throat_width_um * kMetresPerMicrometre;
  if (!c.window_origin_um.empty()) {
    if (!(c.window_pixel_size_um > 0))
      throw InputError({"(command line)", 0, 0, "--window-pixel-size-um"}, "the imaged window needs its pixel size", fmt::format("{:g}", c.window_pixel_size_um),
                       "a positive pixel size in um");
    spec.window = compare::SceneSpec::Window{c.window_origin_um[0] * kMetresPerMicrometre, c.window_origin_um[1] * kMetresPerMicrometre,
                                             c.window_rotation_deg * kRadiansPerDegree, c.window_pixel_size_um * kMetresPerMicrometre};
  }
  return spec;
}

/// A check that a number is above `bound` (strictly when `strict`), naming what was expected.
CLI::Validator numberAtLeast(double bound, bool strict, const std::string& unit) {
  return CLI::Validator(
      [=](const std::string& v) {
        double x = 0;
        const bool ok = CLI::detail::lexical_cast(v, x) && std::isfinite(x) && (strict ? x > bound : x >= bound);
        return ok ? std::string() : fmt::format("expected a {} number of {}, got {}", strict ? "positive" : "non-negative", unit, v);
      },
      strict ? "POSITIVE" : "NON-NEGATIVE");
}

/// One line on stderr for an option spelled the older way: it still works, and this says what to write instead.
void noteOlderSpelling(const std::string& given, const std::string& use) {
  std::fprintf(stderr, "mmval: note: %s is an older spelling; use %s\n", given.c_str(), use.c_str());
}

void printComparison(const compare::Comparison& result, const std::string& out) {
  for (const auto& m : result.metrics)
    std::printf("%-20s %12.5g %-6s %s\n", m.name.c_str(), m.value, m.unit.c_str(), m.pass.has_value() ? (*m.pass ? "pass" : "FAIL") : "info");
  if (result.alignment.contains("dx_px"))
    std::printf("registration: dx %.3f px, dy %.3f px, rotation %.4f deg, ECC correlation %.4f, RMS residual %.4f\n", result.alignment["dx_px"].get<double>(),
                result.alignment["dy_px"].get<double>(), result.alignment["rotation_deg"].get<double>(), result.alignment["ecc_correlation"].get<double>(),
                result.alignment["rms_residual"].get<double>());
  std::printf("rest rule: experiment %zu of %zu points at rest, simulation %zu of %zu\n", result.rest_experiment.at_rest, result.rest_experiment.points,
              result.rest_simulation.at_rest, result.rest_simulation.points);
  std::printf("compare: %s\n", (fs::path(out) / "metrics.json").string().c_str());
}

/// Exit status 3 (README) when a metric is outside its tolerance; called after
/// the outputs are written, so the user can see why.
void throwIfAnyMetricFailed(const compare::Comparison& result, const std::string& out) {
  const std::vector<std::string> failed = compare::failedMetrics(result);
  if (failed.empty()) return;
  throw MetricsFailed(fmt::format("compare: {} metric(s) outside tolerance: {} (outputs written to {})", failed.size(), join(failed, ", "), out));
}

void runCompare(const CompareCli& c) {
  compare::TrackImport opts;
  opts.pixel_size = c.pixel_size_um * kMetresPerMicrometre;
  opts.fps = c.fps;
  opts.format = compare::parseTrackFormat(c.experiment_format);
  const compare::ImportedTracks exp = compare::readTracksAnyFormat(c.experiment, opts);
  opts.format = compare::parseTrackFormat(c.simulation_format);
  const compare::ImportedTracks sim = compare::readTracksAnyFormat(c.simulation, opts);
  std::printf("experiment: %s (%s)\nsimulation: %s (%s)\n", c.experiment.c_str(), exp.note.c_str(), c.simulation.c_str(), sim.note.c_str());
  const Tracks& experiment = exp.tracks;
  const Tracks& simulation = sim.tracks;
  const compare::Comparison result = compare::compareScene(experiment, simulation, sceneSpecOf(c), compareOptionsOf(c));
  StagedDirectory staged(c.out);
  compare::writeComparison(result, staged.path());
  staged.commit();
  printComparison(result, c.out);
  throwIfAnyMetricFailed(result, c.out);
}

void runReport(const ReportCli& r) {
  if (!r.diff.empty()) {
    std::fputs(reports::diffMetricFiles(r.diff[0], r.diff[1]).c_str(), stdout);
    return;
  }
  if (r.dirs.empty()) throw CLI::RequiredError("dirs");
  const std::vector<fs::path> dirs(r.dirs.begin(), r.dirs.end());
  const reports::ReportInput input = reports::collect(dirs);
  // Staged like every output folder: a user's folder given as --out is refused, never overwritten.
  StagedDirectory staged(r.out);
  const int figures = reports::writeReport(input, staged.path());
  staged.commit();
  std::printf("report: %zu run(s), %zu comparison(s), %zu sweep(s), %d figure(s) -> %s\n", input.summary.results.size(), input.comparisons.size(),
              input.sweeps.size(), figures,
              (staged.finalPath() / "index.html").string().c_str());
}

}  // namespace

void registerReportCommands(CLI::App& app) {
  auto c = std::make_shared<CompareCli>();
  CLI::App* cmp = app.add_subcommand("compare", "Compare experiment tracks with simulated trajectories (shared tracks CSV schema)");
  cmp->add_option("--experiment", c->experiment, "Tracks CSV from `mmval track`")->required();
  cmp->add_option("--simulation", c->simulation, "Trajectories CSV from a simulation")->required();
  cmp->add_option("--out", c->out, "Output folder")->required();
  cmp->add_option("--pixel-size-um", c->pixel_size_um, "Pixel size when a file has positions in pixels only");
  const auto formats = CLI::IsMember({"auto", "mmval", "trackpy", "trackmate"});
  cmp->add_option("--experiment-format", c->experiment_format,
                  "Who wrote the experiment file: mmval (tracks.csv), trackpy (a linked DataFrame saved with to_csv; needs --fps and "
                  "--pixel-size-um), trackmate (its Spots table as CSV), or auto (from the header)")
      ->check(formats)
      ->capture_default_str();
  cmp->add_option("--simulation-format", c->simulation_format, "Who wrote the simulation file (as --experiment-format)")->check(formats)->capture_default_str();
  cmp->add_option("--fps", c->fps, "Frame rate, for files that store frame numbers rather than times (trackpy; TrackMate without time units)");
  cmp->add_option("--immobile-um", c->immobile_um, "Particles that never move farther than this are immobile (left out)")->capture_default_str();
  cmp->add_option("--stuck-um", c->stuck_um, "A particle moving less than this over its last window is retained")->capture_default_str();
  cmp->add_option("--stuck-window-s", c->stuck_window_s, "Length of that final window")->capture_default_str();
  cmp->add_option("--rest-window-s", c->rest_window_s,
                  "One rest rule for both files (speeds, W1, dispersion): a point is at rest when its particle stays within --rest-um for this "
                  "long, as the tracker labels rests (default: the tracker's analysis.stuck_window; 0 turns the rule off)")
      ->check(numberAtLeast(0.0, false, "seconds"))
      ->capture_default_str();
  cmp->add_option("--rest-um", c->rest_um, "Distance of that rest rule (default: the tracker's analysis.stuck_distance)")
      ->check(numberAtLeast(0.0, true, "um"))
      ->capture_default_str();
  cmp->add_option("--cell-um", c->cell_um, "Grid cell of the streamline occupancy maps")->capture_default_str();
  cmp->add_option("--time-bins", c->time_bins, "Bins of the time series")->capture_default_str();
  CLI::Option* mask = cmp->add_option("--mask", c->mask, "Geometry mask the simulation was built from: per-region speeds, and the target of --register-frame");
  CLI::Option* older_mask = cmp->add_option("--register-mask", c->mask)->group("");  // its older name, hidden from --help
  cmp->add_option("--mask-pixel-size-um", c->mask_pixel_size_um, "Size of one mask pixel");
  // The mask options speak the case's words (compare-tracks' geometry.grains and geometry.y_up, synth's
  // --grain-pixels); the older spellings stay accepted, hidden from --help, and say what replaces them.
  const CLI::Validator grain_choice(
      [](const std::string& v) { return v == "dark" || v == "bright" || v == "light" ? std::string() : "expected dark or bright, got " + v; }, "{dark,bright}");
  CLI::Option* grains =
      cmp->add_option("--grain-pixels", c->grains, "Which pixels of the mask are grains (as geometry.grains in a compare-tracks case)")->check(grain_choice)->capture_default_str();
  CLI::Option* older_grains = cmp->add_option("--mask-grains", c->grains)->check(grain_choice)->group("");
  CLI::Option* y_up = cmp->add_option("--y-up", c->y_up,
                                      "true: simulation y runs up the image from its lower-left corner, as mmval's solver reads masks; false: down from the "
                                      "upper-left corner (as geometry.y_up in a compare-tracks case)")
                          ->default_str("true");
  CLI::Option* older_y = cmp->add_flag("--mask-y-down", c->y_down_older_flag)->group("");
  cmp->add_option("--register-frame", c->register_frame, "First video frame or the tracker's background image: registered to the mask (OpenCV ECC) to put the experiment in the simulation frame");
  cmp->add_option("--frame-pixel-size-um", c->frame_pixel_size_um, "Camera pixel size (default: from the experiment tracks)");
  cmp->add_option("--min-correlation", c->min_correlation, "Smallest ECC correlation accepted")->capture_default_str();
  cmp->add_option("--window-origin-um", c->window_origin_um, "Imaged window given directly: X Y of the frame's pixel (0, 0) in the simulation frame")->expected(2);
  cmp->add_option("--window-rotation-deg", c->window_rotation_deg, "Imaged window's rotation, counter-clockwise")->capture_default_str();
  cmp->add_option("--window-pixel-size-um", c->window_pixel_size_um, "Imaged window's camera pixel size");
  cmp->add_option("--throat-width-um", c->throat_width_um, "Pore width at or below which pore space is throat (0: median inscribed diameter)")->capture_default_str();
  cmp->callback([c, mask, older_mask, grains, older_grains, y_up, older_y] {
    if (mask->count() > 0 && older_mask->count() > 0) throw CLI::ExcludesError("--mask", "--register-mask");
    if (grains->count() > 0 && older_grains->count() > 0) throw CLI::ExcludesError("--grain-pixels", "--mask-grains");
    if (y_up->count() > 0 && older_y->count() > 0) throw CLI::ExcludesError("--y-up", "--mask-y-down");
    if (older_grains->count() > 0 || c->grains == "light") {
      const std::string given = fmt::format("--{} {}", older_grains->count() > 0 ? "mask-grains" : "grain-pixels", c->grains);
      if (c->grains == "light") c->grains = "bright";
      noteOlderSpelling(given, "--grain-pixels " + c->grains);
    }
    if (older_mask->count() > 0) noteOlderSpelling("--register-mask " + c->mask, "--mask " + c->mask);
    if (older_y->count() > 0) {
      noteOlderSpelling("--mask-y-down", "--y-up false");
      c->y_up = !c->y_down_older_flag;
    }
    runCompare(*c);
  });

  auto r = std::make_shared<ReportCli>();
  CLI::App* rep = app.add_subcommand("report", "Build the HTML/Markdown report from run and compare folders, or diff two metrics.json");
  rep->add_option("dirs", r->dirs, "Folders written by run, compare or validate");
  rep->add_option("--out", r->out, "Report folder")->capture_default_str();
  rep->add_option("--diff", r->diff, "Two metrics.json files: list metrics that changed beyond tolerance")->expected(2);
  rep->callback([r] { runReport(*r); });
}

}  // namespace mmval::app
