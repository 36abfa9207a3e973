#include "TrackCommands.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/tracking/Kinds.hpp"
#include "mmval/tracking/Synth.hpp"
#include "SynthFlow.hpp"

namespace fs = std::filesystem;

namespace mmval::app {

namespace {

struct TrackCli {
  std::string input, config, out, truth, linker;
  double pixel_um = 0, fps = 0;
  std::vector<int> roi;
  int first = 0, last = -1, smooth = -1;
  bool quiet = false, no_background = false;
};

struct SynthCli {
  std::string out, geometry, grains = "dark";
  double amplitude = 0.35, snr = 0;
  tracking::SynthOptions o;
  double pixel_um = 1;
};

/// A real-valued option given on the command line must be finite and in its range; NaN and
/// infinities pass CLI11's own range checks (every comparison with NaN is false), and a bad
/// value must not be mistaken for a missing one. Exit 2 naming the option, the value and the rule.
void requireOptionValue(const char* option, double value, double lo, bool lo_open, double hi, const std::string& expected) {
  const bool ok = std::isfinite(value) && (lo_open ? value > lo : value >= lo) && value <= hi;
  if (!ok) throw InputError({}, fmt::format("option {} has an invalid value", option), fmt::format("{} {:g}", option, value), expected);
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
  track->callback([t, &registry, pixel_opt, fps_opt] {
    // Given values are checked here, not mistaken for absent ones (a bad --fps used to read "missing").
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
    Case c = t->config.empty() ? Case::parse("[case]\nname = \"track\"\nkind = \"tracking-video\"\n", file, registry) : Case::load(file, registry);
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
    if (s.result["details"].value("detections", 1) == 0)
      std::fprintf(stderr, "mmval: warning: no particles found in %s; check the polarity (--config detect.polarity), "
                           "the threshold and the background removal (--no-background)\n", t->input.c_str());
    std::printf("track: %s in %.1f s\n", t->out.c_str(), s.wall_seconds);
  });

  auto sy = std::make_shared<SynthCli>();
  CLI::App* synth = app.add_subcommand("synth", "Write a synthetic micromodel video (PNG frames) with its ground truth (truth.csv)");
  synth->add_option("--out", sy->out, "Output folder")->required();
  synth->add_option("--width", sy->o.width, "px")->capture_default_str()->check(CLI::Range(32, 8192));
  synth->add_option("--height", sy->o.height, "px")->capture_default_str()->check(CLI::Range(32, 8192));
  synth->add_option("--frames", sy->o.frames, "Frames")->capture_default_str()->check(CLI::Range(2, 1000000));
  synth->add_option("--fps", sy->o.fps, "Frames per second")->capture_default_str();
  synth->add_option("--pixel-size-um", sy->pixel_um, "Pixel size")->capture_default_str();
  synth->add_option("--particles", sy->o.particles, "Moving particles")->capture_default_str()->check(CLI::Range(0, 1000000));
  synth->add_option("--immobile", sy->o.immobile, "Particles stuck from the start")->capture_default_str()->check(CLI::Range(0, 1000000));
  synth->add_option("--grains", sy->o.grains, "Grains")->capture_default_str()->check(CLI::Range(0, 10000));
  synth->add_option("--speed", sy->o.speed, "Flow speed, px per frame")->capture_default_str();
  synth->add_option("--noise", sy->o.noise, "Camera noise, fraction of full scale")->capture_default_str();
  synth->add_option("--seed", sy->o.seed, "Random seed")->capture_default_str();
  synth->add_option("--geometry", sy->geometry, "Binary pore image: grains from it, particles carried by its Stokes flow (mmval's solver)");
  synth->add_option("--grain-pixels", sy->grains, "Which pixels of --geometry are grains")->check(CLI::IsMember({"dark", "bright"}))->capture_default_str();
  CLI::Option* snr_opt = synth->add_option("--snr", sy->snr, "Signal-to-noise ratio (spot amplitude / noise std); overrides --noise");
  synth->callback([sy, snr_opt] {
    // NaN passes CLI11's range checks and used to write NaN times: every real option is checked here (exit 2).
    requireOptionValue("--fps", sy->o.fps, 0, true, 1e9, "a frame rate in frames per second, finite and > 0 (e.g. --fps 10)");
    requireOptionValue("--pixel-size-um", sy->pixel_um, 0, true, 1e6, "a pixel size in micrometres, finite and > 0");
    requireOptionValue("--speed", sy->o.speed, 0, false, 1e6, "a flow speed in px per frame, finite and >= 0");
    requireOptionValue("--noise", sy->o.noise, 0, false, 0.5, "a camera noise between 0 and 0.5 of full scale");
    if (snr_opt->count() > 0) requireOptionValue("--snr", sy->snr, 0, true, 1e12, "a signal-to-noise ratio, finite and > 0");
    sy->o.pixel_size = sy->pixel_um * 1e-6;
    if (sy->snr > 0) sy->o.noise = sy->o.spot_amplitude / sy->snr;
    std::unique_ptr<PoreFlowMap> flow;
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
        flow = std::make_unique<PoreFlowMap>(sy->o.geometry, sy->o.speed);
      } catch (const std::runtime_error& e) {
        throw InputError({sy->geometry, 0, 0, "--geometry"}, e.what(), {}, "an image with a connected pore path from the left to the right edge");
      }
      sy->o.flow = [f = flow.get()](double x, double y) { return f->at(x, y); };
    }
    StagedDirectory staged(sy->out);
    const auto r = tracking::writeSyntheticVideo(sy->o, staged.path());
    staged.commit();
    std::printf("synth: %zu frames, %d moving, %d depositing, %d immobile -> %s/frames, truth.csv\n", r.frames.size(), r.moving, r.deposited,
                r.immobile, sy->out.c_str());
  });
}

}  // namespace mmval::app
