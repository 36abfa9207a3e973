#include "mmval/tracking/TrackpyFlags.hpp"

#include <cmath>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "mmval/core/Error.hpp"
#include "TrackpyFlagsChecks.hpp"

namespace fs = std::filesystem;

namespace mmval::tracking {

using detail::flagInteger;
using detail::flagNumber;
using detail::requireOptionValue;

std::vector<TrackpyKey> trackpyKeys(const TrackpyFlags& t) {
  std::vector<TrackpyKey> keys;
  auto put = [&](const char* flag, const char* key, Value v) { keys.push_back({flag, key, std::move(v)}); };
  if (!t.diameter.empty()) {
    const std::int64_t d = flagInteger("--diameter", t.diameter, 3, 101, "an odd whole number of pixels from 3 to 101 (trackpy's feature diameter)");
    if (d % 2 == 0)
      throw InputError({}, "option --diameter has an invalid value", fmt::format("--diameter {}", t.diameter),
                       "an odd whole number of pixels from 3 to 101 (trackpy requires an odd diameter)");
    const std::int64_t radius = d / 2;
    put("--diameter", "detect.method", std::string("peaks"));
    put("--diameter", "detect.refinement", std::string("disc"));
    put("--diameter", "detect.refine_radius", radius);
    put("--diameter", "detect.local_background", radius);
    put("--diameter", "detect.blur_sigma", 1.0);
    put("--diameter", "detect.subtract_background", false);
    put("--diameter", "detect.min_snr", 0.0);
    put("--diameter", "detect.min_area", 1.0);
    put("--diameter", "detect.min_percentile", 64.0);
    put("--diameter", "detect.max_size_ratio", 0.0);
    if (t.separation.empty()) put("--diameter", "detect.separation", d + 1);
  }
  if (!t.separation.empty())
    put("--separation", "detect.separation",
        static_cast<std::int64_t>(std::lround(flagNumber("--separation", t.separation, 1, 100, "a distance in px from 1 to 100 (trackpy's separation)"))));
  if (!t.minmass.empty())
    put("--minmass", "detect.min_mass_relative",
        flagNumber("--minmass", t.minmass, 0, 1e9, "a mass >= 0 in trackpy's units for 8-bit frames (e.g. --minmass 140)") / 255.0);
  if (!t.search_range.empty())
    put("--search-range", "link.search_radius",
        flagNumber("--search-range", t.search_range, 0.1, 1e4, "a distance in px per frame from 0.1 to 10000 (trackpy's search_range)"));
  if (!t.memory.empty()) put("--memory", "link.memory", flagInteger("--memory", t.memory, 0, 100, "a whole number of frames from 0 to 100 (trackpy's memory)"));
  if (!t.threads.empty()) put("--threads", "detect.threads", flagInteger("--threads", t.threads, 0, 256, "a whole number of threads from 0 (every core) to 256"));
  if (t.invert) put("--invert", "detect.polarity", std::string("dark"));
  return keys;
}

namespace {

/// The video's own flags, each checked here so that a bad --fps is named as bad, not reported as missing.
void checkVideoFlags(const TrackFlags& t) {
  if (t.pixel_size_um)
    requireOptionValue("--pixel-size-um", *t.pixel_size_um, 0, true, 1e6, "a pixel size in micrometres, finite and > 0 (e.g. --pixel-size-um 0.65)");
  if (t.fps_hz) requireOptionValue("--fps", *t.fps_hz, 0, true, 1e9, "a frame rate in frames per second, finite and > 0 (e.g. --fps 20)");
  if (t.first < 0) throw InputError({}, "option --first has an invalid value", fmt::format("--first {}", t.first), "a frame number >= 0");
  if (t.last < -1) throw InputError({}, "option --last has an invalid value", fmt::format("--last {}", t.last), "a frame number >= --first, or -1 for the end");
  if (t.last >= 0 && t.last < t.first)
    throw InputError({}, "the frame range is empty", fmt::format("--first {} --last {}", t.first, t.last), "--last >= --first, or -1 for the end");
  if (!t.roi.empty() && (t.roi.size() != 4 || t.roi[0] < 0 || t.roi[1] < 0 || t.roi[2] <= 0 || t.roi[3] <= 0))
    throw InputError({}, "option --roi has an invalid value", fmt::format("--roi {}", fmt::join(t.roi, ",")), "x,y >= 0 and width,height > 0 in px");
}

}  // namespace

Case trackingVideoCase(const TrackFlags& t, const CaseKindRegistry& registry) {
  checkVideoFlags(t);
  // The settings are a tracking-video case: from --config, or the defaults.
  fs::path file = "(command line)";
  if (!t.config.empty()) {
    file = t.config;
    const Case probe = Case::load(file, registry);
    if (probe.kind() != "tracking-video")
      throw InputError(probe.where("case.kind"), "a --config file must be a tracking-video case", probe.kind(), "kind = \"tracking-video\"");
  }
  std::vector<CaseOverride> overrides;
  for (const auto& text : t.set) overrides.push_back(CaseOverride::parse(text));
  // The trackpy-style flags are checked before the case, and may not contradict a --set.
  const std::vector<TrackpyKey> trackpy = trackpyKeys(t.trackpy);
  for (const TrackpyKey& k : trackpy)
    for (const CaseOverride& o : overrides)
      if (o.key == k.key)
        throw InputError({}, fmt::format("options {} and --set {} both set {}", k.flag, o.text(), o.key), fmt::format("--set {}", o.text()),
                         fmt::format("one of them (docs/trackpy-mapping.md lists the keys {} sets)", k.flag));
  Case c = t.config.empty() ? Case::parse("[case]\nname = \"track\"\nkind = \"tracking-video\"\n", file, registry, overrides)
                            : Case::load(file, registry, overrides);
  for (const TrackpyKey& k : trackpy) c.set(k.key, k.value);
  c.set("inputs.video", fs::absolute(t.input).string());
  if (t.pixel_size_um) c.set("inputs.pixel_size", *t.pixel_size_um * 1e-6);
  if (t.fps_hz) c.set("inputs.frame_rate", *t.fps_hz);
  if (!t.truth.empty()) c.set("inputs.truth", fs::absolute(t.truth).string());
  if (!t.roi.empty()) c.set("inputs.roi", std::vector<std::int64_t>(t.roi.begin(), t.roi.end()));
  c.set("inputs.first_frame", static_cast<std::int64_t>(t.first));
  c.set("inputs.last_frame", static_cast<std::int64_t>(t.last));
  if (!t.linker.empty()) c.set("link.method", t.linker);
  if (t.no_background) c.set("detect.subtract_background", false);
  if (t.smooth >= 0) c.set("link.smooth_frames", static_cast<std::int64_t>(t.smooth));
  return c;
}

}  // namespace mmval::tracking
