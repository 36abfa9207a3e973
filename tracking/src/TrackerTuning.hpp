// Internal to mmval::tracking: the tuning constants of the tracker's pipeline
// (Pipeline.cpp, PipelineJoins.cpp) and of the joint fit of overlapping spots
// (SpotFit.cpp), in one place, each with the reason for its value. They are not case
// keys: the case's own settings (TrackConfig, the tracking-video schema) stay where
// they are declared.
#pragma once
#include <cstddef>

namespace mmval::tracking::detail {

/// runTracker's stages: sampling, large discs, stuck and deposited particles.
struct PipelineTuning {
  /// Frames the polarity and ring guesses sample, spread over the video.
  int polarity_samples = 24;
  /// Large discs: radii searched, as multiples of detect.refine_radius (the real discs
  /// video has radii ~40-60 px, +-20 % about its middle; 0.7-1.3 also allows a size given
  /// roughly).
  double disc_radius_low = 0.7, disc_radius_high = 1.3;

  /// Reference frames (kept whole; where a track ends they tell whether a particle of the
  /// background was missing before and there after): about a dozen spread over the video,
  /// every frame_count / reference_spacing-th ...
  int reference_spacing = 12;
  /// ... or every reference_stride_unknown-th when the frame count is unknown ...
  int reference_stride_unknown = 25;
  /// ... and no more than this many (memory stays bounded on long videos).
  std::size_t max_references = 24;

  /// The absence test of a particle of the background (stuck candidates, reference
  /// frames): least-squares amplitude of a spot of sigma spot_sigma_px over the window of
  /// half-width spot_window_px around it in sign x (frame - background), ~0 while the
  /// particle is there, about minus its amplitude once it has gone; it is missing below
  /// -missing_fraction x the spot's peak.
  double spot_sigma_px = 1.5;
  int spot_window_px = 4;
  double missing_fraction = 0.5;

  /// Stuck particles look like the moving ones: keep background spots whose blob area is
  /// within a factor stuck_area_ratio of the median area of the moving detections ...
  double stuck_area_ratio = 2.0;
  /// ... and whose peak is at least stuck_peak_fraction of the moving ones' median peak
  /// (grain edges leave faint round residues in the hat).
  double stuck_peak_fraction = 0.5;
  /// Frames the absence test may get wrong: frame count / absence_error_divisor (a tenth).
  int absence_error_divisor = 10;

  /// Joining a track end to a resting place: within max(join_gate_min_px, the linker's
  /// search radius) of it, and within max(join_gate_min_frames, join_gate_memory_factor x
  /// (link.memory + 1)) frames of its arrival (a few pixels, a few frames).
  double join_gate_min_px = 3.0;
  int join_gate_min_frames = 10;
  int join_gate_memory_factor = 3;
  /// A point at a resting place: within max(resting_min_px, detect.refine_radius) of it.
  double resting_min_px = 1.0;

  /// A deposit found by the reference frames: missing from at least
  /// missing_before_quarters / 4 of the references before the track's end, and from at most
  /// missing_after_quarters / 4 of those after it.
  int missing_before_quarters = 3;
  int missing_after_quarters = 1;
};

/// detail::deblend's stages: residual set-up, joint fit sweeps, hidden-spot search,
/// split test, merge removal.
struct DeblendTuning {
  /// Fit window half-width: window_sigmas x the spots' smoothed sigma, at least
  /// window_min_px.
  double window_sigmas = 3;
  int window_min_px = 2;
  /// Widest window the per-spot tables hold (wider: the joint fit is skipped).
  static constexpr int max_window = 32;
  /// Neighbours: spots farther apart than neighbour_sigmas sigma bias each other's masked
  /// centroid by < 0.02 px; at least neighbour_min_px.
  double neighbour_sigmas = 4.6;
  double neighbour_min_px = 3.0;

