#include "mmval/tracking/Kinds.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "InputLimits.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/tracking/KindMetrics.hpp"
#include "mmval/tracking/Score.hpp"
#include "mmval/tracking/Synth.hpp"

namespace mmval::tracking {

namespace {

/// analysis.exposure is part of one frame interval.
void requireExposureWithinFrame(const Case& c, const TrackConfig& cfg) {
  if (cfg.analysis.brownian.exposure > 1.0 / cfg.fps * (1 + 1e-9))
    throw InputError(c.where("analysis.exposure"), "the exposure is longer than the frame interval",
                     fmt::format("{:g} s at {:g} frames/s", cfg.analysis.brownian.exposure, cfg.fps),
                     fmt::format("at most {:g} s (1 / frame rate)", 1.0 / cfg.fps));
}

Linker parseLinker(const std::string& s) { return s == "paper" ? Linker::paper : Linker::global; }

Prediction parsePrediction(const std::string& s) {
  return s == "none" ? Prediction::none : s == "velocity" ? Prediction::velocity : s == "neighbours" ? Prediction::neighbours : Prediction::automatic;
}

/// The choice that `parse` reads as `value`: a choice key's default named by the same
/// parser that reads the case, so that the struct's enum default is the only one.
template <class Enum, class Parse>
std::string choiceOf(const std::vector<std::string>& choices, Enum value, Parse parse) {
  for (const std::string& name : choices)
    if (parse(name) == value) return name;
  throw std::logic_error("the option struct's default is none of the schema's choices");
}

/// analysis.motion, link.predict and the Brownian analysis keys, their defaults those of
/// the option structs.
void declareMotionKeys(Schema& s) {
  const TrackConfig config_defaults{};
  const TrackOptions& defaults = config_defaults.analysis;
  const std::vector<std::string> predictions = {"auto", "none", "velocity", "neighbours"};
  s.choice("analysis.motion", {"auto", "flow", "brownian"},
           "How tracks are analysed: flow (particles carried by a flow: velocities, dispersion, retention, deposits, speed maps) or brownian "
           "(diffusing: ensemble drift removed, MSD fitted with a localisation-error and motion-blur term for D and its exponent, per-track D "
           "by the covariance-based estimator, immobile by a statistical test); auto decides from the tracks (directed or carried steps: "
           "flow) and says why in summary.json")
      .def(motionModelName(defaults.motion));
  s.choice("link.predict", predictions,
           "Where a track is looked for in the next frame: where it was (none), one step along its own smoothed velocity (velocity), or "
           "also, for a track too new to have one, along its neighbours' within link.neighbour_radius (neighbours); auto: none for Brownian "
           "motion, otherwise velocity (neighbours when link.neighbour_radius > 0)")
      .def(choiceOf(predictions, config_defaults.link.predict, parsePrediction));
  s.quantity("analysis.exposure", "s",
             "Brownian: camera exposure per frame (motion blur, at most the frame interval); 0: instantaneous. D does not depend on it; with 0 "
             "the blur reads as a smaller localisation error")
      .def(defaults.brownian.exposure)
      .nonNegative();
  s.integer("analysis.brownian_min_points", "Brownian: tracks with fewer points are short, in no D estimate (a 10-point track's D has ~60 % error)")
      .def(defaults.brownian.min_points)
      .min(3)
      .max(100000);
  s.integer("analysis.msd_lags",
            "Brownian: lags of the MSD fit for D (0: the number that gives D the smallest standard error, Michalet 2010)")
      .def(defaults.brownian.max_lag)
      .min(0)
      .max(1000);
  s.real("analysis.immobile_level",
         "Brownian: a track is immobile when its D is below the ensemble D and not above 0, each one-sided at this significance level (at "
         "most the share of free particles called immobile)")
      .def(defaults.brownian.immobile_level)
      .min(1e-6)
      .max(0.5);
}

}  // namespace

void addSceneDecisions(const TrackRun& run, nlohmann::json& summary) {
  const BackgroundDecision& b = run.background_decision;
  summary["background"] = {{"requested", b.requested}, {"subtracted", b.subtract}, {"reason", b.reason}};
  if (b.frames_compared > 0)
    summary["background"]["numbers"] = {{"frames_compared", b.frames_compared}, {"spots_per_frame", b.spots_per_frame},
                                        {"spots_in_median", b.spots_in_median}, {"static_share", b.static_share}, {"persistent_spots", b.persistent_spots}, {"moving_energy_share", b.moving_energy_share},
                                        {"static_share_limit", kStaticShareLimit}};
  summary["detection"] = {{"polarity", polarityName(run.polarity)}, {"reason", run.polarity_reason}};
  if (run.ring.candidates > 0 || run.ring.rings)
    summary["detection"]["rings"] = {{"found", run.ring.rings}, {"bright_spots", run.ring.candidates}, {"ringed", run.ring.ringed},
                                     {"dark_centred_rings", run.ring.dark_ringed}, {"share", run.ring.share}, {"ring_radius_px", run.ring.radius_px}};
}

void declareTrackerKeys(Schema& s) {
  // The option structs hold the defaults; each key's default is taken from them.
  const TrackConfig defaults{};
  const DetectOptions& detect = defaults.detect;
  const LinkOptions& link = defaults.link;
  const std::vector<std::string> thresholds = {"otsu", "manual", "adaptive"};
  const std::vector<std::string> morphologies = {"none", "erode", "dilate", "open", "close"};
  const std::vector<std::string> refinements = {"intensity", "disc", "moments", "gaussian"};
  const std::vector<std::string> seed_methods = {"contours", "peaks"};
  const std::vector<std::string> linkers = {"global", "paper"};
  s.choice("detect.background", {"auto", "median", "none"},
           "Static background: the temporal median of sampled frames subtracted (median: grains, stuck particles, uneven illumination "
           "vanish), not (none), or auto: not when more than half of the round spots of sampled frames sit on spots of the median (the "
           "particles barely move, so the median is the particles), nor for ring colloids when no spot of the median recurs in 3/4 of "
           "the frames (nothing static; the median would hold ghosts of slow rings); otherwise subtracted. When auto decides against it a spatial "
           "high-pass of refine_radius evens the illumination. summary.json \"background\" says which, with its numbers and why")
      .def(backgroundModeName(detect.background_mode));
  s.boolean("detect.subtract_background", "Older switch of the background: true is detect.background = \"median\", false \"none\" (wins over it)")
      .optional();
  s.choice("detect.polarity", {"auto", "dark", "bright", "ring"},
           "Particles darker or brighter than the background, or ring-shaped brightfield colloids (bright centre inside a dark ring, "
           "detected at the centre by a matched filter of their measured profile); auto recognises rings first, then takes the side of "
           "the moving foreground. summary.json \"detection\" says which and why")
      .def(polarityName(detect.polarity));
  s.real("detect.blur_sigma", "Gaussian blur, px (0: none)").def(detect.blur_sigma).min(0).max(20);
  s.choice("detect.threshold", thresholds, "Threshold method").def(choiceOf(thresholds, detect.threshold, parseThreshold));
  s.real("detect.threshold_value", "Manual threshold, fraction of full scale of the background-removed signal").def(detect.threshold_value).min(0).max(1);
  s.choice("detect.morphology", morphologies, "Morphological operation after the threshold")
      .def(choiceOf(morphologies, detect.morphology, parseMorphology));
  s.integer("detect.kernel", "Morphology kernel, px (odd)").def(detect.kernel).min(1).max(51);
  s.integer("detect.iterations", "Morphology iterations").def(detect.iterations).min(0).max(20);
  s.real("detect.min_area", "Smallest blob, px^2").def(detect.min_area).min(0);
  s.real("detect.max_area", "Largest blob, px^2").def(detect.max_area).min(1);
  s.real("detect.min_circularity", "Smallest 4 pi A / P^2").def(detect.min_circularity).min(0).max(1);
  s.choice("detect.refinement", refinements,
           "Centroid: intensity-weighted under a Gaussian mask re-centred each iteration (intensity), over a flat disc of refine_radius "
           "(disc, Crocker & Grier), the contour's moments, or the intensity centroid then a least-squares fit of a Gaussian spot plus "
           "a constant (gaussian; slower, for well-separated spots)")
      .def(choiceOf(refinements, detect.refinement, parseRefinement));
  s.choice("detect.method", seed_methods,
           "Seeds: contours of the thresholded signal (the paper), or local maxima of the band-passed signal (splits touching particles)")
      .def(choiceOf(seed_methods, detect.method, parseSeedMethod));
  s.integer("detect.local_background", "Half-width of a boxcar local mean subtracted from the signal, px (0: none; ~ particle diameter)").def(detect.local_background).min(0).max(200);
  s.integer("detect.refine_radius", "Radius of the centroid window and of the mass, px").def(detect.refine_radius).min(1).max(50);
  s.integer("detect.separation", "peaks: smallest distance between two maxima, px (0: refine_radius)").def(detect.separation).min(0).max(100);
  s.real("detect.refine_sigma", "Sigma of the Gaussian mask of the intensity centroid, px (0: from the spots' size)").def(detect.refine_sigma).min(0).max(20);
  s.real("detect.min_mass", "Smallest integrated signal within refine_radius, fraction of full scale x px^2 (0: no filter)").def(detect.min_mass).min(0);
  s.real("detect.min_snr", "Smallest peak over the frame's robust noise floor (0: no filter)").def(detect.min_snr).min(0);
  s.real("detect.max_size_ratio",
         "Focus filter: drop spots whose measured sigma exceeds this multiple of the frame's modal (in-focus) sigma; blurred, "
         "out-of-focus particles are localised worse (0: off; docs/trackpy-mapping.md)")
      .def(detect.max_size_ratio)
      .min(0)
      .max(100);
  s.real("detect.min_mass_relative",
         "Smallest mass over the frame's brightest band-passed value, px^2: trackpy's minmass / 255 for 8-bit frames (/ 65535 for 16-bit), "
         "which trackpy sums on the band-passed frame rescaled to fill the integer range (0: no filter)")
      .def(detect.min_mass_relative)
      .min(0);
  s.real("detect.min_percentile", "peaks: maxima must exceed this percentile of the band-passed frame's pixels (trackpy's percentile; 0: off)")
      .def(detect.min_percentile)
      .min(0)
      .max(100);
  s.boolean("detect.deblend",
            "peaks + intensity: fit overlapping spots jointly, look for spots hidden beside brighter ones, split blobs two spots fit "
            "significantly better than one")
      .def(detect.deblend);
  s.boolean("detect.find_stuck",
            "Find particles at rest in the median background (black/top-hat spots the size of moving ones): stuck all video long "
            "(immobile), or arrived and deposited (joined to the track that brought them, which continues at rest to the end)")
      .def(detect.find_stuck);
  s.real("detect.background_quantile",
         "Per-pixel quantile of the sampled frames that is the static background (0.5: median; higher for dark particles that cover a pixel "
         "often, lower for bright ones)")
      .def(defaults.background_quantile)
      .min(0)
      .max(1);
  s.integer("detect.background_window",
            "Rolling background: frames per block, each with its own background, blended between blocks (long videos that drift); 0: one for "
            "the whole video")
      .def(defaults.background_window)
      .min(0);
  s.integer("detect.threads", "Frames decoded and detected in parallel (linking stays in frame order; results do not depend on it); 0: every core").def(defaults.threads).min(0).max(256);
  s.choice("link.method", linkers, "Linker: optimal assignment with gap closing, or the paper's distance + angle rule")
      .def(choiceOf(linkers, link.method, parseLinker));
  s.real("link.search_radius", "Search radius, px per frame").def(link.search_radius).min(0.1);
  s.integer("link.memory", "Frames a particle may be missed (gap closing)").def(link.memory).min(0).max(100);
  s.real("link.velocity_smoothing", "Weight of the previous velocity in the prediction's exponential filter (0: last step only)").def(link.velocity_smoothing).min(0).max(0.95);
  s.real("link.neighbour_radius",
         "px: a track too new to have a velocity predicts with the mean velocity of the tracks within this distance (particles in a "
         "pore flow follow nearby streamlines); 0: no prediction before its second point")
      .def(link.neighbour_radius)
      .min(0);
  s.integer("link.smooth_frames",
            "Half-width, frames, of a quadratic fit along each moving track that refines its positions (localisation error "
            "x 0.70 at 2, x 0.58 at 3); for particles carried by a flow, not for Brownian motion (0: positions as detected)")
      .def(defaults.smooth_frames)
      .min(0)
      .max(10);
  s.quantity("analysis.immobile_distance", "um", "Flow: particles that never move farther are immobile (left out of velocities)")
      .def(defaults.analysis.immobile_distance).nonNegative();
  s.quantity("analysis.stuck_distance", "um",
             "Moving less than this (plus what the track's own localisation noise explains) over the final window counts as deposited")
      .def(defaults.analysis.stuck_distance)
      .nonNegative();
  s.quantity("analysis.stuck_window", "s", "That final window").def(defaults.analysis.stuck_window).positive();
  declareMotionKeys(s);
}

TrackConfig trackerConfig(const Case& c) {
  TrackConfig t;
  t.detect.background_mode = parseBackgroundMode(c.text("detect.background"));
  if (c.has("detect.subtract_background"))
    t.detect.background_mode = c.flag("detect.subtract_background") ? BackgroundMode::median : BackgroundMode::none;
  t.detect.polarity = parsePolarity(c.text("detect.polarity"));
  t.detect.blur_sigma = c.real("detect.blur_sigma");
  t.detect.threshold = parseThreshold(c.text("detect.threshold"));
  t.detect.threshold_value = c.real("detect.threshold_value");
  t.detect.morphology = parseMorphology(c.text("detect.morphology"));
  t.detect.kernel = static_cast<int>(c.integer("detect.kernel"));
  t.detect.iterations = static_cast<int>(c.integer("detect.iterations"));
  t.detect.min_area = c.real("detect.min_area");
  t.detect.max_area = c.real("detect.max_area");
  t.detect.min_circularity = c.real("detect.min_circularity");
  t.detect.refinement = parseRefinement(c.text("detect.refinement"));
  t.detect.find_stuck = c.flag("detect.find_stuck");
  t.detect.deblend = c.flag("detect.deblend");
  t.detect.method = parseSeedMethod(c.text("detect.method"));
  t.detect.local_background = static_cast<int>(c.integer("detect.local_background"));
  t.detect.refine_radius = static_cast<int>(c.integer("detect.refine_radius"));
  t.detect.separation = static_cast<int>(c.integer("detect.separation"));
  t.detect.min_mass = c.real("detect.min_mass");
  t.detect.refine_sigma = c.real("detect.refine_sigma");
  t.detect.min_snr = c.real("detect.min_snr");
  t.detect.max_size_ratio = c.real("detect.max_size_ratio");
  t.detect.min_mass_relative = c.real("detect.min_mass_relative");
  t.detect.min_percentile = c.real("detect.min_percentile");
  t.threads = static_cast<int>(c.integer("detect.threads"));
  if (t.threads == 0) t.threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));  // reported as used
  t.background_quantile = c.real("detect.background_quantile");
  t.background_window = static_cast<int>(c.integer("detect.background_window"));
  t.link.method = parseLinker(c.text("link.method"));
  t.link.search_radius = c.real("link.search_radius");
  t.link.memory = static_cast<int>(c.integer("link.memory"));
  t.link.velocity_smoothing = c.real("link.velocity_smoothing");
  t.link.neighbour_radius = c.real("link.neighbour_radius");
  t.link.predict = parsePrediction(c.text("link.predict"));
  if (t.link.predict == Prediction::neighbours && !(t.link.neighbour_radius > 0))
    throw InputError(c.where("link.predict"), "prediction from the neighbours needs a neighbour radius", "neighbours with link.neighbour_radius = 0",
                     "link.neighbour_radius > 0 px (a few particle spacings), or link.predict = \"velocity\"");
  t.smooth_frames = static_cast<int>(c.integer("link.smooth_frames"));
  t.analysis.immobile_distance = c.quantity("analysis.immobile_distance");
  t.analysis.stuck_distance = c.quantity("analysis.stuck_distance");
  t.analysis.stuck_window = c.quantity("analysis.stuck_window");
  t.analysis.motion = parseMotionModel(c.text("analysis.motion"));
  t.analysis.brownian.exposure = c.quantity("analysis.exposure");
  t.analysis.brownian.min_points = static_cast<int>(c.integer("analysis.brownian_min_points"));
  t.analysis.brownian.max_lag = static_cast<int>(c.integer("analysis.msd_lags"));
  t.analysis.brownian.immobile_level = c.real("analysis.immobile_level");
  return t;
}

