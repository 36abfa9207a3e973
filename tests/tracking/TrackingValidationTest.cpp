// The tracker's accuracy targets on synthetic micromodel videos with ground
// truth: a crowded, noisy pore scene scored after Chenouard et al. (2014), and
// the statistics (MSD diffusion coefficient, dispersion) against the analytic
// values the video was rendered with. Seconds each (label: validation).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>

#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/Score.hpp"
#include "mmval/tracking/Synth.hpp"
#include "mmval/tracking/TrackSmooth.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

fs::path render(const char* name, const SynthOptions& o, SynthResult& r) {
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / name;
  fs::remove_all(dir);
  r = writeSyntheticVideo(o, dir);
  return dir;
}

/// Largest truth step of a moving particle, px per frame.
double fastestStep(const Tracks& truth) {
  double v = 0;
  for (std::size_t i = 1; i < truth.points.size(); ++i) {
    const auto& a = truth.points[i - 1];
    const auto& b = truth.points[i];
    if (a.particle == b.particle && b.frame == a.frame + 1) v = std::max(v, std::hypot(b.x_px - a.x_px, b.y_px - a.y_px));
  }
  return v;
}

// The validation scene: 300 moving particles plus 75 stuck (20 %), SNR 4, carried
// through a field of grains at a mean 2.5 px/frame (up to 5 px/frame beside grains).
SynthOptions micromodelScene() {
  SynthOptions o;
  o.width = 640;
  o.height = 480;
  o.frames = 40;
  o.particles = 300;
  o.immobile = 75;
  o.grains = 24;
  o.grain_radius = 22;
  o.speed = 2.5;
  o.snr = 4;
  o.deposit_fraction = 0.1;
  o.seed = 31;
  return o;
}

TEST(TrackingValidation, MicromodelSnr4MeetsIssueTargets) {
  // The case's seed (31) with both linkers, then two more seeds with the default (global)
  // linker, so the targets are not met by one lucky video.
  for (const std::uint64_t seed : {31u, 7u, 11u}) {
    SynthOptions o = micromodelScene();
    o.seed = seed;
    SynthResult truth;
    const fs::path dir = render("validation-micromodel", o, truth);
    const double fastest = fastestStep(truth.truth);
    for (Linker method : {Linker::global, Linker::paper}) {
      if (seed != 31 && method != Linker::global) continue;
      TrackConfig c;
      c.detect.find_stuck = true;
      c.link.method = method;
      FrameSource src((dir / "frames").string());
      const TrackRun run = runTracker(src, c, true);
      const Scores s = scoreTracks(truth.truth, run.tracks);
      const TrackStats stats = analyseTracks(run.tracks, c.analysis);
      const double recall = immobileRecall(truth.truth, truth.immobile_ids, run.tracks, stats);
      std::printf("micromodel SNR 4, seed %d, %s linker (fastest truth step %.2f px/frame): JSC %.4f JSC_theta %.4f alpha %.4f beta %.4f "
                  "RMSE %.3f px (localisation %.3f px, %lld points off by >= 1 px) immobile recall %.3f (%d stuck found)\n",
                  static_cast<int>(seed), method == Linker::global ? "global" : "paper", fastest, s.jaccard_points, s.jaccard_tracks, s.alpha,
                  s.beta, s.rmse_px, s.rmse_localisation_px, s.gross_points, recall, run.stuck_found);
      EXPECT_GE(fastest, 4.5);  // the scene really reaches ~5 px/frame
      if (method != Linker::global) continue;  // the paper's rule is reported, the targets are the global linker's
      // The targets: JSC >= 0.95, JSC_theta >= 0.85, immobile recall >= 0.95 (met:
      // measured 0.967-0.981, 0.955-0.968, 0.960-1.000 over the three seeds).
      EXPECT_GE(s.jaccard_points, 0.95);
      EXPECT_GE(s.jaccard_tracks, 0.85);
      EXPECT_GE(recall, 0.95);
      // The positions as detected, frame by frame. Localisation (matched points within
      // 1 px of the truth): 0.294-0.299 px over the three seeds. The Cramer-Rao bound for one
      // Gaussian spot's position at peak SNR 4 (rendered sigma 1.3 px, summed over the
      // pixels) is 0.282 px in 2D, 0.288 px with the noise of a 40-frame median
      // background; pairs travelling closer than ~2 px add the rest (no single-frame
      // estimator separates them at this SNR). Guarded at the bound + 8 %.
      EXPECT_LE(s.rmse_localisation_px, 0.31);
      // Matched points 1 px or more off (close pairs 1-2 px off, and a paired track on a
      // neighbour for a few frames, 3-5 px off): 71-125 of ~14,700 (0.5-0.85 %) over the
      // seeds and fit variants. Guarded at 1.2 %.
      EXPECT_LE(static_cast<double>(s.gross_points), 0.012 * static_cast<double>(s.tp));
      // The challenge's RMSE takes both (0.327-0.346 px over the seeds and fit variants,
      // whose localisation RMSE agrees to 1e-4 px: the spread is a few such events, one
      // 9-frame event at ~4 px adds ~0.01 px). Guarded at the largest measured + 0.015 px.
      EXPECT_LE(s.rmse_px, 0.36);
      // The target RMSE <= 0.3 px comes from using the track: a quadratic fit along each
      // moving track over 5 frames (link.smooth_frames = 2, what the case sets) averages
      // independent frame errors (variance x 17/35 at the centre). Measured 0.258-0.262 px
      // over the three seeds; JSC and JSC_theta are unchanged (positions move, links do not).
      Tracks smoothed = run.tracks;
      smoothTracks(smoothed, 2, c.pixel_size);
      const Scores sm = scoreTracks(truth.truth, smoothed);
      std::printf("  with link.smooth_frames = 2: JSC %.4f JSC_theta %.4f RMSE %.3f px\n", sm.jaccard_points, sm.jaccard_tracks, sm.rmse_px);
      EXPECT_LE(sm.rmse_px, 0.30);
      EXPECT_LT(sm.rmse_px, s.rmse_px - 0.05);
      EXPECT_NEAR(sm.jaccard_points, s.jaccard_points, 0.005);
    }
  }
}

