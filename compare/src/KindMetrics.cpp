#include "mmval/compare/KindMetrics.hpp"

namespace mmval::compare {

namespace {

// The comparator judges its metrics itself (RunOutput::evaluated): simulation
// value against experiment value with the case's [tolerances].
void compareTracksMetrics(Schema& s) {
  s.metric("mean_speed", "um/s", "Mean particle speed, simulation against experiment (paper Fig. 15)");
  s.metric("median_speed", "um/s", "Median particle speed, simulation against experiment (paper Fig. 15)");
  s.metric("sigma_x", "um", "Time-averaged dispersion along x (paper Eq. 18 / Fig. 16)");
  s.metric("sigma_y", "um", "Time-averaged dispersion along y (paper Eq. 18 / Fig. 16)");
  s.metric("retention_fraction", "1",
           "Particles at rest at the end over particles that entered, by one rule on both files (fragments of a track chained; "
           "at rest: drift over the final analysis.stuck_window below stuck_distance / stuck_window plus 3 standard errors of the noise)");
  s.metric("retention_simulation_labelled", "1",
           "Simulated particles whose trajectory ends on a row labelled deposited (the engine's attachments) over those that entered; not compared");
  s.metric("streamline_iou", "1", "Intersection over union of the occupancy maps (paper Fig. 14)");
  s.metric("speed_pore_bodies", "um/s", "With a geometry mask: mean speed of the steps in pore bodies");
  s.metric("speed_throats", "um/s", "With a geometry mask: mean speed of the steps in pore throats");
  s.metric("experiment_steps_in_grains", "1", "With a geometry mask: share of experiment steps inside grains (large: poor alignment)");
  s.metric("speed_wasserstein1", "um/s", "Wasserstein-1 distance between the speed distributions");
  s.metric("speed_ks_statistic", "1", "Two-sample Kolmogorov-Smirnov D of the speeds");
  s.metric("speed_ks_p_value", "1", "Asymptotic p-value of the Kolmogorov-Smirnov D over per-frame steps taken as independent (too small: steps of a track are correlated)");
  s.metric("track_speed_ks_statistic", "1", "Two-sample Kolmogorov-Smirnov D of the per-track mean speeds (one value per moving track)");
  s.metric("track_speed_ks_p_value", "1", "Asymptotic p-value of the per-track D: tracks are independent samples, so it can be read as a p-value");
  s.metric("registration_dx", "um", "With registration: fitted shift of the frame in the mask frame, x");
  s.metric("registration_dy", "um", "With registration: fitted shift, y (image rows, down)");
  s.metric("registration_rotation", "deg", "With registration: fitted rotation, counter-clockwise in image axes");
  s.metric("registration_ecc_correlation", "1", "With registration: ECC correlation coefficient at the fit (1: perfect)");
  s.metric("registration_rms_residual", "1", "With registration: RMS of frame - (gain x registered mask + bias), grey levels in [0, 1]");
}

}  // namespace

void declareCompareMetrics(CaseKindRegistry& registry) { registry.declareMetrics("compare-tracks", compareTracksMetrics); }

}  // namespace mmval::compare
