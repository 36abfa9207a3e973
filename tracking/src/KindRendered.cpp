// "tracking-rendered": a simulation's trajectories seen through a camera. The
// trajectories (a file, or the run of another case in the same validation)
// are drawn over the geometry image as a noisy microscope video, which the
// tracker then processes like an experiment's. Its tracks.csv is what
// `compare` sets against the trajectories: the differences are what video
// processing alone does to each metric.
#include <algorithm>
#include <cmath>
#include <filesystem>

#include <opencv2/imgcodecs.hpp>
#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "InputLimits.hpp"
#include "mmval/core/MaskRule.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/tracking/Kinds.hpp"
#include "mmval/tracking/RenderTracks.hpp"
#include "mmval/tracking/Score.hpp"

namespace mmval::tracking {

namespace fs = std::filesystem;

void registerRenderedKind(CaseKindRegistry& registry) {
  CaseKind k;
  k.name = "tracking-rendered";
  k.summary = "Render a simulation's trajectories as a microscope video over its geometry, track it, and score the tracks against them";
  k.declare = [](Schema& s) {
    s.path("inputs.trajectories", "Trajectories CSV (shared tracks schema, with pixel columns in the geometry image)").optional();
    s.string("inputs.trajectories_run", "Instead: name of a case run earlier in the same validation; its trajectories.csv is used").optional();
    declareMask(s, {.mask_doc = "Geometry image the trajectories were simulated in (the same crop)"});
    s.integerList("geometry.crop", "Window of the image the simulation used: [x, y, width, height] in px").optional();
    s.real("render.scale", "Video pixels per geometry pixel").def(1.0).min(0.1).max(16);
    s.real("render.spot_sigma", "Particle spot sigma, video px").def(1.3).min(0.3);
    s.real("render.snr", "Spot depth over the camera noise std").def(8).min(0.5);
    s.integer("render.seed", "Camera noise seed").def(1).min(0);
    s.real("score.gate", "Gate of the scores, px (5 in the tracking challenge)").def(5).min(0.1);
    declareTrackerKeys(s);
  };
  k.run = [](const Case& c, const RunContext& ctx) {
    const fs::path file = fileOrRunFile(c, ctx, "inputs.trajectories", "trajectories.csv");
    const double geometry_pixel = c.quantity("geometry.pixel_size");
    const fs::path mask = c.path("geometry.mask");
    // Before anything is read: the trajectories' size, and the mask's from its header. Each mask
    // pixel becomes render.scale^2 video pixels, and the tracker holds ~64 float frames of the
    // video (60 background samples and the detection batch: 256 B per video pixel, from the code).
    detail::requireTracksFile(c, file, "inputs.trajectories");
    const double scale = c.real("render.scale");
    requireImageWithin(mask, c.where("geometry.mask"), maxMemoryBytes(c), 12 + 256 * scale * scale,
                       "a smaller mask (geometry.crop crops after reading) or a smaller render.scale");
    const Tracks sim = readTracksCsv(file, geometry_pixel);
    cv::Mat img = cv::imread(mask.string(), cv::IMREAD_GRAYSCALE);
    if (img.empty()) throw InputError(c.where("geometry.mask"), "cannot read the image", mask.string(), "a PNG or TIFF mask");
    if (c.has("geometry.crop")) {
      const auto& crop = c.integers("geometry.crop");
      const cv::Rect r(static_cast<int>(crop.at(0)), static_cast<int>(crop.size() > 1 ? crop[1] : 0), static_cast<int>(crop.size() > 2 ? crop[2] : 0),
                       static_cast<int>(crop.size() > 3 ? crop[3] : 0));
      if (crop.size() != 4 || r.width <= 0 || r.height <= 0 || (r & cv::Rect(0, 0, img.cols, img.rows)) != r)
        throw InputError(c.where("geometry.crop"), "not a window inside the image", {}, fmt::format("[x, y, width, height] inside {} x {} px", img.cols, img.rows));
      img = img(r).clone();
    }
    cv::Mat grains;
    // mmval's mask rule (core/MaskRule.hpp), as the simulation that wrote the trajectories read it.
    cv::threshold(img, grains, maskSplit(img.ptr<std::uint8_t>(), img.total()), 255,
                  c.text("geometry.grains") == "dark" ? cv::THRESH_BINARY_INV : cv::THRESH_BINARY);
    RenderOptions ro;
    ro.scale = c.real("render.scale");
    ro.spot_sigma = c.real("render.spot_sigma");
    ro.snr = c.real("render.snr");
    ro.seed = static_cast<std::uint64_t>(c.integer("render.seed"));
    RenderedVideo video;
    try {
      video = renderTracksVideo(sim, grains, geometry_pixel, ro, ctx.out_dir / "video");
    } catch (const std::invalid_argument& e) {
      throw InputError({file.string(), 0, 0, "x, y"}, e.what(), {}, "trajectories with pixel columns and at least two output steps");
    }
    TrackConfig cfg = trackerConfig(c);
    cfg.pixel_size = geometry_pixel / ro.scale;
    cfg.fps = video.fps;
    // The rendering's own grains at the video's size: a grain as small as a particle would read
    // as a particle at rest in the median background (TrackConfig::solids).
    cv::resize(grains, cfg.solids, cv::Size(), ro.scale, ro.scale, cv::INTER_NEAREST);
    FrameSource source((ctx.out_dir / "video" / "frames").string());
    TrackRun run = runTracker(source, cfg, ctx.quiet);
    const Scores sc = scoreTracks(video.truth, run.tracks, c.real("score.gate"));
    // Positions in micrometres: the tracker's pixel size is the geometry's over the scale,
    // and a video pixel centre (i + 0.5) / scale - 0.5 geometry pixels from the origin.
    for (auto& p : run.tracks.points) {
      p.x = ((p.x_px + 0.5) / ro.scale - 0.5) * geometry_pixel;
      p.y = ((p.y_px + 0.5) / ro.scale - 0.5) * geometry_pixel;
    }
    const TrackStats truth_stats = analyseTracks(video.truth, cfg.analysis), ours = analyseTracks(run.tracks, cfg.analysis);
    nlohmann::json extra = {{"trajectories", file.string()},
                            {"scores", scoresJson(sc)}};
    RunOutput out;
    out.files = writeTrackOutputs(run, cfg, ctx.out_dir, extra);
    addScoreMetrics(sc, out.metrics);
    if (truth_stats.mean_speed > 0) out.metrics["mean_speed_relative_error"] = (ours.mean_speed - truth_stats.mean_speed) / truth_stats.mean_speed;
    out.metrics["frames_per_second"] = run.frame_index.size() / std::max(run.seconds, 1e-9);
    out.units["frames_per_second"] = "Hz";
    out.details = extra;
    out.details["video"] = {{"frames", video.frames}, {"fps", video.fps}, {"pixel_size_um", cfg.pixel_size * 1e6}, {"snr", ro.snr}};
    out.details["truth_mean_speed_um_per_s"] = truth_stats.mean_speed * 1e6;
    out.details["tracked_mean_speed_um_per_s"] = ours.mean_speed * 1e6;
    return out;
  };
  registry.add(k);
}

}  // namespace mmval::tracking
