// The one tracks schema shared by the tracker (experiment) and the simulator
// (trajectories), so that `compare` never cares where a trajectory came from.
//
// CSV, one row per particle per frame, header names carry units:
//   frame, particle, x, y, x_um, y_um, t_s [, z_um]
//   [, sigma_px, eccentricity, signal, mass, background, ep_px] [, state]
// trackpy's column names come first (x, y in pixels), so trackpy users load
// the file as it is. x_um/y_um are required (or pixels plus a pixel size
// given by the caller); pixel columns are optional for simulated
// trajectories. x_px/y_px are read as synonyms of x/y. Readers find columns
// by name, so a column they do not know is skipped, and the optional quality
// columns may be absent.
//
// The quality columns describe the detected spot behind each point (the
// tracker writes them; simulated trajectories have none): see SpotQuality.
// An empty field is a point without a measurement (NaN in memory), e.g. a
// deposited particle's resting points added from the background.
#pragma once
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

namespace mmval {

/// How well one detected spot is measured (tracking/src/SpotQuality.cpp says how).
/// Brightness is in fractions of full scale of the video (1 = white): signal and
/// mass on the background-removed signal with the particles' polarity (dark
/// particles count positive), background the video's own level. NaN: not measured.
struct SpotQuality {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  double sigma_px = kNaN;      ///< Gaussian sigma of the spot, px (mean of the principal axes; not trackpy's radius of gyration, ~1.4 sigma)
  double eccentricity = kNaN;  ///< sqrt(1 - b^2 / a^2) of the spot's principal sigmas a >= b: 0 round, towards 1 elongated
  double signal = kNaN;        ///< peak amplitude of the spot above its local background
  double mass = kNaN;          ///< integrated signal within the detector's refine_radius (trackpy's mass), full scale x px^2
  double background = kNaN;    ///< the video's local brightness around the spot (median of a ring), full scale
  double ep_px = kNaN;         ///< localisation uncertainty per axis (Cramer-Rao bound from signal, noise, sigma), px
  bool measured() const { return !std::isnan(sigma_px); }
};

struct TrackPoint {
  std::int64_t frame = 0;
  std::int64_t particle = 0;
  double t = 0;  ///< s
  double x = 0, y = 0;  ///< m
  double z = std::numeric_limits<double>::quiet_NaN();  ///< m, NaN when absent
  double x_px = std::numeric_limits<double>::quiet_NaN(), y_px = std::numeric_limits<double>::quiet_NaN();
  std::string state;  ///< optional: mobile, immobile, deposited
  SpotQuality quality;  ///< the detected spot's; unmeasured for simulated trajectories
};

struct Tracks {
  std::vector<TrackPoint> points;  ///< sorted by particle, then frame
  std::string source;              ///< file it came from
};

/// Reads a tracks CSV; `pixel_size` (m) converts pixel columns when the
/// micrometre columns are absent (0: they must be present). `particle` and
/// `frame` are read as exact 64-bit integers (ids above 2^53 stay distinct).
/// The quality columns are read when present (an empty field or "nan" is NaN).
/// Throws InputError naming the file, line and column, also for a frame below 0.
Tracks readTracksCsv(const std::filesystem::path& file, double pixel_size = 0.0);

/// Writes the shared schema atomically (pixel columns when `pixel_size` > 0;
/// the quality columns when any point has a measured spot).
void writeTracksCsv(const std::filesystem::path& file, const Tracks& tracks, double pixel_size = 0.0);

}  // namespace mmval
