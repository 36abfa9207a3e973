// The flags of `mmval track` as a tracking-video case: trackpy's parameter names
// mapped to case keys (the contract docs/trackpy-mapping.md documents), and the
// video's own flags (input, pixel size, frame rate, frame range, region).
#pragma once
#include <optional>
#include <string>
#include <vector>

#include "mmval/core/Case.hpp"
#include "mmval/core/Schema.hpp"

namespace mmval {
class CaseKindRegistry;
}

namespace mmval::tracking {

/// trackpy's names, as the text given on the command line (empty: not given), so that a
/// bad value is reported with its flag and exactly as typed.
struct TrackpyFlags {
  std::string diameter;      ///< --diameter: feature diameter, px, odd, 3-101
  std::string minmass;       ///< --minmass: integrated brightness in trackpy's 8-bit units, >= 0
  std::string separation;    ///< --separation: px, 1-100
  std::string search_range;  ///< --search-range: px per frame, 0.1-10000
  std::string memory;        ///< --memory: frames, whole, 0-100
  std::string threads;       ///< --threads: whole, 0 (every core) to 256
  bool invert = false;       ///< --invert: dark features on a bright background
};

/// One case key set by one trackpy-style flag.
struct TrackpyKey {
  std::string flag;  ///< e.g. "--diameter"
  std::string key;   ///< e.g. "detect.refine_radius"
  Value value;
};

/// The case keys the given flags set, in flag order (--diameter, --separation, --minmass,
/// --search-range, --memory, --threads, --invert), as docs/trackpy-mapping.md lists them.
/// --diameter stands for trackpy's locate: its band pass, centroid, mass disc and
/// separation, and none of mmval's own filters that trackpy lacks. --minmass is divided
/// by 255 (trackpy's mass of an 8-bit frame -> detect.min_mass_relative).
/// Throws InputError (naming the flag, the text and the allowed range) for a bad value.
std::vector<TrackpyKey> trackpyKeys(const TrackpyFlags& flags);

/// Every flag of `mmval track` that becomes a case key.
struct TrackFlags {
  std::string input;   ///< video, image folder, glob or multi-page TIFF (made absolute)
  std::string config;  ///< tracking-video case file; empty: the kind's defaults
  std::string truth;   ///< ground-truth tracks CSV; empty: none
  std::string linker;  ///< link.method; empty: the case's
  std::optional<double> pixel_size_um;  ///< inputs.pixel_size (set in m)
  std::optional<double> fps_hz;         ///< inputs.frame_rate
  std::vector<int> roi;                 ///< x, y, width, height in px; empty: whole frame
  int first = 0, last = -1;             ///< frame range; last -1: to the end
  int smooth = -1;                      ///< link.smooth_frames; < 0: the case's
  bool no_background = false;           ///< detect.subtract_background = false
  TrackpyFlags trackpy;
  std::vector<std::string> set;  ///< --set KEY=VALUE, in order
};

/// The tracking-video case the flags describe: the --config file (or the kind's defaults)
/// with the --set overrides, then the trackpy keys, then the video's own keys. The flags'
/// values are checked before the case is read. Throws InputError naming the flag for a bad
/// value, for a --config of another kind, and for a --set of a key that a trackpy-style
/// flag also sets (say it one way).
Case trackingVideoCase(const TrackFlags& flags, const CaseKindRegistry& registry);

}  // namespace mmval::tracking
