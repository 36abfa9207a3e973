#include "mmval/compare/Kinds.hpp"

#include <exception>
#include <filesystem>
#include <fstream>
#include <string>

#include <nlohmann/json.hpp>

#include "mmval/compare/Compare.hpp"
#include "mmval/compare/ForeignTracks.hpp"
#include "mmval/compare/KindMetrics.hpp"
#include "mmval/compare/Scene.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/core/Units.hpp"

namespace mmval::compare {

namespace {

/// The rest rule (labelRests) of a compare-tracks case: its analysis.rest_window and
/// rest_distance where given; otherwise the tracker's analysis.stuck_window and stuck_distance
/// as the run named by inputs.experiment_run resolved them (its result.json), so both files are
/// judged by the rule the tracker labelled its own rests with; otherwise the tracker's defaults.
/// Returns where the values came from.
std::string restRule(const Case& c, const RunContext& ctx, RestRule& rule) {
  std::string source = "the tracker's defaults (analysis.stuck_window, stuck_distance)";
  if (c.has("inputs.experiment_run") && !c.has("inputs.experiment")) {
    const std::filesystem::path f = ctx.out_dir.parent_path() / c.text("inputs.experiment_run") / "result.json";
    try {
      std::ifstream in(f);
      const nlohmann::json r = nlohmann::json::parse(in);
      const auto& a = r.at("resolved_case").at("analysis");
      const double window = parseQuantity(a.at("stuck_window").get<std::string>()).si;
      const double distance = parseQuantity(a.at("stuck_distance").get<std::string>()).si;
      rule.window = window;
      rule.distance = distance;
      source = "analysis.stuck_window and stuck_distance of run " + c.text("inputs.experiment_run");
    } catch (const std::exception&) {
      // Not a tracking run, or no result.json: the defaults stand.
    }
  }
  const bool w = c.has("analysis.rest_window"), d = c.has("analysis.rest_distance");
  if (w) rule.window = c.quantity("analysis.rest_window");
  if (d) rule.distance = c.quantity("analysis.rest_distance");
  if (w && d) return "analysis.rest_window and rest_distance";
  if (w || d) return std::string(w ? "analysis.rest_window" : "analysis.rest_distance") + "; the other from " + source;
  return source;
}

}  // namespace

void registerCompareKinds(CaseKindRegistry& registry) {
  CaseKind k;
  k.name = "compare-tracks";
  k.summary = "Experiment tracks against simulated trajectories: speeds, dispersion, retention, streamline overlap";
  k.declare = [](Schema& s) {
    s.path("inputs.experiment", "Tracks CSV of the experiment (shared tracks schema)").optional();
    s.path("inputs.simulation", "Trajectories CSV of the simulation (shared tracks schema)").optional();
    s.string("inputs.experiment_run", "Instead of inputs.experiment: a case run earlier in the same validation; its tracks.csv").optional();
    s.string("inputs.simulation_run", "Instead of inputs.simulation: a case run earlier in the same validation; its trajectories.csv").optional();
    s.quantity("inputs.pixel_size", "um", "Pixel size, for files with positions in pixels only").def(0.0).nonNegative();
    s.choice("inputs.experiment_format", {"auto", "mmval", "trackpy", "trackmate"},
             "Who wrote inputs.experiment: mmval, trackpy (a linked DataFrame saved with to_csv; needs inputs.fps and inputs.pixel_size), "
             "trackmate (its Spots table as CSV), or auto (from the header)")
        .def("auto");
    s.choice("inputs.simulation_format", {"auto", "mmval", "trackpy", "trackmate"}, "Who wrote inputs.simulation (as inputs.experiment_format)").def("auto");
    s.quantity("inputs.fps", "Hz", "Frame rate, for files that store frame numbers rather than times (trackpy; TrackMate without time units); 0: none")
        .def(0.0)
        .nonNegative();
    declareMask(s, {.mask_doc = "Geometry mask image the simulation was built from (enables registration and per-region speeds)", .optional = true});
    s.integerList("geometry.crop", "Window of the mask the simulation used, [x, y, width, height] in px (the simulation's coordinates start at its corner)").optional();
    s.boolean("geometry.y_up", "Simulation y runs up the image, origin at its lower-left corner (as mmval's solver reads masks); false: y down from the upper-left corner").def(true);
    s.path("registration.frame", "First video frame or the tracker's background image, registered to the mask with OpenCV ECC (rigid motion)").optional();
    s.quantity("registration.frame_pixel_size", "um", "Camera pixel size; default: from the experiment tracks (x_um / x), else the mask's").optional().positive();
    s.quantity("registration.min_correlation", "1", "Smallest ECC correlation accepted as a registration").def(0.6).fraction();
    s.quantity("window.origin_x", "um", "Imaged window given directly: x of the frame's pixel (0, 0) in the simulation frame").optional();
    s.quantity("window.origin_y", "um", "Imaged window given directly: y of the frame's pixel (0, 0) in the simulation frame").optional();
    s.quantity("window.rotation", "deg", "Imaged window's rotation, counter-clockwise").def(0.0);
    s.quantity("window.pixel_size", "um", "Imaged window's camera pixel size").optional().positive();
    s.quantity("regions.throat_width", "um", "Pore width at or below which pore space is throat; 0: the median inscribed diameter along the medial axis").def(0.0).nonNegative();
    s.quantity("analysis.immobile_distance", "um", "Particles that never get farther than this from their start are immobile and left out")
        .def("2 um").nonNegative();
    s.quantity("analysis.stuck_distance", "um", "A mobile particle that moves less than this over its final window is retained").def("1 um").nonNegative();
    s.quantity("analysis.stuck_window", "s", "Length of that final window").def("2 s").positive();
    s.quantity("analysis.rest_window", "s",
               "Rest rule applied to both files before speeds and spreads: a point is at rest in a window this long over which the particle "
               "moves less than analysis.rest_distance (plus what its localisation noise explains); steps between resting points are left "
               "out on both sides, whatever the files label. Default: the tracker's analysis.stuck_window, read from the run named by "
               "inputs.experiment_run when its case records one, else the tracker's default (2 s); 0: off (each file's own deposited labels decide)")
        .optional()
        .nonNegative();
    s.quantity("analysis.rest_distance", "um",
               "Distance of that rest rule. Default: the tracker's analysis.stuck_distance, from inputs.experiment_run as rest_window, else 1 um")
        .optional()
        .nonNegative();
    s.quantity("analysis.occupancy_cell", "um", "Grid cell of the streamline occupancy maps").def("5 um").positive();
    s.integer("analysis.time_bins", "Bins of the time series").def(20).min(1).max(10000);
    s.quantity("tolerances.speed", "1", "Relative tolerance of mean and median speed").def(0.2).min(0, true);
    s.quantity("tolerances.dispersion", "1", "Relative tolerance of the time-averaged sigma_x, sigma_y").def(0.25).min(0, true);
    s.quantity("tolerances.retention", "1", "Absolute tolerance of the retained fraction").def(0.05).min(0, true);
    s.quantity("tolerances.streamline_iou", "1", "Smallest acceptable overlap of the occupancy maps").def(0.5).fraction();
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    CompareOptions o;
    o.tracks.immobile_distance = c.quantity("analysis.immobile_distance");
    o.tracks.stuck_distance = c.quantity("analysis.stuck_distance");
    o.tracks.stuck_window = c.quantity("analysis.stuck_window");
    o.tracks.time_bins = static_cast<int>(c.integer("analysis.time_bins"));
    const std::string rest_source = restRule(c, ctx, o.rest);
    o.occupancy_cell = c.quantity("analysis.occupancy_cell");
    o.speed_tolerance = c.quantity("tolerances.speed");
    o.dispersion_tolerance = c.quantity("tolerances.dispersion");
    o.retention_tolerance = c.quantity("tolerances.retention");
    o.iou_minimum = c.quantity("tolerances.streamline_iou");
    if (c.has("inputs.experiment_run")) o.reference_name = "tracks of run " + c.text("inputs.experiment_run");
    const double px = c.quantity("inputs.pixel_size");
    SceneSpec spec;
    if (c.has("geometry.mask")) {
      spec.mask = c.path("geometry.mask");
      if (!c.has("geometry.pixel_size"))
        throw InputError(c.where("geometry.mask"), "a geometry mask needs geometry.pixel_size", {}, "the size of one mask pixel, e.g. \"2 um\"");
      spec.mask_pixel_size = c.quantity("geometry.pixel_size");
    }
    spec.grains_dark = c.text("geometry.grains") == "dark";
    if (c.has("geometry.crop")) {
      const auto& r = c.integers("geometry.crop");
      if (r.size() != 4) throw InputError(c.where("geometry.crop"), "a crop has four integers", {}, "[x, y, width, height] in px");
      spec.crop = cv::Rect(static_cast<int>(r[0]), static_cast<int>(r[1]), static_cast<int>(r[2]), static_cast<int>(r[3]));
    }
    spec.y_up = c.flag("geometry.y_up");
    if (c.has("registration.frame")) spec.register_frame = c.path("registration.frame");
    if (c.has("registration.frame_pixel_size")) spec.frame_pixel_size = c.quantity("registration.frame_pixel_size");
    spec.registration.min_correlation = c.quantity("registration.min_correlation");
    const bool wx = c.has("window.origin_x"), wy = c.has("window.origin_y"), ws = c.has("window.pixel_size");
    if (wx || wy || ws) {
      if (!(wx && wy && ws))
        throw InputError(c.where(wx ? "window.origin_x" : (wy ? "window.origin_y" : "window.pixel_size")), "the imaged window needs origin_x, origin_y and pixel_size together",
                         {}, "all three keys of [window] (rotation defaults to 0 deg)");
      spec.window = SceneSpec::Window{c.quantity("window.origin_x"), c.quantity("window.origin_y"), c.quantity("window.rotation"), c.quantity("window.pixel_size")};
    }
    spec.region_options.throat_width = c.quantity("regions.throat_width");
    TrackImport opts;
    opts.pixel_size = px;
    opts.fps = c.quantity("inputs.fps");
    opts.format = parseTrackFormat(c.text("inputs.experiment_format"));
    const ImportedTracks exp = readTracksAnyFormat(fileOrRunFile(c, ctx, "inputs.experiment", "tracks.csv"), opts);
    opts.format = parseTrackFormat(c.text("inputs.simulation_format"));
    const ImportedTracks sim = readTracksAnyFormat(fileOrRunFile(c, ctx, "inputs.simulation", "trajectories.csv"), opts);
    const Comparison cmp = compareScene(exp.tracks, sim.tracks, spec, o);
    RunOutput out;
    out.files = writeComparison(cmp, ctx.out_dir);
    // A metric the comparison only reports (speed_wasserstein1, the KS statistics) is judged by
    // the case's own [[acceptance]] on it when there is one: its value goes through out.metrics,
    // where the run applies the entry (core/Run.cpp evaluateMetrics), and not also as an info row.
    for (const auto& m : cmp.metrics) {
      if (!m.pass.has_value() && c.acceptanceFor(m.name) != nullptr) {
        out.metrics[m.name] = m.value * parseUnit(m.unit).to_si;
        out.units[m.name] = m.unit;
      } else {
        out.evaluated.push_back(m);
      }
    }
    out.details = cmp.toJson();
    out.details.erase("metrics");
    out.details["rest_rule"]["source"] = rest_source;
    out.details["inputs"] = {{"experiment_format", trackFormatName(exp.format)}, {"experiment_note", exp.note},
                             {"simulation_format", trackFormatName(sim.format)}, {"simulation_note", sim.note}};
    return out;
  };
  registry.add(k);
  declareCompareMetrics(registry);
}

}  // namespace mmval::compare
