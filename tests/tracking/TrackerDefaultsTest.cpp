// The tracker's case keys take their defaults from the option structs
// (Kinds.cpp: declareTrackerKeys): a case that sets no tracker key must give
// exactly TrackConfig{} (Pipeline.hpp), and a synthetic case that sets no synth
// key exactly SynthOptions{} (Synth.hpp), so that the schema and the structs
// cannot drift apart.
//
// Tolerance: the defaults are copied, not computed; quantities pass through the
// schema's SI value, so reals agree to round-off (EXPECT_DOUBLE_EQ, 4 ulp).
#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/tracking/Kinds.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/Synth.hpp"

namespace mmval::tracking {
namespace {

const CaseKindRegistry& registry() {
  static const CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    registerTrackingKinds(reg);
    return reg;
  }();
  return r;
}

/// A case of `kind` with only its [case] table: every other key at its default.
Case emptyCase(const std::string& kind) {
  return Case::parse("[case]\nname = \"defaults\"\nkind = \"" + kind + "\"\n", "defaults.toml", registry());
}

TEST(TrackerDefaults, DetectKeysDefaultToDetectOptions) {
  const TrackConfig ref{};
  const TrackConfig t = trackerConfig(emptyCase("tracking-video"));
  const DetectOptions& e = ref.detect;
  const DetectOptions& d = t.detect;
  EXPECT_EQ(d.subtract_background, e.subtract_background);
  EXPECT_EQ(d.background_mode, e.background_mode);
  EXPECT_EQ(d.polarity, e.polarity);
  EXPECT_DOUBLE_EQ(d.blur_sigma, e.blur_sigma);
  EXPECT_EQ(d.threshold, e.threshold);
  EXPECT_DOUBLE_EQ(d.threshold_value, e.threshold_value);
  EXPECT_EQ(d.morphology, e.morphology);
  EXPECT_EQ(d.kernel, e.kernel);
  EXPECT_EQ(d.iterations, e.iterations);
  EXPECT_DOUBLE_EQ(d.min_area, e.min_area);
  EXPECT_DOUBLE_EQ(d.max_area, e.max_area);
  EXPECT_DOUBLE_EQ(d.min_circularity, e.min_circularity);
  EXPECT_DOUBLE_EQ(d.min_snr, e.min_snr);
  EXPECT_EQ(d.refinement, e.refinement);
  EXPECT_EQ(d.method, e.method);
  EXPECT_EQ(d.local_background, e.local_background);
  EXPECT_EQ(d.separation, e.separation);
  EXPECT_DOUBLE_EQ(d.min_mass, e.min_mass);
  EXPECT_DOUBLE_EQ(d.min_mass_relative, e.min_mass_relative);
  EXPECT_DOUBLE_EQ(d.min_percentile, e.min_percentile);
  EXPECT_EQ(d.deblend, e.deblend);
  EXPECT_EQ(d.find_stuck, e.find_stuck);
  EXPECT_EQ(d.refine_radius, e.refine_radius);
  EXPECT_DOUBLE_EQ(d.refine_sigma, e.refine_sigma);
  EXPECT_DOUBLE_EQ(d.max_size_ratio, e.max_size_ratio);
  EXPECT_DOUBLE_EQ(t.background_quantile, ref.background_quantile);
  EXPECT_EQ(t.background_window, ref.background_window);
}

TEST(TrackerDefaults, LinkKeysDefaultToLinkOptions) {
  const TrackConfig ref{};
  const Case c = emptyCase("tracking-video");
  const TrackConfig t = trackerConfig(c);
  EXPECT_EQ(t.link.method, ref.link.method);
  EXPECT_DOUBLE_EQ(t.link.search_radius, ref.link.search_radius);
  EXPECT_EQ(t.link.memory, ref.link.memory);
  EXPECT_EQ(t.link.predict, ref.link.predict);
  EXPECT_DOUBLE_EQ(t.link.velocity_smoothing, ref.link.velocity_smoothing);
  EXPECT_DOUBLE_EQ(t.link.neighbour_radius, ref.link.neighbour_radius);
  EXPECT_EQ(t.smooth_frames, ref.smooth_frames);
  // trackerConfig turns threads = 0 into the core count: the key itself holds the default.
  EXPECT_EQ(c.integer("detect.threads"), ref.threads);
}

TEST(TrackerDefaults, AnalysisKeysDefaultToTrackOptions) {
  const TrackConfig ref{};
  const TrackConfig t = trackerConfig(emptyCase("tracking-video"));
  EXPECT_DOUBLE_EQ(t.analysis.immobile_distance, ref.analysis.immobile_distance);
  EXPECT_DOUBLE_EQ(t.analysis.stuck_distance, ref.analysis.stuck_distance);
  EXPECT_DOUBLE_EQ(t.analysis.stuck_window, ref.analysis.stuck_window);
  EXPECT_EQ(t.analysis.motion, ref.analysis.motion);
  EXPECT_DOUBLE_EQ(t.analysis.brownian.exposure, ref.analysis.brownian.exposure);
  EXPECT_EQ(t.analysis.brownian.min_points, ref.analysis.brownian.min_points);
  EXPECT_EQ(t.analysis.brownian.max_lag, ref.analysis.brownian.max_lag);
  EXPECT_DOUBLE_EQ(t.analysis.brownian.immobile_level, ref.analysis.brownian.immobile_level);
}

TEST(TrackerDefaults, SyntheticKindSharesTheTrackerDefaults) {
  const TrackConfig ref{};
  const TrackConfig t = trackerConfig(emptyCase("tracking-synthetic"));
  EXPECT_EQ(t.detect.method, ref.detect.method);
  EXPECT_DOUBLE_EQ(t.detect.blur_sigma, ref.detect.blur_sigma);
  EXPECT_DOUBLE_EQ(t.link.search_radius, ref.link.search_radius);
  EXPECT_DOUBLE_EQ(t.analysis.stuck_window, ref.analysis.stuck_window);
}

TEST(TrackerDefaults, SynthKeysDefaultToSynthOptions) {
  const SynthOptions e;
  const Case c = emptyCase("tracking-synthetic");
  EXPECT_EQ(c.integer("synth.width"), e.width);
  EXPECT_EQ(c.integer("synth.height"), e.height);
  EXPECT_EQ(c.integer("synth.frames"), e.frames);
  EXPECT_DOUBLE_EQ(c.quantity("synth.frame_rate"), e.fps);
  EXPECT_DOUBLE_EQ(c.quantity("synth.pixel_size"), e.pixel_size);
  EXPECT_EQ(c.integer("synth.particles"), e.particles);
  EXPECT_EQ(c.integer("synth.immobile"), e.immobile);
  EXPECT_DOUBLE_EQ(c.quantity("synth.deposit_fraction"), e.deposit_fraction);
  EXPECT_EQ(c.integer("synth.grains"), e.grains);
  EXPECT_DOUBLE_EQ(c.real("synth.grain_radius"), e.grain_radius);
  EXPECT_DOUBLE_EQ(c.real("synth.speed"), e.speed);
  EXPECT_DOUBLE_EQ(c.real("synth.spot_sigma"), e.spot_sigma);
  EXPECT_DOUBLE_EQ(c.real("synth.noise"), e.noise);
  EXPECT_DOUBLE_EQ(c.real("synth.snr"), e.snr);
  EXPECT_DOUBLE_EQ(c.real("synth.photons"), e.photons);
  EXPECT_DOUBLE_EQ(c.real("synth.illumination_gradient"), e.illumination_gradient);
  EXPECT_DOUBLE_EQ(c.real("synth.brownian_d"), e.brownian_d);
  EXPECT_DOUBLE_EQ(c.real("synth.defocus"), e.defocus);
  EXPECT_EQ(static_cast<std::uint64_t>(c.integer("synth.seed")), e.seed);
}

TEST(TrackerDefaults, FrameRangeKeysDefaultToFrameRange) {
  const FrameRange e;
  const Case c = emptyCase("tracking-video");
  EXPECT_EQ(c.integer("inputs.first_frame"), e.first);
  EXPECT_EQ(c.integer("inputs.last_frame"), e.last);
}

}  // namespace
}  // namespace mmval::tracking
