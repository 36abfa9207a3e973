#include "mmval/tracking/KindMetrics.hpp"

namespace mmval::tracking {

namespace {

// Scores against ground truth (Score.hpp, Chenouard et al. 2014). Distances are
// in pixels, which are no unit of their own: rmse is declared dimensionless.
void jaccardAndRmse(Schema& s) {
  s.metric("jaccard_points", "1", "Jaccard index of the detections: TP / (TP + FP + FN) under the score gate");
  s.metric("jaccard_tracks", "1", "Jaccard index of whole tracks paired by optimal assignment");
  s.metric("rmse", "1", "RMS position error of the matched points (error under the score gate), px: the challenge's, localisation and wrong-particle errors together");
  s.metric("rmse_localisation", "1", "RMS position error of the matched points within 1 px of the truth, px: the localisation error alone");
  s.metric("gross_points", "1", "Matched points 1 px or more from the truth (a track on a neighbour for a few frames)");
}

void alphaBeta(Schema& s) {
  s.metric("alpha", "1", "Track-matching score 1 - d(X, Y) / d(X, 0) (1: perfect)");
  s.metric("beta", "1", "alpha also penalising spurious tracks");
}

void videoMetrics(Schema& s) {
  alphaBeta(s);  // these five only with inputs.truth
  jaccardAndRmse(s);
  s.metric("mean_speed", "um/s", "Mean speed over all steps of mobile particles");
  s.metric("median_speed", "um/s", "Median speed over all steps of mobile particles");
  s.metric("sigma_x", "um", "Time-averaged dispersion of the mobile particles along x");
  s.metric("sigma_y", "um", "Time-averaged dispersion of the mobile particles along y");
  s.metric("retention_fraction", "1", "Retained over entered particles (retained over mobile when none entered)");
  s.metric("tracks", "1", "Particles tracked");
  s.metric("immobile", "1", "Particles that never moved farther than the immobile distance (flow); Brownian: tracks whose D is significantly below the ensemble's and not above 0");
  // analysis.motion = "brownian" (or "auto" deciding so) reports these instead of speeds, dispersion and retention.
  s.metric("diffusion_coefficient", "um2/s", "Brownian: D of the drift-corrected ensemble MSD fitted as 4 D t + 4 sigma^2 - (4/3) D t_E (Michalet 2010)");
  s.metric("msd_exponent", "1", "Brownian: exponent alpha of the drift-corrected ensemble MSD, c + 4 K t^alpha (1: free diffusion)");
  s.metric("localisation_sigma", "um", "Brownian: localisation error per axis from the MSD fit's offset (with the blur term of analysis.exposure)");
}

void syntheticMetrics(Schema& s) {
  alphaBeta(s);
  jaccardAndRmse(s);
  s.metric("mean_speed_relative_error", "1", "|tracked - true mean speed| / true mean speed");
  s.metric("immobile_found", "1", "Immobile tracks found");
  s.metric("immobile_recall", "1", "Share of the particles stuck from the start that an immobile track sits on (when there are any)");
  s.metric("frames_per_second", "Hz", "Tracking throughput, frames per wall-clock second");
}

void renderedMetrics(Schema& s) {
  jaccardAndRmse(s);
  s.metric("mean_speed_relative_error", "1", "(tracked - true mean speed) / true mean speed, signed");
  s.metric("frames_per_second", "Hz", "Tracking throughput, frames per wall-clock second");
}

}  // namespace

void declareTrackingMetrics(CaseKindRegistry& registry) {
  registry.declareMetrics("tracking-video", videoMetrics);
  registry.declareMetrics("tracking-synthetic", syntheticMetrics);
  registry.declareMetrics("tracking-rendered", renderedMetrics);
}

}  // namespace mmval::tracking