/// Pairs of detections in one frame closer than `radius` px with at most one truth
/// particle within `radius` of their midpoint: one particle found twice.
int falseDuplicates(const TrackRun& run, const Tracks& truth, double radius) {
  int dups = 0;
  for (std::size_t f = 0; f < run.detections.size(); ++f) {
    const auto& d = run.detections[f];
    const std::int64_t frame = run.frame_index[f];
    for (std::size_t i = 0; i < d.size(); ++i)
      for (std::size_t j = i + 1; j < d.size(); ++j) {
        if (std::hypot(d[i].x - d[j].x, d[i].y - d[j].y) >= radius) continue;
        const double mx = 0.5 * (d[i].x + d[j].x), my = 0.5 * (d[i].y + d[j].y);
        int near = 0;
        for (const auto& p : truth.points)
          if (p.frame == frame && std::hypot(p.x_px - mx, p.y_px - my) < radius) ++near;
        if (near <= 1) ++dups;
      }
  }
  return dups;
}

TEST(TrackingValidation, CleanSparseSpotsAreNotSplit) {
  // Regression: the split test of the joint spot fit (deblend) once judged two spots
  // against one spot of the joint fit's narrow model, which every lone spot fits worse
  // by a few percent of its energy; on clean sparse scenes (SNR 10 and more) most spots
  // were found twice ~2 px apart and tracks fragmented (JSC_theta 0.48 at SNR 10).
  for (const double snr : {10.0, 20.0}) {
    SynthOptions o;
    o.width = 480;
    o.height = 360;
    o.frames = 12;
    o.particles = 150;
    o.immobile = 0;
    o.deposit_fraction = 0;
    o.grains = 8;
    o.grain_radius = 20;
    o.speed = 2;
    o.snr = snr;
    o.seed = 5;
    SynthResult truth;
    const fs::path dir = render("validation-clean-sparse", o, truth);
    TrackConfig c;
    c.link.search_radius = 2 * o.speed + 3;
    FrameSource src((dir / "frames").string());
    const TrackRun run = runTracker(src, c, true);
    const Scores s = scoreTracks(truth.truth, run.tracks);
    const int dups = falseDuplicates(run, truth.truth, 3.0);
    std::printf("clean sparse scene, SNR %.0f: JSC %.4f JSC_theta %.4f RMSE %.3f px, false duplicates %d of %lld truth points\n", snr,
                s.jaccard_points, s.jaccard_tracks, s.rmse_px, dups, static_cast<long long>(truth.truth.points.size()));
    // Measured 0 duplicates and JSC_theta >= 0.97 at both SNRs; without deblending (no
    // split at all) JSC_theta is ~0.96. A duplicate or two can be a real pair whose
    // second truth particle sits just beyond 3 px.
    EXPECT_LE(dups, 2) << "SNR " << snr;
    EXPECT_GE(s.jaccard_tracks, 0.95) << "SNR " << snr;
    EXPECT_GE(s.jaccard_points, 0.95) << "SNR " << snr;
  }
}

