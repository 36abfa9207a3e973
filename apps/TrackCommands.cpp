#include "TrackCommands.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/DetailFields.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/PoreFlowMap.hpp"
#include "mmval/tracking/SynthDiscs.hpp"
#include "mmval/tracking/Kinds.hpp"
#include "mmval/tracking/Synth.hpp"
#include "mmval/tracking/SynthRings.hpp"
#include "mmval/tracking/SynthSlab.hpp"

namespace fs = std::filesystem;

namespace mmval::app {

namespace {

struct TrackCli {
  std::string input, config, out, truth, linker;
  double pixel_um = 0, fps = 0;
  std::vector<int> roi;
  int first = 0, last = -1, smooth = -1;
  bool quiet = false, no_background = false;
  /// trackpy's names (docs/trackpy-mapping.md), read as text and checked here so that a
  /// bad value names its flag; empty: not given.
  std::string diameter, minmass, separation, search_range, memory, threads;
  bool invert = false;
  std::vector<std::string> set;  ///< --set KEY=VALUE, in order
};

/// A number given to a trackpy-style flag, finite and in [lo, hi]; InputError naming the
/// flag and `expected` otherwise.
double flagNumber(const char* flag, const std::string& text, double lo, double hi, const std::string& expected) {
  double v = 0;
  std::size_t used = 0;
  try {
    v = std::stod(text, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != text.size() || !std::isfinite(v) || v < lo || v > hi)
    throw InputError({}, fmt::format("option {} has an invalid value", flag), fmt::format("{} {}", flag, text), expected);
  return v;
}

/// Whole-number flags: as flagNumber, and no fraction.
std::int64_t flagInteger(const char* flag, const std::string& text, std::int64_t lo, std::int64_t hi, const std::string& expected) {
  const double v = flagNumber(flag, text, static_cast<double>(lo), static_cast<double>(hi), expected);
  if (v != std::floor(v)) throw InputError({}, fmt::format("option {} has an invalid value", flag), fmt::format("{} {}", flag, text), expected);
  return static_cast<std::int64_t>(v);
}

/// The case keys the trackpy-style flags set (docs/trackpy-mapping.md), flag by key.
/// --diameter stands for trackpy's locate: its band pass, centroid, mass disc and
/// separation, and none of mmval's own filters that trackpy lacks.
std::vector<std::pair<std::string, std::pair<std::string, Value>>> trackpyKeys(const TrackCli& t) {
  std::vector<std::pair<std::string, std::pair<std::string, Value>>> keys;
  auto put = [&](const char* flag, const char* key, Value v) { keys.push_back({flag, {key, std::move(v)}}); };
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

struct SynthCli {
  std::string out, geometry, grains = "dark", scene = "flow", format = "png";
  double amplitude = 0.35, snr = 0;
  tracking::SynthOptions o;
  double pixel_um = 1;
  tracking::BrownianSlabOptions slab;  ///< --scene brownian-slab; its defaults are the real video's class
  std::vector<double> drift_um_s, drift_change_um_s2;
  bool bright_particles = false;
  /// Options shared by both scenes, whose defaults differ (the slab takes its own unless given).
  CLI::Option *width = nullptr, *height = nullptr, *frames = nullptr, *fps = nullptr, *pixel = nullptr, *particles = nullptr, *noise = nullptr;
  CLI::Option *diffusion = nullptr, *temperature = nullptr, *viscosity = nullptr, *bright = nullptr;
  std::vector<CLI::Option*> flow_only, slab_only;
  tracking::RingSceneOptions rings;  ///< --scene brightfield-rings; its defaults are the real video's class
  std::vector<CLI::Option*> rings_only;
};

/// A real-valued option given on the command line must be finite and in its range; NaN and
/// infinities pass CLI11's own range checks (every comparison with NaN is false), and a bad
/// value must not be mistaken for a missing one. Exit 2 naming the option, the value and the rule.
void requireOptionValue(const char* option, double value, double lo, bool lo_open, double hi, const std::string& expected) {
  const bool ok = std::isfinite(value) && (lo_open ? value > lo : value >= lo) && value <= hi;
  if (!ok) throw InputError({}, fmt::format("option {} has an invalid value", option), fmt::format("{} {:g}", option, value), expected);
}

/// The Brownian slab scene's own options (synth --scene brownian-slab); see SynthSlab.hpp for the models.
void addSlabOptions(CLI::App* synth, SynthCli& sy) {
  auto& s = sy.slab;
  auto slab = [&](CLI::Option* opt) { sy.slab_only.push_back(opt->capture_default_str()); };
  sy.diffusion = synth->add_option("--diffusion-um2s", s.diffusion_um2_s, "brownian-slab: diffusion coefficient in um^2/s (instead of Stokes-Einstein from --temperature-K, --viscosity-Pa-s, --radius-um)");
  sy.temperature = synth->add_option("--temperature-K", s.temperature_K, "brownian-slab: temperature for Stokes-Einstein");
  sy.viscosity = synth->add_option("--viscosity-Pa-s", s.viscosity_Pa_s, "brownian-slab: fluid viscosity for Stokes-Einstein (water at 22 C)");
  for (CLI::Option* opt : {sy.diffusion, sy.temperature, sy.viscosity}) slab(opt);
  slab(synth->add_option("--radius-um", s.radius_um, "brownian-slab: particle radius (Stokes-Einstein and the in-focus spot size)"));
  slab(synth->add_option("--slab-um", s.slab_um, "brownian-slab: range of particle centre heights between the reflecting walls"));
  slab(synth->add_option("--focus-um", s.focus_um, "brownian-slab: height of the focal plane above the lower wall (< 0: mid-slab)"));
  sy.slab_only.push_back(synth->add_option("--drift-um-s", sy.drift_um_s, "brownian-slab: uniform drift X,Y in um/s (default 0.6,0)")->delimiter(',')->expected(2));
  sy.slab_only.push_back(
      synth->add_option("--drift-change-um-s2", sy.drift_change_um_s2, "brownian-slab: rate of change of the drift X,Y in um/s^2 (default 0,0)")->delimiter(',')->expected(2));
  slab(synth->add_option("--na", s.numerical_aperture, "brownian-slab: objective numerical aperture (defocus blur and depth of field)"));
  slab(synth->add_option("--medium-index", s.medium_index, "brownian-slab: refractive index of the sample medium"));
  slab(synth->add_option("--wavelength-um", s.wavelength_um, "brownian-slab: illumination wavelength"));
  slab(synth->add_option("--contrast", s.contrast, "brownian-slab: peak darkening of an in-focus particle, fraction of the background"));
  slab(synth->add_option("--flicker", s.flicker, "brownian-slab: relative std of the per-frame illumination"));
  slab(synth->add_option("--photons", s.photons, "brownian-slab: photons at full scale for shot noise (0: none)"));
  slab(synth->add_option("--exposure-s", s.exposure_s, "brownian-slab: exposure time for motion blur (0: none; at most 1/fps)"));
  slab(synth->add_option("--exposure-substeps", s.exposure_substeps, "brownian-slab: positions averaged over the exposure")->check(CLI::Range(1, 1000)));
  sy.bright = synth->add_flag("--bright-particles", sy.bright_particles, "brownian-slab: bright particles on a dim background (default dark on bright)");
  sy.slab_only.push_back(sy.bright);
}

/// synth --scene brownian-slab: shared options given on the command line replace the slab's defaults.
void runBrownianSlab(SynthCli& sy) {
  tracking::BrownianSlabOptions s = sy.slab;
  if (sy.width->count() > 0) s.width = sy.o.width;
  if (sy.height->count() > 0) s.height = sy.o.height;
  if (sy.frames->count() > 0) s.frames = sy.o.frames;
  if (sy.fps->count() > 0) s.fps_hz = sy.o.fps;
  if (sy.pixel->count() > 0) s.pixel_size_um = sy.pixel_um;
  if (sy.particles->count() > 0) s.particles = sy.o.particles;
  if (sy.noise->count() > 0) s.noise = sy.o.noise;
  s.seed = sy.o.seed;
  s.format = tracking::parseSynthFormat(sy.format);
  s.dark_particles = !sy.bright_particles;
  if (sy.diffusion->count() > 0 && (sy.temperature->count() > 0 || sy.viscosity->count() > 0))
    throw InputError({}, "options --diffusion-um2s and --temperature-K/--viscosity-Pa-s both set D", fmt::format("--diffusion-um2s {:g}", s.diffusion_um2_s),
                     "either D directly (--diffusion-um2s) or Stokes-Einstein's inputs (--temperature-K, --viscosity-Pa-s, --radius-um)");
  if (!sy.drift_um_s.empty()) s.drift_um_s = {sy.drift_um_s[0], sy.drift_um_s[1]};
  if (!sy.drift_change_um_s2.empty()) s.drift_change_um_s2 = {sy.drift_change_um_s2[0], sy.drift_change_um_s2[1]};
  if (s.diffusion_um2_s != 0) requireOptionValue("--diffusion-um2s", s.diffusion_um2_s, 0, true, 1e6, "a diffusion coefficient in um^2/s, finite and > 0");
  requireOptionValue("--temperature-K", s.temperature_K, 0, true, 1e4, "an absolute temperature in K, finite and > 0 (e.g. 295.15)");
  requireOptionValue("--viscosity-Pa-s", s.viscosity_Pa_s, 0, true, 1e6, "a viscosity in Pa s, finite and > 0 (water at 22 C: 0.9544e-3)");
  requireOptionValue("--radius-um", s.radius_um, 0, true, 1e4, "a particle radius in um, finite and > 0");
  requireOptionValue("--slab-um", s.slab_um, 0, true, 1e6, "a slab thickness in um, finite and > 0");
  if (!(s.focus_um < 0)) requireOptionValue("--focus-um", s.focus_um, 0, false, s.slab_um, "a focal-plane height from 0 to --slab-um (or < 0 for mid-slab)");
  for (double v : {s.drift_um_s[0], s.drift_um_s[1]}) requireOptionValue("--drift-um-s", v, -1e6, false, 1e6, "two finite velocities X,Y in um/s");
  for (double v : {s.drift_change_um_s2[0], s.drift_change_um_s2[1]})
    requireOptionValue("--drift-change-um-s2", v, -1e6, false, 1e6, "two finite rates X,Y in um/s^2");
  requireOptionValue("--medium-index", s.medium_index, 1, false, 5, "a refractive index from 1 to 5 (water: 1.33)");
  requireOptionValue("--na", s.numerical_aperture, 0, true, s.medium_index * (1 - 1e-9), "a numerical aperture > 0 and below --medium-index");
  requireOptionValue("--wavelength-um", s.wavelength_um, 0, true, 100, "a wavelength in um, finite and > 0 (e.g. 0.55)");
  requireOptionValue("--contrast", s.contrast, 0, false, 1, "a contrast from 0 to 1 of the background");
  requireOptionValue("--flicker", s.flicker, 0, false, 0.5, "a relative brightness std from 0 to 0.5");
  requireOptionValue("--photons", s.photons, 0, false, 1e12, "a photon count at full scale, finite and >= 0 (0: no shot noise)");
  requireOptionValue("--exposure-s", s.exposure_s, 0, false, 1 / s.fps_hz, fmt::format("an exposure time from 0 to one frame interval (1/fps = {:g} s)", 1 / s.fps_hz));
  StagedDirectory staged(sy.out);
  const auto r = tracking::writeBrownianSlabVideo(s, staged.path());
  staged.commit();
  std::printf("synth: %d frames (%s), Brownian slab with D %.4g um^2/s: %.0f particles per frame in view, %.0f in focus, %lld distinct -> %s, truth.csv, truth_in_focus.csv, truth.json\n",
              s.frames, sy.format.c_str(), r.diffusion_um2_s, r.mean_in_view, r.mean_in_focus, static_cast<long long>(r.distinct_in_view), sy.out.c_str());
}

/// The ring scene's own options (synth --scene brightfield-rings; SynthRings.hpp).
void addRingOptions(CLI::App* synth, SynthCli& sy) {
  auto& r = sy.rings;
  auto ring = [&](CLI::Option* opt) { sy.rings_only.push_back(opt->capture_default_str()); };
  ring(synth->add_option("--ring-radius-px", r.ring_radius_px, "brightfield-rings: radius of the dark ring"));
  ring(synth->add_option("--diffusion-px2", r.diffusion_px2, "brightfield-rings: diffusion coefficient in px^2 per frame"));
  ring(synth->add_option("--illumination-gradient", r.illumination_gradient, "brightfield-rings: brightness falls by this fraction from left to right"));
  ring(synth->add_option("--specks", r.static_specks, "brightfield-rings: static dark specks (dust on the optics)")->check(CLI::Range(0, 1000)));
}

/// synth --scene brightfield-rings: shared options given on the command line replace the scene's defaults.
void runRingScene(SynthCli& sy) {
  tracking::RingSceneOptions r = sy.rings;
  if (sy.width->count() > 0) r.width = sy.o.width;
  if (sy.height->count() > 0) r.height = sy.o.height;
  if (sy.frames->count() > 0) r.frames = sy.o.frames;
  if (sy.fps->count() > 0) r.fps_hz = sy.o.fps;
  if (sy.pixel->count() > 0) r.pixel_size_um = sy.pixel_um;
  if (sy.particles->count() > 0) r.particles = sy.o.particles;
  if (sy.noise->count() > 0) r.noise = sy.o.noise;
  r.seed = sy.o.seed;
  r.format = tracking::parseSynthFormat(sy.format);
  requireOptionValue("--ring-radius-px", r.ring_radius_px, 2, false, 100, "a ring radius from 2 to 100 px");
  requireOptionValue("--diffusion-px2", r.diffusion_px2, 0, false, 1e4, "a diffusion coefficient in px^2 per frame, finite and >= 0");
  requireOptionValue("--illumination-gradient", r.illumination_gradient, -0.89, false, 0.89, "a fraction between -0.89 and 0.89");
  try {
    StagedDirectory staged(sy.out);
    tracking::writeRingScene(r, staged.path());
    staged.commit();
  } catch (const std::invalid_argument& e) {
    throw InputError({}, e.what(), {}, "fewer or smaller rings (--particles, --ring-radius-px) or a larger frame (--width, --height)");
  }
  std::printf("synth: %d frames (%s), %d brightfield ring colloids of ring radius %g px -> %s, truth.csv, truth.json\n", r.frames, sy.format.c_str(),
              r.particles, r.ring_radius_px, sy.out.c_str());
}

/// synth --scene large-discs: the stand-in of the real discs video's class (SynthDiscs.hpp);
/// the shared options given on the command line replace the scene's defaults.
void runDiscScene(SynthCli& sy) {
  tracking::DiscSceneOptions d;
  if (sy.width->count() > 0) d.width = sy.o.width;
  if (sy.height->count() > 0) d.height = sy.o.height;
  if (sy.frames->count() > 0) d.frames = sy.o.frames;
  if (sy.fps->count() > 0) d.fps_hz = sy.o.fps;
  if (sy.pixel->count() > 0) d.pixel_size_um = sy.pixel_um;
  if (sy.particles->count() > 0) d.particles = sy.o.particles;
  if (sy.noise->count() > 0) d.noise = sy.o.noise;
  d.seed = sy.o.seed;
  d.format = tracking::parseSynthFormat(sy.format);
  try {
    StagedDirectory staged(sy.out);
    tracking::writeDiscScene(d, staged.path());
    staged.commit();
  } catch (const std::invalid_argument& e) {
    throw InputError({}, e.what(), {}, "fewer discs (--particles) or a larger frame (--width, --height)");
  }
  std::printf("synth: %d frames (%s), %d large discs of radius %g-%g px -> %s, truth.csv, truth.json (track them with --diameter %d)\n", d.frames,
              sy.format.c_str(), d.particles, d.radius_min_px, d.radius_max_px, sy.out.c_str(),
              static_cast<int>(d.radius_min_px + d.radius_max_px) + 1);
}

}  // namespace

void registerTrackCommands(CLI::App& app, const CaseKindRegistry& registry) {
  auto t = std::make_shared<TrackCli>();
  CLI::App* track = app.add_subcommand("track", "Track particles in a microscope video: tracks, velocities, dispersion, retention, streamlines");
  track->add_option("input", t->input, "Video, image folder, glob (quoted) or multi-page TIFF")->required();
  track->add_option("--out", t->out, "Output folder")->required();
  CLI::Option* pixel_opt = track->add_option("--pixel-size-um", t->pixel_um, "Pixel size in micrometres (or inputs.pixel_size in --config)");
  CLI::Option* fps_opt = track->add_option("--fps", t->fps, "Frames per second (or inputs.frame_rate in --config)");
  track->add_option("--config", t->config, "A tracking-video case file with [detect], [link], [analysis] settings (see `mmval case-doc tracking-video`)");
  track->add_option("--truth", t->truth, "Ground-truth tracks CSV: adds the scores to summary.json");
  track->add_option("--roi", t->roi, "Region of interest x,y,width,height in px")->delimiter(',')->expected(4);
  track->add_option("--first", t->first, "First frame")->capture_default_str();
  track->add_option("--last", t->last, "Last frame (-1: to the end)")->capture_default_str();
  track->add_option("--linker", t->linker, "global or paper (overrides the config)")->check(CLI::IsMember({"global", "paper"}));
  track->add_option("--smooth", t->smooth,
                    "Half-width in frames of the quadratic fit along each moving track (link.smooth_frames; 2 for particles carried by a "
                    "flow, 0 for Brownian motion)")
      ->check(CLI::Range(0, 10));
  track->add_flag("--no-background", t->no_background, "Do not subtract the median background (to count stuck particles)");
  track->add_flag("--quiet", t->quiet, "No progress bar");
  // trackpy's parameter names (docs/trackpy-mapping.md says which keys each sets).
  track->add_option("--diameter", t->diameter, "trackpy: feature diameter, px (odd); sets trackpy's locate (band pass, disc centroid and mass, separation)");
  track->add_option("--minmass", t->minmass, "trackpy: smallest integrated brightness, trackpy's units for 8-bit frames (detect.min_mass_relative x 255)");
  track->add_option("--separation", t->separation, "trackpy: smallest distance between features, px (detect.separation; default with --diameter: diameter + 1)");
  track->add_option("--search-range", t->search_range, "trackpy: largest displacement per frame, px (link.search_radius)");
  track->add_option("--memory", t->memory, "trackpy: frames a particle may vanish and keep its id (link.memory)");
  track->add_option("--threads", t->threads, "Frames decoded and detected in parallel (detect.threads; default 0: every core; results do not depend on it)");
  track->add_flag("--invert", t->invert, "trackpy: dark features on a bright background (detect.polarity = \"dark\"; mmval otherwise guesses)");
  track->add_option("--set", t->set, "KEY=VALUE: set any key of a tracking-video case as if the --config file said KEY = VALUE (repeatable)")
      ->allow_extra_args(false);
  track->callback([t, &registry, pixel_opt, fps_opt] {
    // Given values are checked here, so a bad --fps is named as bad, not reported as missing.
    if (pixel_opt->count() > 0)
      requireOptionValue("--pixel-size-um", t->pixel_um, 0, true, 1e6, "a pixel size in micrometres, finite and > 0 (e.g. --pixel-size-um 0.65)");
    if (fps_opt->count() > 0) requireOptionValue("--fps", t->fps, 0, true, 1e9, "a frame rate in frames per second, finite and > 0 (e.g. --fps 20)");
    if (t->first < 0) throw InputError({}, "option --first has an invalid value", fmt::format("--first {}", t->first), "a frame number >= 0");
    if (t->last < -1) throw InputError({}, "option --last has an invalid value", fmt::format("--last {}", t->last), "a frame number >= --first, or -1 for the end");
    if (t->last >= 0 && t->last < t->first)
      throw InputError({}, "the frame range is empty", fmt::format("--first {} --last {}", t->first, t->last), "--last >= --first, or -1 for the end");
    if (!t->roi.empty() && (t->roi[0] < 0 || t->roi[1] < 0 || t->roi[2] <= 0 || t->roi[3] <= 0))
      throw InputError({}, "option --roi has an invalid value", fmt::format("--roi {},{},{},{}", t->roi[0], t->roi[1], t->roi[2], t->roi[3]),
                       "x,y >= 0 and width,height > 0 in px");
    // The settings are a tracking-video case: from --config, or the defaults.
    std::string text;
    fs::path file = "(command line)";
    if (!t->config.empty()) {
      file = t->config;
      const Case probe = Case::load(file, registry);
      if (probe.kind() != "tracking-video")
        throw InputError(probe.where("case.kind"), "a --config file must be a tracking-video case", probe.kind(), "kind = \"tracking-video\"");
    }
    std::vector<CaseOverride> overrides;
    for (const auto& text : t->set) overrides.push_back(CaseOverride::parse(text));
    // The trackpy-style flags are checked before the case, and may not contradict a --set.
    const auto trackpy = trackpyKeys(*t);
    for (const auto& [flag, kv] : trackpy)
      for (const auto& o : overrides)
        if (o.key == kv.first)
          throw InputError({}, fmt::format("options {} and --set {} both set {}", flag, o.text(), o.key), fmt::format("--set {}", o.text()),
                           fmt::format("one of them (docs/trackpy-mapping.md lists the keys {} sets)", flag));
    Case c = t->config.empty() ? Case::parse("[case]\nname = \"track\"\nkind = \"tracking-video\"\n", file, registry, overrides)
                               : Case::load(file, registry, overrides);
    for (const auto& [flag, kv] : trackpy) c.set(kv.first, kv.second);
    c.set("inputs.video", fs::absolute(t->input).string());
    if (pixel_opt->count() > 0) c.set("inputs.pixel_size", t->pixel_um * 1e-6);
    if (fps_opt->count() > 0) c.set("inputs.frame_rate", t->fps);
    if (!t->truth.empty()) c.set("inputs.truth", fs::absolute(t->truth).string());
    if (!t->roi.empty()) c.set("inputs.roi", std::vector<std::int64_t>(t->roi.begin(), t->roi.end()));
    c.set("inputs.first_frame", static_cast<std::int64_t>(t->first));
    c.set("inputs.last_frame", static_cast<std::int64_t>(t->last));
    if (!t->linker.empty()) c.set("link.method", t->linker);
    if (t->no_background) c.set("detect.subtract_background", false);
    if (t->smooth >= 0) c.set("link.smooth_frames", static_cast<std::int64_t>(t->smooth));
    const RunSummary s = runCaseWith(c, tracking::runTrackingVideo, t->out, {t->quiet, false});
    for (const auto& m : s.metrics) std::printf("%-20s %12.5g %s\n", m.name.c_str(), m.value, m.unit.c_str());
    if (detailInteger(resultDetails(s.result), DetailField::detections).value_or(1) == 0)
      std::fprintf(stderr, "mmval: warning: no particles found in %s; check the polarity (--config detect.polarity), "
                           "the threshold and the background removal (--no-background)\n", t->input.c_str());
    std::printf("track: %s in %.1f s\n", t->out.c_str(), s.wall_seconds);
  });

  auto sy = std::make_shared<SynthCli>();
  CLI::App* synth = app.add_subcommand("synth", "Write a synthetic video with its ground truth (truth.csv): micromodel flow, or Brownian particles in a slab");
  synth->add_option("--out", sy->out, "Output folder")->required();
  synth->add_option("--scene", sy->scene,
                    "flow (micromodel flow past grains), brownian-slab (3D diffusion in a slab, depth-dependent defocus, drift, flicker) or "
                    "brightfield-rings (ring-shaped colloids: bright centre, dark ring, halo; Brownian, illumination gradient, static specks) or "
                    "large-discs (bright-rimmed discs of radius 40-60 px with darker interiors, Brownian; track with --diameter 101)")
      ->check(CLI::IsMember({"flow", "brownian-slab", "brightfield-rings", "large-discs"}))
      ->capture_default_str();
  synth->add_option("--format", sy->format, "Frames as png (8-bit grey), rgba (RGBA PNG), tiff16 (16-bit grey TIFF) or mp4 (one lossy video.mp4)")
      ->check(CLI::IsMember({"png", "rgba", "tiff16", "mp4"}))
      ->capture_default_str();
  sy->width = synth->add_option("--width", sy->o.width, "px (brownian-slab: 640)")->capture_default_str()->check(CLI::Range(32, 8192));
  sy->height = synth->add_option("--height", sy->o.height, "px (brownian-slab: 424)")->capture_default_str()->check(CLI::Range(32, 8192));
  sy->frames = synth->add_option("--frames", sy->o.frames, "Frames (brownian-slab: 300)")->capture_default_str()->check(CLI::Range(2, 1000000));
  sy->fps = synth->add_option("--fps", sy->o.fps, "Frames per second (brownian-slab: 24)")->capture_default_str();
  sy->pixel = synth->add_option("--pixel-size-um", sy->pixel_um, "Pixel size (brownian-slab: 0.15)")->capture_default_str();
  sy->particles = synth->add_option("--particles", sy->o.particles, "Moving particles (brownian-slab: 600, mean number in view at all depths)")
                      ->capture_default_str()
                      ->check(CLI::Range(0, 1000000));
  sy->flow_only.push_back(synth->add_option("--immobile", sy->o.immobile, "Particles stuck from the start")->capture_default_str()->check(CLI::Range(0, 1000000)));
  sy->flow_only.push_back(synth->add_option("--grains", sy->o.grains, "Grains")->capture_default_str()->check(CLI::Range(0, 10000)));
  sy->flow_only.push_back(synth->add_option("--speed", sy->o.speed, "Flow speed, px per frame")->capture_default_str());
  sy->noise = synth->add_option("--noise", sy->o.noise, "Camera noise, fraction of full scale (brownian-slab: 0.01 read noise)")->capture_default_str();
  synth->add_option("--seed", sy->o.seed, "Random seed")->capture_default_str();
  sy->flow_only.push_back(synth->add_option("--geometry", sy->geometry, "Binary pore image: grains from it, particles carried by its Stokes flow (mmval's solver)"));
  sy->flow_only.push_back(
      synth->add_option("--grain-pixels", sy->grains, "Which pixels of --geometry are grains")->check(CLI::IsMember({"dark", "bright"}))->capture_default_str());
  CLI::Option* snr_opt = synth->add_option("--snr", sy->snr, "Signal-to-noise ratio (spot amplitude / noise std); overrides --noise");
  sy->flow_only.push_back(snr_opt);
  addSlabOptions(synth, *sy);
  addRingOptions(synth, *sy);
  synth->callback([sy, snr_opt] {
    // NaN passes CLI11's range checks and would write NaN times: every real option is checked here (exit 2).
    requireOptionValue("--fps", sy->o.fps, 0, true, 1e9, "a frame rate in frames per second, finite and > 0 (e.g. --fps 10)");
    requireOptionValue("--pixel-size-um", sy->pixel_um, 0, true, 1e6, "a pixel size in micrometres, finite and > 0");
    requireOptionValue("--speed", sy->o.speed, 0, false, 1e6, "a flow speed in px per frame, finite and >= 0");
    requireOptionValue("--noise", sy->o.noise, 0, false, 0.5, "a camera noise between 0 and 0.5 of full scale");
    // Each scene's own options are refused in the other, rather than silently ignored.
    const bool slab = sy->scene == "brownian-slab", rings = sy->scene == "brightfield-rings";
    const std::pair<const std::vector<CLI::Option*>*, const char*> groups[] = {
        {&sy->flow_only, "flow"}, {&sy->slab_only, "brownian-slab"}, {&sy->rings_only, "brightfield-rings"}};
    for (const auto& [options, scene] : groups)
      if (sy->scene != scene)
        for (CLI::Option* opt : *options)
          if (opt->count() > 0)
            throw InputError({}, fmt::format("option {} does not apply to --scene {}", opt->get_name(), sy->scene), opt->get_name(),
                             fmt::format("--scene {} for it, or leave it out", scene));
    if (rings) {
      runRingScene(*sy);
      return;
    }
    if (sy->scene == "large-discs") {
      runDiscScene(*sy);
      return;
    }
    if (slab) {
      runBrownianSlab(*sy);
      return;
    }
    sy->o.format = tracking::parseSynthFormat(sy->format);
    if (snr_opt->count() > 0) requireOptionValue("--snr", sy->snr, 0, true, 1e12, "a signal-to-noise ratio, finite and > 0");
    sy->o.pixel_size = sy->pixel_um * 1e-6;
    if (sy->snr > 0) sy->o.noise = sy->o.spot_amplitude / sy->snr;
    std::unique_ptr<simulate::PoreFlowMap> flow;
    if (!sy->geometry.empty()) {
      // The image's size from its header, before decoding. synth --geometry peaks at 11.6 B per mask
      // pixel above ~0.5 GB (measured with /usr/bin/time -v: 3000^2 and 6000^2 masks, 588 and 902 MB);
      // the pore analysis' flood-fill stack of the mirrored mask adds up to 8 B/px on an open image.
      constexpr double kSynthGeometryBytesPerPixel = 20;
      requireImageWithin(sy->geometry, {sy->geometry, 0, 0, "--geometry"}, defaultMaxMemoryBytes(), kSynthGeometryBytesPerPixel,
                         "a smaller image (the flow is solved on ~40000 cells whatever its size): crop or downscale it");
      const cv::Mat img = cv::imread(sy->geometry, cv::IMREAD_GRAYSCALE);
      if (img.empty()) throw InputError({sy->geometry, 0, 0, "--geometry"}, "cannot read the image", {}, "a PNG or TIFF mask");
      cv::threshold(img, sy->o.geometry, 127, 255, sy->grains == "dark" ? cv::THRESH_BINARY_INV : cv::THRESH_BINARY);
      try {
        flow = std::make_unique<simulate::PoreFlowMap>(sy->o.geometry, sy->o.speed);
      } catch (const std::runtime_error& e) {
        throw InputError({sy->geometry, 0, 0, "--geometry"}, e.what(), {}, "an image with a connected pore path from the left to the right edge");
      }
      sy->o.flow = [f = flow.get()](double x, double y) { return f->at(x, y); };
    }
    StagedDirectory staged(sy->out);
    const auto r = tracking::writeSyntheticVideo(sy->o, staged.path());
    staged.commit();
    std::printf("synth: %d frames, %d moving, %d depositing, %d immobile -> %s, truth.csv\n", sy->o.frames, r.moving, r.deposited,
                r.immobile, sy->out.c_str());
  });
}

}  // namespace mmval::app
