#include "TrackCommands.hpp"

#include <cstdio>
#include <memory>
#include <utility>

#include <fmt/format.h>

#include "mmval/core/Case.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/SynthFlow.hpp"
#include "mmval/tracking/Kinds.hpp"
#include "mmval/tracking/SynthScenes.hpp"
#include "mmval/tracking/TrackpyFlags.hpp"

namespace mmval::app {

namespace {

struct TrackCli {
  tracking::TrackFlags flags;  ///< the flags that become case keys
  std::string out;
  double pixel_um = 0, fps = 0;
  bool quiet = false;
};

struct SynthCli {
  std::string out, geometry, grains = "dark", scene = "flow", format = "png";
  double snr = 0;
  tracking::SynthOptions o;
  double pixel_um = 1;
  tracking::BrownianSlabOptions slab;  ///< --scene brownian-slab; its defaults are the real video's class
  std::vector<double> drift_um_s, drift_change_um_s2;
  bool bright_particles = false;
  /// Options shared by both scenes, whose defaults differ (the slab takes its own unless given).
  CLI::Option *width = nullptr, *height = nullptr, *frames = nullptr, *fps = nullptr, *pixel = nullptr, *particles = nullptr, *noise = nullptr;
  CLI::Option *diffusion = nullptr, *temperature = nullptr, *viscosity = nullptr, *bright = nullptr, *snr_opt = nullptr;
  std::vector<CLI::Option*> flow_only, slab_only;
  tracking::RingSceneOptions rings;  ///< --scene brightfield-rings; its defaults are the real video's class
  std::vector<CLI::Option*> rings_only;
};

/// The shared options given on the command line (a scene keeps its own default for the others).
tracking::SynthSharedSettings sharedSettings(const SynthCli& sy) {
  tracking::SynthSharedSettings s;
  if (sy.width->count() > 0) s.width = sy.o.width;
  if (sy.height->count() > 0) s.height = sy.o.height;
  if (sy.frames->count() > 0) s.frames = sy.o.frames;
  if (sy.fps->count() > 0) s.fps_hz = sy.o.fps;
  if (sy.pixel->count() > 0) s.pixel_size_um = sy.pixel_um;
  if (sy.particles->count() > 0) s.particles = sy.o.particles;
  if (sy.noise->count() > 0) s.noise = sy.o.noise;
  s.seed = sy.o.seed;
  s.format = tracking::parseSynthFormat(sy.format);
  return s;
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

/// The ring scene's own options (synth --scene brightfield-rings; SynthRings.hpp).
void addRingOptions(CLI::App* synth, SynthCli& sy) {
  auto& r = sy.rings;
  auto ring = [&](CLI::Option* opt) { sy.rings_only.push_back(opt->capture_default_str()); };
  ring(synth->add_option("--ring-radius-px", r.ring_radius_px, "brightfield-rings: radius of the dark ring"));
  ring(synth->add_option("--diffusion-px2", r.diffusion_px2, "brightfield-rings: diffusion coefficient in px^2 per frame"));
  ring(synth->add_option("--illumination-gradient", r.illumination_gradient, "brightfield-rings: brightness falls by this fraction from left to right"));
  ring(synth->add_option("--specks", r.static_specks, "brightfield-rings: static dark specks (dust on the optics)")->check(CLI::Range(0, 1000)));
}

// Each scene: the command line's values as the scene's settings, one library call, one summary line.

void runBrownianSlab(const SynthCli& sy) {
  tracking::SlabSceneSettings s;
  s.slab = sy.slab;
  tracking::applySharedSettings(sharedSettings(sy), s.slab);
  s.slab.dark_particles = !sy.bright_particles;
  s.diffusion_given = sy.diffusion->count() > 0;
  s.stokes_einstein_given = sy.temperature->count() > 0 || sy.viscosity->count() > 0;
  if (!sy.drift_um_s.empty()) s.slab.drift_um_s = {sy.drift_um_s[0], sy.drift_um_s[1]};
  if (!sy.drift_change_um_s2.empty()) s.slab.drift_change_um_s2 = {sy.drift_change_um_s2[0], sy.drift_change_um_s2[1]};
  const auto r = tracking::writeSlabScene(s, sy.out);
  std::printf("synth: %d frames (%s), Brownian slab with D %.4g um^2/s: %.0f particles per frame in view, %.0f in focus, %lld distinct -> %s, truth.csv, truth_in_focus.csv, truth.json\n",
              s.slab.frames, sy.format.c_str(), r.diffusion_um2_s, r.mean_in_view, r.mean_in_focus, static_cast<long long>(r.distinct_in_view), sy.out.c_str());
}

void runRingScene(const SynthCli& sy) {
  tracking::RingSceneOptions r = sy.rings;
  tracking::applySharedSettings(sharedSettings(sy), r);
  tracking::writeRingSceneFolder(r, sy.out);
  std::printf("synth: %d frames (%s), %d brightfield ring colloids of ring radius %g px -> %s, truth.csv, truth.json\n", r.frames, sy.format.c_str(),
              r.particles, r.ring_radius_px, sy.out.c_str());
}

void runDiscScene(const SynthCli& sy) {
  tracking::DiscSceneOptions d;
  tracking::applySharedSettings(sharedSettings(sy), d);
  tracking::writeDiscSceneFolder(d, sy.out);
  std::printf("synth: %d frames (%s), %d large discs of radius %g-%g px -> %s, truth.csv, truth.json (track them with --diameter %d)\n", d.frames,
              sy.format.c_str(), d.particles, d.radius_min_px, d.radius_max_px, sy.out.c_str(),
              static_cast<int>(d.radius_min_px + d.radius_max_px) + 1);
}

void runFlowScene(const SynthCli& sy) {
  tracking::FlowSceneSettings f;
  f.video = sy.o;
  tracking::applySharedSettings(sharedSettings(sy), f.video);
  if (sy.snr_opt->count() > 0) f.snr = sy.snr;
  f.geometry = sy.geometry;
  f.dark_grains = sy.grains == "dark";
  const auto r = tracking::writeFlowScene(f, sy.out, simulate::synthPoreFlow);
  std::printf("synth: %d frames, %d moving, %d depositing, %d immobile -> %s, truth.csv\n", f.video.frames, r.moving, r.deposited, r.immobile,
              sy.out.c_str());
}

}  // namespace

void registerTrackCommands(CLI::App& app, const CaseKindRegistry& registry) {
  auto t = std::make_shared<TrackCli>();
  CLI::App* track = app.add_subcommand("track", "Track particles in a microscope video: tracks, velocities, dispersion, retention, streamlines");
  track->add_option("input", t->flags.input, "Video, image folder, glob (quoted) or multi-page TIFF")->required();
  track->add_option("--out", t->out, "Output folder")->required();
  CLI::Option* pixel_opt = track->add_option("--pixel-size-um", t->pixel_um, "Pixel size in micrometres (or inputs.pixel_size in --config)");
  CLI::Option* fps_opt = track->add_option("--fps", t->fps, "Frames per second (or inputs.frame_rate in --config)");
  track->add_option("--config", t->flags.config, "A tracking-video case file with [detect], [link], [analysis] settings (see `mmval case-doc tracking-video`)");
  track->add_option("--truth", t->flags.truth, "Ground-truth tracks CSV: adds the scores to summary.json");
  track->add_option("--roi", t->flags.roi, "Region of interest x,y,width,height in px")->delimiter(',')->expected(4);
  track->add_option("--first", t->flags.first, "First frame")->capture_default_str();
  track->add_option("--last", t->flags.last, "Last frame (-1: to the end)")->capture_default_str();
  track->add_option("--linker", t->flags.linker, "global or paper (overrides the config)")->check(CLI::IsMember({"global", "paper"}));
  track->add_option("--smooth", t->flags.smooth,
                    "Half-width in frames of the quadratic fit along each moving track (link.smooth_frames; 2 for particles carried by a "
                    "flow, 0 for Brownian motion)")
      ->check(CLI::Range(0, 10));
  track->add_flag("--no-background", t->flags.no_background, "Do not subtract the median background (to count stuck particles)");
  track->add_flag("--quiet", t->quiet, "No progress bar");
  // trackpy's parameter names (docs/trackpy-mapping.md says which keys each sets).
  track->add_option("--diameter", t->flags.trackpy.diameter, "trackpy: feature diameter, px (odd); sets trackpy's locate (band pass, disc centroid and mass, separation)");
  track->add_option("--minmass", t->flags.trackpy.minmass, "trackpy: smallest integrated brightness, trackpy's units for 8-bit frames (detect.min_mass_relative x 255)");
  track->add_option("--separation", t->flags.trackpy.separation, "trackpy: smallest distance between features, px (detect.separation; default with --diameter: diameter + 1)");
  track->add_option("--search-range", t->flags.trackpy.search_range, "trackpy: largest displacement per frame, px (link.search_radius)");
  track->add_option("--memory", t->flags.trackpy.memory, "trackpy: frames a particle may vanish and keep its id (link.memory)");
  track->add_option("--threads", t->flags.trackpy.threads, "Frames decoded and detected in parallel (detect.threads; default 0: every core; results do not depend on it)");
  track->add_flag("--invert", t->flags.trackpy.invert, "trackpy: dark features on a bright background (detect.polarity = \"dark\"; mmval otherwise guesses)");
  track->add_option("--set", t->flags.set, "KEY=VALUE: set any key of a tracking-video case as if the --config file said KEY = VALUE (repeatable)")
      ->allow_extra_args(false);
  track->callback([t, &registry, pixel_opt, fps_opt] {
    if (pixel_opt->count() > 0) t->flags.pixel_size_um = t->pixel_um;
    if (fps_opt->count() > 0) t->flags.fps_hz = t->fps;
    const Case c = tracking::trackingVideoCase(t->flags, registry);
    const RunSummary s = runCaseWith(c, tracking::runTrackingVideo, t->out, {t->quiet, false});
    for (const auto& m : s.metrics) std::printf("%-20s %12.5g %s\n", m.name.c_str(), m.value, m.unit.c_str());
    if (detailInteger(resultDetails(s.result), DetailField::detections).value_or(1) == 0)
      std::fprintf(stderr, "mmval: warning: no particles found in %s; check the polarity (--config detect.polarity), "
                           "the threshold and the background removal (--no-background)\n", t->flags.input.c_str());
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
      synth->add_option("--grain-pixels", sy->grains, "Which pixels of --geometry are grains (as geometry.grains in a case)")->check(CLI::IsMember({"dark", "bright"}))->capture_default_str());
  sy->snr_opt = synth->add_option("--snr", sy->snr, "Signal-to-noise ratio (spot amplitude / noise std); overrides --noise");
  sy->flow_only.push_back(sy->snr_opt);
  addSlabOptions(synth, *sy);
  addRingOptions(synth, *sy);
  synth->callback([sy] {
    tracking::checkSynthSharedSettings(sharedSettings(*sy), sy->o.speed);
    // Each scene's own options are refused in the other, rather than silently ignored.
    const std::pair<const std::vector<CLI::Option*>*, const char*> groups[] = {
        {&sy->flow_only, "flow"}, {&sy->slab_only, "brownian-slab"}, {&sy->rings_only, "brightfield-rings"}};
    for (const auto& [options, scene] : groups)
      if (sy->scene != scene)
        for (CLI::Option* opt : *options)
          if (opt->count() > 0)
            throw InputError({}, fmt::format("option {} does not apply to --scene {}", opt->get_name(), sy->scene), opt->get_name(),
                             fmt::format("--scene {} for it, or leave it out", scene));
    if (sy->scene == "brightfield-rings")
      runRingScene(*sy);
    else if (sy->scene == "large-discs")
      runDiscScene(*sy);
    else if (sy->scene == "brownian-slab")
      runBrownianSlab(*sy);
    else
      runFlowScene(*sy);
  });
}

}  // namespace mmval::app