TEST(TrackingValidation, BrownianDiffusionFromAVideo) {
  // Free Brownian particles, D = 0.8 px^2/frame, nothing else moving: the MSD's slope
  // gives D. Reference: D as rendered. Tolerance 5 %: the statistical error
  // of the ensemble MSD over ~150 particles x 60 frames is ~1.5 %, localisation noise
  // adds 4 sigma_loc^2 ~ 0.02 px^2 to the MSD (< 1 % of 4 D).
  SynthOptions o;
  o.width = 400;
  o.height = 300;
  o.frames = 60;
  o.particles = 150;
  o.immobile = 0;
  o.grains = 0;
  o.speed = 0;
  o.deposit_fraction = 0;
  o.brownian_d = 0.8;
  o.fps = 10;
  o.pixel_size = 0.5e-6;
  o.seed = 17;
  SynthResult truth;
  const fs::path dir = render("validation-brownian", o, truth);
  TrackConfig c;
  c.fps = o.fps;
  c.pixel_size = o.pixel_size;
  c.link.predict = Prediction::none;  // Brownian steps are uncorrelated: the last step predicts nothing
  c.link.search_radius = 6;
  c.analysis.immobile_distance = 0;
  c.analysis.min_points = 10;
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  const TrackStats s = analyseTracks(run.tracks, c.analysis);
  const double d_true = o.brownian_d * o.pixel_size * o.pixel_size * o.fps;  // m^2/s
  std::printf("Brownian video: D true %.4g um^2/s, from the MSD %.4g (line) %.4g (power law, exponent %.3f)\n", d_true * 1e12,
              s.msd.d_linear * 1e12, s.msd.d_power * 1e12, s.msd.alpha);
  EXPECT_NEAR(s.msd.d_linear, d_true, 0.05 * d_true);
  EXPECT_NEAR(s.msd.alpha, 1.0, 0.05);
}

TEST(TrackingValidation, DispersionMatchesTheTruth) {
  // Flow around grains with noise and stuck particles: sigma_x(t), sigma_y(t) of the
  // tracked mobile particles against the truth's, frame by frame (paper Eq. 18).
  // Tolerance 3 % of the truth's sigma: a missed or spurious point moves a frame's
  // sigma by ~1 / N with N ~ 60 particles per frame.
  SynthOptions o;
  o.frames = 30;
  o.particles = 60;
  o.immobile = 0;
  o.deposit_fraction = 0;
  o.seed = 23;
  SynthResult truth;
  const fs::path dir = render("validation-dispersion", o, truth);
  TrackConfig c;
  FrameSource src((dir / "frames").string());
  const TrackRun run = runTracker(src, c, true);
  const TrackStats ours = analyseTracks(run.tracks, c.analysis);
  const TrackStats ref = analyseTracks(truth.truth, c.analysis);
  std::printf("dispersion: sigma_x %.3f um (truth %.3f), sigma_y %.3f um (truth %.3f)\n", ours.sigma_x * 1e6, ref.sigma_x * 1e6,
              ours.sigma_y * 1e6, ref.sigma_y * 1e6);
  EXPECT_NEAR(ours.sigma_x, ref.sigma_x, 0.03 * ref.sigma_x);
  EXPECT_NEAR(ours.sigma_y, ref.sigma_y, 0.03 * ref.sigma_y);
  // Frame by frame, the worst frame within 8 %.
  double worst = 0;
  for (const auto& f : ours.frames) {
    const auto it = std::find_if(ref.frames.begin(), ref.frames.end(), [&](const FrameDispersion& r) { return r.frame == f.frame; });
    if (it == ref.frames.end() || it->count < 10) continue;
    worst = std::max({worst, std::abs(f.sigma_x - it->sigma_x) / it->sigma_x, std::abs(f.sigma_y - it->sigma_y) / it->sigma_y});
  }
  std::printf("dispersion: worst frame relative difference %.3f\n", worst);
  EXPECT_LT(worst, 0.08);
}

}  // namespace
}  // namespace mmval::tracking
