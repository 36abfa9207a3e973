// The one tracks schema shared by the tracker (experiment) and the simulator
// (trajectories), so that `compare` never cares where a trajectory came from.
//
// CSV, one row per particle per frame, header names carry units:
//   frame, particle, x, y, x_um, y_um, t_s [, z_um] [, state]
// trackpy's column names come first (x, y in pixels), so trackpy users load
// the file as it is. x_um/y_um are required (or pixels plus a pixel size
// given by the caller); pixel columns are optional for simulated
// trajectories. x_px/y_px are read as synonyms of x/y.
#pragma once
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

namespace mmval {

struct TrackPoint {
  std::int64_t frame = 0;
  std::int64_t particle = 0;
  double t = 0;  ///< s
  double x = 0, y = 0;  ///< m
  double z = std::numeric_limits<double>::quiet_NaN();  ///< m, NaN when absent
  double x_px = std::numeric_limits<double>::quiet_NaN(), y_px = std::numeric_limits<double>::quiet_NaN();
  std::string state;  ///< optional: mobile, immobile, deposited
};

struct Tracks {
  std::vector<TrackPoint> points;  ///< sorted by particle, then frame
  std::string source;              ///< file it came from
};

/// Reads a tracks CSV; `pixel_size` (m) converts pixel columns when the
/// micrometre columns are absent (0: they must be present). `particle` and
/// `frame` are read as exact 64-bit integers (ids above 2^53 stay distinct).
/// Throws InputError naming the file, line and column, also for a frame below 0.
Tracks readTracksCsv(const std::filesystem::path& file, double pixel_size = 0.0);

/// Writes the shared schema atomically (pixel columns when `pixel_size` > 0).
void writeTracksCsv(const std::filesystem::path& file, const Tracks& tracks, double pixel_size = 0.0);

}  // namespace mmval