RunOutput runTrackingVideo(const Case& c, const RunContext& ctx) {
  if (!c.has("inputs.video"))
    throw InputError(c.where("inputs.video"), "no input video", {}, "inputs.video in the case, or INPUT on the command line");
  for (const char* key : {"inputs.pixel_size", "inputs.frame_rate"})
    if (!c.has(key)) throw InputError(c.where(key), "missing", {}, "a value in the case, or --pixel-size-um / --fps on the command line");
  if (c.has("inputs.truth")) detail::requireTracksFile(c, c.path("inputs.truth"), "inputs.truth");  // before the tracking, not after
  TrackConfig cfg = trackerConfig(c);
  cfg.pixel_size = c.quantity("inputs.pixel_size");
  cfg.fps = c.quantity("inputs.frame_rate");
  // An infinite pixel size would write inf positions: finite and positive, whichever way it came.
  if (!(std::isfinite(cfg.pixel_size) && cfg.pixel_size > 0))
    throw InputError(c.where("inputs.pixel_size"), "the pixel size must be finite and positive", fmt::format("{:g} um", cfg.pixel_size * 1e6),
                     "a length such as \"0.65 um\" (or --pixel-size-um 0.65)");
  if (!(std::isfinite(cfg.fps) && cfg.fps > 0))
    throw InputError(c.where("inputs.frame_rate"), "the frame rate must be finite and positive", fmt::format("{:g} Hz", cfg.fps),
                     "a frequency such as \"20 Hz\" (or --fps 20)");
  requireExposureWithinFrame(c, cfg);
  std::optional<cv::Rect> roi;
  if (c.has("inputs.roi")) {
    const auto& r = c.integers("inputs.roi");
    if (r.size() != 4) throw InputError(c.where("inputs.roi"), "a region of interest has four integers", {}, "[x, y, width, height] in px");
    roi = cv::Rect(static_cast<int>(r[0]), static_cast<int>(r[1]), static_cast<int>(r[2]), static_cast<int>(r[3]));
  }
  FrameRange range;
  range.first = static_cast<int>(c.integer("inputs.first_frame"));
  range.last = static_cast<int>(c.integer("inputs.last_frame"));
  // Paths given on the command line are taken as they are, case-file paths relative to the file.
  const std::string video = c.text("inputs.video");
  FrameSource source(std::filesystem::path(video).is_absolute() ? video : (c.file().parent_path() / video).string(), roi, range);
  const TrackRun run = runTracker(source, cfg, ctx.quiet);
  nlohmann::json extra = {{"input", video}, {"pixel_size_um", cfg.pixel_size * 1e6}, {"fps", cfg.fps}};
  RunOutput out;
  if (c.has("inputs.truth")) {
    const Tracks truth = readTracksCsv(c.path("inputs.truth"), cfg.pixel_size);
    Tracks truth_px = truth;
    for (auto& p : truth_px.points)
      if (!std::isfinite(p.x_px)) {
        p.x_px = p.x / cfg.pixel_size;
        p.y_px = p.y / cfg.pixel_size;
      }
    const Scores sc = scoreTracks(truth_px, run.tracks, c.real("score.gate"));
    extra["scores"] = scoresJson(sc);
    out.metrics["alpha"] = sc.alpha;
    out.metrics["beta"] = sc.beta;
    addScoreMetrics(sc, out.metrics);
  }
  addSceneDecisions(run, extra);
  out.files = writeTrackOutputs(run, cfg, ctx.out_dir, extra);
  if (run.motion.model == MotionModel::brownian) {
    // Speeds, dispersion and retention describe a flow: for Brownian motion, D and its kin.
    std::optional<BrownianStats> own;  // runTracker's, unless the run was put together otherwise
    if (!run.brownian) own = analyseBrownian(run.tracks, cfg.analysis.brownian);
    const BrownianStats& b = run.brownian ? *run.brownian : *own;
    if (std::isfinite(b.msd.d)) {
      out.metrics["diffusion_coefficient"] = b.msd.d;
      out.units["diffusion_coefficient"] = "um2/s";
    }
    if (std::isfinite(b.msd.alpha)) out.metrics["msd_exponent"] = b.msd.alpha;
    if (std::isfinite(b.msd.sigma2)) {
      out.metrics["localisation_sigma"] = std::sqrt(std::max(0.0, b.msd.sigma2));
      out.units["localisation_sigma"] = "um";
    }
    out.metrics["tracks"] = b.particles;
    out.metrics["immobile"] = b.immobile;
  } else {
    const TrackStats stats = analyseTracks(run.tracks, cfg.analysis);  // flow statistics: not needed for Brownian motion
    out.metrics["mean_speed"] = stats.mean_speed;
    out.units["mean_speed"] = "um/s";
    out.metrics["median_speed"] = stats.median_speed;
    out.units["median_speed"] = "um/s";
    out.metrics["sigma_x"] = stats.sigma_x;
    out.units["sigma_x"] = "um";
    out.metrics["sigma_y"] = stats.sigma_y;
    out.units["sigma_y"] = "um";
    out.metrics["retention_fraction"] = stats.retained_fraction;
    out.metrics["tracks"] = stats.particles;
    out.metrics["immobile"] = stats.immobile;
  }
  out.details = extra;
  out.details["motion"] = {{"model", motionModelName(run.motion.model)}, {"reason", run.motion.reason}};
  out.details["frames"] = run.frame_index.size();
  std::size_t detections = 0;
  for (const auto& d : run.detections) detections += d.size();
  out.details["detections"] = detections;
  out.details["seconds"] = run.seconds;
  return out;
}

