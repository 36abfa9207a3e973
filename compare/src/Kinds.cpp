#include "mmval/compare/Kinds.hpp"

#include "mmval/compare/Compare.hpp"

namespace mmval::compare {

void registerCompareKinds(CaseKindRegistry& registry) {
  CaseKind k;
  k.name = "compare-tracks";
  k.summary = "Experiment tracks against simulated trajectories: speeds, dispersion, retention, streamline overlap";
  k.declare = [](Schema& s) {
    s.path("inputs.experiment", "Tracks CSV of the experiment (shared tracks schema)");
    s.path("inputs.simulation", "Trajectories CSV of the simulation (shared tracks schema)");
    s.quantity("inputs.pixel_size", "um", "Pixel size, for files with positions in pixels only").def(0.0).nonNegative();
    s.quantity("analysis.immobile_distance", "um", "Particles that never get farther than this from their start are immobile and left out")
        .def("2 um").nonNegative();
    s.quantity("analysis.stuck_distance", "um", "A mobile particle that moves less than this over its final window is retained").def("1 um").nonNegative();
    s.quantity("analysis.stuck_window", "s", "Length of that final window").def("2 s").positive();
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
    o.occupancy_cell = c.quantity("analysis.occupancy_cell");
    o.speed_tolerance = c.quantity("tolerances.speed");
    o.dispersion_tolerance = c.quantity("tolerances.dispersion");
    o.retention_tolerance = c.quantity("tolerances.retention");
    o.iou_minimum = c.quantity("tolerances.streamline_iou");
    const double px = c.quantity("inputs.pixel_size");
    const Comparison cmp = compareTracks(readTracksCsv(c.path("inputs.experiment"), px), readTracksCsv(c.path("inputs.simulation"), px), o);
    RunOutput out;
    out.files = writeComparison(cmp, ctx.out_dir);
    out.evaluated = cmp.metrics;
    out.details = cmp.toJson();
    out.details.erase("metrics");
    return out;
  };
  registry.add(k);
}

}  // namespace mmval::compare
