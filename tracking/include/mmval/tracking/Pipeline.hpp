// The whole tracker: frames -> (background) -> detections -> links -> tracks,
// streamed frame by frame, and the files a researcher looks at.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Link.hpp"
#include "mmval/tracking/SceneDecisions.hpp"
#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::tracking {

struct TrackConfig {
  DetectOptions detect;
  LinkOptions link;
  TrackOptions analysis;
  double pixel_size = 1e-6;  ///< m per px
  double fps = 10;
  int threads = 0;  ///< decoding and detection threads (frames in parallel, linked in order); 0: every core
  /// Half-width, in frames, of the along-track quadratic fit of moving particles'
  /// positions (TrackSmooth.hpp); 0: positions as detected.
  int smooth_frames = 0;
  /// Background (detect.subtract_background): the per-pixel quantile of sampled frames
  /// (0.5: the median), one for the whole video, or with background_window > 0 one per
  /// block of that many frames, blended between blocks (Background.hpp).
  double background_quantile = 0.5;
  int background_window = 0;
  /// The static scene's solids (grains, walls) where known: CV_8U of the frames' size,
  /// non-zero on solid pixels (a rendered video's mask, a chip design registered to the
  /// video); empty: unknown. A grain as small as a particle is, in the median background,
  /// a particle at rest all along (detect.find_stuck): a spot centred on or beside a solid
  /// pixel is taken as the scene instead (a particle's centre lies a radius into the pores).
  cv::Mat solids;
};

struct TrackRun {
  Tracks tracks;                 ///< px and m, t = frame / fps
  std::vector<std::vector<Detection>> detections;  ///< per processed frame
  std::vector<int> frame_index;
  LinkStats link;
  Polarity polarity = Polarity::dark;
  std::string polarity_reason;   ///< why this polarity (as set, or the guesses' numbers)
  RingGuess ring;                ///< the ring test on the sampled frames (polarity auto or ring)
  BackgroundDecision background_decision;  ///< whether the temporal median was subtracted, and why
  cv::Mat background;
  double seconds = 0;
  /// Wall time of runTracker's stages in order (name, s): sampling (decoding the frames the
  /// background and polarity samplers keep), background (the median), rings, polarity and
  /// decisions (the guesses and the background decision), frames (decoding the rest,
  /// detecting and linking every frame), joins (motion model, deposits), analysis. For
  /// benchmarks and profiling.
  std::vector<std::pair<std::string, double>> stage_seconds;
  /// The same stages' CPU time, summed over the process' threads (s): on a loaded
  /// machine steadier than the wall time, and CPU / wall tells how well a stage used the cores.
  std::vector<std::pair<std::string, double>> stage_cpu_seconds;
  int stuck_found = 0;  ///< particles found in the background (stuck all along)
  int stuck_on_solids = 0;  ///< spots of the background centred on TrackConfig::solids: the scene, left out
  /// Particles that arrived, deposited and stayed long enough to be part of the median
  /// background: joined to the track that brought them (it continues, at rest, to the end
  /// of the video, its points from the stop on labelled "deposited"), or found without one.
  int deposits_joined = 0, deposits_unjoined = 0;
  /// Tracks that end, in the interior, on a particle already at rest and are continued by
  /// no other track: the particle deposited onto it (clusters); continued there, at rest.
  int cluster_arrivals = 0;
  /// Tracks that end, in the interior, where the background holds a particle that
  /// reference frames before the end lack and after it show: deposited there.
  int deposits_by_reference = 0;
  long long smoothed_points = 0;  ///< moving points refined along their track (smooth_frames)
  /// Flow or Brownian analysis (analysis.motion), decided from the tracks when "auto".
  MotionDecision motion;
  /// Brownian motion: the analysis of `tracks` (runTracker does it once; writers and the
  /// kinds read it). Empty for flow, or when the tracks were changed after runTracker.
  std::optional<BrownianStats> brownian;
};

/// Runs the tracker over the whole source; a progress bar unless quiet. Memory stays
/// bounded: frames are read in batches of 2 x threads, only detections are kept, and the
/// frames sampled for the background and the polarity wait in the source's bounded cache
/// for the main pass, so that each frame is decoded once (Frames.hpp). config.threads 0:
/// every core; results do not depend on the number of threads.
/// With detect.find_stuck, particles at rest in the median background are immobile
/// tracks (stuck from the start) or continue the track that ends where and when they
/// arrived (deposited). Tracks at rest over their final analysis.stuck_window are
/// labelled "deposited" from where they stopped (markDeposits). With analysis.motion
/// "auto" the linked tracks decide flow or Brownian (decideMotion); Brownian with
/// link.predict automatic links again without prediction. Deposits and the stuck-
/// particle joins are flow-mode steps, skipped for Brownian motion.
TrackRun runTracker(FrameSource& source, const TrackConfig& config, bool quiet);

/// Writes detections.csv, tracks.csv, track_summary.csv, velocities.csv,
/// dispersion.csv, msd.csv, speed_time.csv, retention.csv (counts per frame, the
/// schema of mmval/core/OutputTables.hpp), streamlines.png and summary.json into `dir`;
/// returns the file names. For Brownian motion (run.motion) the flow files (velocities,
/// speed, retention, speed map) are not written; instead track_diffusion.csv,
/// van_hove.csv, diffusion_histogram.csv/.png and a "brownian" block in summary.json
/// (BrownianOutputs.hpp).
std::vector<std::string> writeTrackOutputs(const TrackRun& run, const TrackConfig& config, const std::filesystem::path& dir,
                                           const nlohmann::json& extra_summary);

}  // namespace mmval::tracking