void registerTrackingKinds(CaseKindRegistry& registry) {
  CaseKind video;
  video.name = "tracking-video";
  video.summary = "Track particles in a microscope video (or image folder / TIFF stack): tracks, velocities, dispersion, retention, streamlines";
  video.declare = [](Schema& s) {
    const FrameRange range;
    s.string("inputs.video", "Video file, image folder, glob or multi-page TIFF (relative to the case file)").optional();
    s.quantity("inputs.pixel_size", "um", "Pixel size").optional().positive();
    s.quantity("inputs.frame_rate", "Hz", "Frames per second").optional().positive();
    s.integerList("inputs.roi", "Region of interest [x, y, width, height], px").optional();
    s.integer("inputs.first_frame", "First frame to use").def(range.first).min(0);
    s.integer("inputs.last_frame", "Last frame to use (-1: to the end)").def(range.last).min(-1);
    s.path("inputs.truth", "Ground-truth tracks CSV (shared schema) to score against").optional();
    s.real("score.gate", "Gate of the scores, px").def(5).min(0.1);
    declareTrackerKeys(s);
  };
  video.run = runTrackingVideo;
  registry.add(video);

  CaseKind k;
  k.name = "tracking-synthetic";
  k.summary = "Track a synthetic micromodel video with known ground truth and score the tracks (Chenouard et al. 2014)";
  k.declare = [](Schema& s) {
    const SynthOptions o;
    s.integer("synth.width", "Frame width, px").def(o.width).min(32).max(8192);
    s.integer("synth.height", "Frame height, px").def(o.height).min(32).max(8192);
    s.integer("synth.frames", "Number of frames").def(o.frames).min(3).max(100000);
    s.quantity("synth.frame_rate", "Hz", "Frames per second").def(o.fps).positive();
    s.quantity("synth.pixel_size", "um", "Pixel size").def(o.pixel_size).positive();
    s.integer("synth.particles", "Moving particles in view").def(o.particles).min(0).max(100000);
    s.integer("synth.immobile", "Particles stuck from the start").def(o.immobile).min(0).max(100000);
    s.quantity("synth.deposit_fraction", "1", "Share of moving particles that stop during the video").def(o.deposit_fraction).fraction();
    s.integer("synth.grains", "Grains in view").def(o.grains).min(0).max(1000);
    s.real("synth.grain_radius", "Grain radius, px").def(o.grain_radius).min(2);
    s.real("synth.speed", "Mean flow speed, px per frame").def(o.speed).min(0);
    s.real("synth.spot_sigma", "Particle spot sigma, px").def(o.spot_sigma).min(0.3);
    s.real("synth.noise", "Camera noise, fraction of full scale").def(o.noise).min(0).max(0.5);
    s.real("synth.snr", "Spot amplitude over the noise std (0: use synth.noise)").def(o.snr).min(0);
    s.real("synth.photons", "Photons at full scale for Poisson shot noise (0: none)").def(o.photons).min(0);
    s.real("synth.illumination_gradient", "Brightness falls by this fraction from the left to the right edge").def(o.illumination_gradient).min(-0.9).max(0.9);
    s.real("synth.brownian_d", "Brownian diffusion coefficient, px^2 per frame").def(o.brownian_d).min(0);
    s.real("synth.defocus", "Spot sigma spread: [1, 1 + defocus] x spot_sigma at constant brightness").def(o.defocus).min(0).max(5);
    s.integer("synth.seed", "Random seed").def(static_cast<std::int64_t>(o.seed)).min(0);
    s.real("score.gate", "Gate of the scores, px (5 in the tracking challenge)").def(5).min(0.1);
    declareTrackerKeys(s);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    SynthOptions o;
    o.width = static_cast<int>(c.integer("synth.width"));
    o.height = static_cast<int>(c.integer("synth.height"));
    o.frames = static_cast<int>(c.integer("synth.frames"));
    o.fps = c.quantity("synth.frame_rate");
    o.pixel_size = c.quantity("synth.pixel_size");
    o.particles = static_cast<int>(c.integer("synth.particles"));
    o.immobile = static_cast<int>(c.integer("synth.immobile"));
    o.deposit_fraction = c.quantity("synth.deposit_fraction");
    o.grains = static_cast<int>(c.integer("synth.grains"));
    o.grain_radius = c.real("synth.grain_radius");
    o.speed = c.real("synth.speed");
    o.spot_sigma = c.real("synth.spot_sigma");
    o.noise = c.real("synth.noise");
    o.snr = c.real("synth.snr");
    o.photons = c.real("synth.photons");
    o.illumination_gradient = c.real("synth.illumination_gradient");
    o.brownian_d = c.real("synth.brownian_d");
    o.defocus = c.real("synth.defocus");
    o.seed = static_cast<std::uint64_t>(c.integer("synth.seed"));
    const SynthResult synth = writeSyntheticVideo(o, ctx.out_dir / "synthetic");
    TrackConfig cfg = trackerConfig(c);
    cfg.pixel_size = o.pixel_size;
    cfg.fps = o.fps;
    requireExposureWithinFrame(c, cfg);
    FrameSource source((ctx.out_dir / "synthetic" / "frames").string());
    const TrackRun run = runTracker(source, cfg, ctx.quiet);
    // With background removal and no search of the background for stuck particles the
    // tracker is meant not to see particles stuck from the start: they leave the scored truth.
    Tracks scored = synth.truth;
    if (run.background_decision.subtract && !cfg.detect.find_stuck)
      std::erase_if(scored.points, [&](const TrackPoint& p) {
        return std::find(synth.immobile_ids.begin(), synth.immobile_ids.end(), p.particle) != synth.immobile_ids.end();
      });
    const Scores sc = scoreTracks(scored, run.tracks, c.real("score.gate"));
    // The truth's resting ends labelled as the tracker labels its own (out of velocities).
    markDeposits(scored, cfg.analysis);
    const TrackStats truth_stats = analyseTracks(scored, cfg.analysis);
    const TrackStats ours = analyseTracks(run.tracks, cfg.analysis);
    nlohmann::json extra = {{"scores", scoresJson(sc)}};
    RunOutput out;
    addSceneDecisions(run, extra);
    out.files = writeTrackOutputs(run, cfg, ctx.out_dir / "tracks", extra);
    for (auto& f : out.files) f = "tracks/" + f;
    out.metrics["alpha"] = sc.alpha;
    out.metrics["beta"] = sc.beta;
    addScoreMetrics(sc, out.metrics);
    out.units["rmse"] = "1";
    out.metrics["mean_speed_relative_error"] = std::abs(ours.mean_speed - truth_stats.mean_speed) / truth_stats.mean_speed;
    out.metrics["immobile_found"] = ours.immobile;
    // Immobile recall: truth particles stuck from the start that an immobile track of ours sits on.
    if (!synth.immobile_ids.empty())
      out.metrics["immobile_recall"] = immobileRecall(synth.truth, synth.immobile_ids, run.tracks, ours, c.real("score.gate"));
    out.metrics["frames_per_second"] = run.frame_index.size() / std::max(run.seconds, 1e-9);
    out.units["frames_per_second"] = "Hz";
    out.details = extra;
    out.details["truth"] = {{"moving", synth.moving}, {"deposited", synth.deposited}, {"immobile", synth.immobile},
                            {"mean_speed_um_per_s", truth_stats.mean_speed * 1e6}};
    out.details["tracked_mean_speed_um_per_s"] = ours.mean_speed * 1e6;
    out.details["link"] = {{"links", run.link.links}, {"gap_closures", run.link.gap_closures}, {"largest_component", run.link.largest_component}};
    return out;
  };
  registry.add(k);
  registerRenderedKind(registry);
  declareTrackingMetrics(registry);
}

}  // namespace mmval::tracking
