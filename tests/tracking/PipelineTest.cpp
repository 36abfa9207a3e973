// The whole tracker (Pipeline.hpp) on synthetic micromodel videos with ground truth.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "mmval/tracking/Frames.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/Score.hpp"
#include "mmval/tracking/TrackMetrics.hpp"
#include "SyntheticVideo.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

/// The truth without the particles immobile from the first frame, which the
/// tracker reports only with detect.find_stuck on.
Tracks withoutImmobile(const SynthResult& r) {
  Tracks t = r.truth;
  std::erase_if(t.points, [&](const TrackPoint& p) { return std::find(r.immobile_ids.begin(), r.immobile_ids.end(), p.particle) != r.immobile_ids.end(); });
  return t;
}

TEST(Pipeline, BothLinkersTrackTheSyntheticVideo) {
  SynthOptions o;
  o.frames = 40;
  o.seed = 5;
  SynthResult truth;
  const fs::path dir = synthetic("synth-link", o, truth);
  for (Linker method : {Linker::global, Linker::paper}) {
    TrackConfig c;
    c.link.method = method;
    FrameSource src((dir / "frames").string());
    const TrackRun run = runTracker(src, c, true);
    const Scores s = scoreTracks(withoutImmobile(truth), run.tracks);
    std::printf("%s linker: JSC %.3f alpha %.3f beta %.3f JSC_tracks %.3f RMSE %.3f px\n", method == Linker::global ? "global" : "paper",
                s.jaccard_points, s.alpha, s.beta, s.jaccard_tracks, s.rmse_px);
    EXPECT_GT(s.jaccard_points, method == Linker::global ? 0.9 : 0.85);
    EXPECT_GT(s.alpha, method == Linker::global ? 0.88 : 0.8);
    EXPECT_LT(s.rmse_px, 0.4);
  }
}

TEST(Pipeline, StuckParticlesAreFoundInTheBackground) {
  SynthOptions o;
  o.frames = 40;
  o.seed = 5;
  o.immobile = 6;
  SynthResult truth;
  const fs::path dir = synthetic("synth-stuck", o, truth);
  TrackConfig c;
  c.detect.find_stuck = true;
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  // Every particle stuck from the start is found (within 1 px) ...
  int found = 0;
  for (auto id : truth.immobile_ids) {
    const auto t = std::find_if(truth.truth.points.begin(), truth.truth.points.end(), [&](const TrackPoint& p) { return p.particle == id; });
    for (const auto& p : run.tracks.points)
      if (p.frame == 0 && std::hypot(p.x_px - t->x_px, p.y_px - t->y_px) < 1.0) {
        ++found;
        break;
      }
  }
  EXPECT_EQ(found, 6);
  // ... and scored against the whole truth, stuck ones included, the tracks stay good.
  EXPECT_GT(scoreTracks(truth.truth, run.tracks).jaccard_points, 0.9);
}

TEST(Pipeline, UniformFlowVelocityWithinOnePercent) {
  SynthOptions o;
  o.grains = 0;  // no grains: the flow is uniform, 3 px per frame
  o.frames = 30;
  o.immobile = 0;
  o.deposit_fraction = 0;
  o.speed = 3.0;
  o.fps = 10;
  SynthResult truth;
  const fs::path dir = synthetic("synth-uniform", o, truth);
  TrackConfig c;
  c.fps = o.fps;
  c.pixel_size = o.pixel_size;
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  const TrackStats s = analyseTracks(run.tracks, c.analysis);
  double vx = 0;
  for (const auto& st : s.steps) vx += st.vx;
  vx /= static_cast<double>(s.steps.size());
  EXPECT_NEAR(vx, 30e-6, 0.01 * 30e-6);  // 3 px/frame x 10 frames/s x 1 um/px
  // Dispersion against the truth's, frame by frame (Eq. 18).
  const TrackStats ts = analyseTracks(truth.truth, c.analysis);
  EXPECT_NEAR(s.sigma_y, ts.sigma_y, 0.05 * ts.sigma_y);
}

}  // namespace
}  // namespace mmval::tracking