  /// One spot's refit: masked-centroid iterations, at most refit_iterations; a step over
  /// refit_lost_px means the spot was lost to a neighbour (the last estimate is kept); a
  /// step under refit_converged_px ends it. Two iterations per visit: its neighbours move
  /// after it anyway, so converging one spot alone within a pass is mostly wasted (6
  /// iterations per visit, 8 passes: 4.2 iterations per refit on the Brownian slab bench
  /// video, with positions no closer to the fit's fixed point than 2 per visit).
  int refit_iterations = 2;
  double refit_lost_px = 2.0;
  double refit_converged_px = 1e-3;
  /// Gauss-Seidel sweeps over the spots that have neighbours until none moves by
  /// sweep_converged_px, at most sweep_passes. (Refitting only the spots whose
  /// neighbourhood still moves was measured: close pairs converge slowly, so it changes
  /// their positions by up to ~0.05 px and, through the linker, the SNR 4 scenes' scores.)
  /// The cap is reached in nearly every frame of the Brownian slab bench video (defocused
  /// spots in contact keep sliding: at 200 passes and 1e-5 px, 30 % of its frames still
  /// had not converged), so the cap sets the cost. Measured there against the truth and
  /// against that 200-pass fit (bench/tracking/README.md, "Stop 42"): with the
  /// extrapolation below and 2 iterations per visit, 8 passes are closer to both than the
  /// former 8 passes x 6 iterations without it, for 55 % fewer iterations; 6 passes cost
  /// 23 % fewer refits but leave spots of the clean sparse SNR 10 scene
  /// (TrackingValidationTest) split into false duplicates.
  int sweep_passes = 8;
  double sweep_converged_px = 5e-3;
  /// Aitken's delta-squared extrapolation of each spot's position after every
  /// extrapolate_every-th plain pass (two steps give the ratio), the ratio capped at
  /// extrapolate_max_ratio (a jump of at most 9 x the last step; not tuned).
  int extrapolate_every = 2;
  double extrapolate_max_ratio = 0.9;

  /// Hidden spots: a residual maximum is a new spot unless it lies within taken_px of a
  /// spot found so far, and only above residual_fraction of its neighbour's smoothed
  /// amplitude (what a slightly wrong spot model leaves behind at high SNR: a sigma off by
  /// 10 % leaves ~10 % of the amplitude) as well as above the seeds' level.
  double taken_px = 2;
  double residual_fraction = 0.3;

  /// The split test (see deblend's stage splitMergedPairs for the derivation):
  /// two spots must gain more than split_kappas x kappa pixel variances (noise, rules at
  /// low SNR; chi2(3) > 7 has probability 0.07, and kappa overstates the correlation the
  /// position directions see by ~25 %; 10 kappa already loses enough true pairs to break
  /// the SNR 4 scene's RMSE target) ...
  double split_kappas = 7;
  /// ... and more than split_energy_fraction of the spot's energy (rules at high SNR: lone
  /// spots gain 0.25 % typically, < 2 % always; true pairs ~2 px apart 2-10 %).
  double split_energy_fraction = 0.025;
  /// Only blobs whose principal variances differ by split_elongation: no accepted split
  /// was less elongated than 1.14, round spots at high SNR are mostly below 1.1.
  double split_elongation = 1.1;
  /// Cheap screen: about screen_window_share of the window's pixel variances remain after a
  /// good fit, so two spots cannot gain more than the excess over that.
  double screen_window_share = 0.5;
  /// The pair starts split_half_px either side of the centre along the blob's axis (2.4 px
  /// apart) and is kept only if its spots end more than split_min_apart_px apart.
  double split_half_px = 1.2;
  double split_min_apart_px = 1.2;
  /// The trial pair's own fit (the two spots alone, Gauss-Seidel, as the sweeps): at most
  /// split_passes passes of split_refit_iterations masked-centroid steps per spot, and
  /// Aitken's extrapolation of both spots after every split_extrapolate_every-th pass.
  /// Measured on the Brownian slab bench video (60 frames, 18,137 trial pairs; see
  /// bench/tracking/README.md, "Stop 47") against the same fit run to convergence (200
  /// passes, 1e-5 px): the former 8 passes x 6 steps without extrapolation took another
  /// decision than the converged fit for 555 pairs (p90 of the kept pairs' distance to it
  /// 0.54 px); 8 x 2 with a jump every 3rd pass for 411 (0.32 px), with 53 % fewer steps.
  /// A jump every 2nd pass (the sweeps') was 473 and 0.38 px. Before the extrapolation,
  /// the joint fit's numbers then (2 x 6) left 3 false duplicates in the clean sparse SNR
  /// 10 scene of TrackingValidationTest instead of 0.
  int split_passes = 8;
  int split_refit_iterations = 2;
  int split_extrapolate_every = 3;

  /// Two fits closer than merged_px are one particle: the fainter is dropped.
  double merged_px = 1.0;
};

inline constexpr PipelineTuning kPipelineTuning{};
inline constexpr DeblendTuning kDeblendTuning{};

}  // namespace mmval::tracking::detail
