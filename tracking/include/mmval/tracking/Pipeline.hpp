// The whole tracker: frames -> (background) -> detections -> links -> tracks,
// streamed frame by frame, and the files a researcher looks at.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Link.hpp"
#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::tracking {

struct TrackConfig {
  DetectOptions detect;
  LinkOptions link;
  TrackOptions analysis;
  double pixel_size = 1e-6;  ///< m per px
  double fps = 10;
  int threads = 1;  ///< detection threads (frames are detected in parallel, linked in order)
};

struct TrackRun {
  Tracks tracks;                 ///< px and m, t = frame / fps
  std::vector<std::vector<Detection>> detections;  ///< per processed frame
  std::vector<int> frame_index;
  LinkStats link;
  Polarity polarity = Polarity::dark;
  cv::Mat background;
  double seconds = 0;
  int stuck_found = 0;  ///< particles found in the background (stuck all along)
};

/// Runs the tracker over the whole source; a progress bar unless quiet. Memory stays
/// bounded: frames are read in batches of 2 x threads, only detections are kept.
TrackRun runTracker(FrameSource& source, const TrackConfig& config, bool quiet);

/// Writes detections.csv, tracks.csv, track_summary.csv, velocities.csv,
/// dispersion.csv, msd.csv, speed_time.csv, retention.csv, retention_time.csv
/// (deposited count per frame), streamlines.png and summary.json into `dir`;
/// returns the file names.
std::vector<std::string> writeTrackOutputs(const TrackRun& run, const TrackConfig& config, const std::filesystem::path& dir,
                                           const nlohmann::json& extra_summary);

}  // namespace mmval::tracking
