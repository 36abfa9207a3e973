// A real-format Brownian video as a user tracks it: `mmval synth --scene
// brownian-slab` writes 300 RGBA PNG frames (640 x 424, 24 fps, ~600 dark 1-um
// spheres through a 20-um slab, most of them out of focus, drifting at
// 0.6 um/s), then `mmval track` with its defaults only. The truth is the
// Stokes-Einstein D the scene was rendered with (truth.json); the must-show of
// the Brownian motion model is D within 2 % and an MSD exponent in 0.97-1.03.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "RunMmval.hpp"

namespace fs = std::filesystem;
using mmval::test::freshTestFolder;
using mmval::test::runMmval;

namespace {

nlohmann::json readJson(const fs::path& file) {
  std::ifstream in(file);
  return nlohmann::json::parse(in);
}

TEST(BrownianVideo, DefaultsFindBrownianMotionAndStokesEinsteinD) {
  const fs::path dir = freshTestFolder("brownian-video", "seed1");
  const auto synth = runMmval("synth --scene brownian-slab --format rgba --seed 1 --out " + (dir / "video").string());
  ASSERT_EQ(synth.status, 0) << synth.output;
  const auto track = runMmval("track " + (dir / "video" / "frames").string() + " --pixel-size-um 0.15 --fps 24 --quiet --out " + (dir / "track").string());
  ASSERT_EQ(track.status, 0) << track.output;

  const double d_true = readJson(dir / "video" / "truth.json").at("diffusion_um2_s").get<double>();
  const auto summary = readJson(dir / "track" / "summary.json");
  EXPECT_EQ(summary.at("motion").at("model"), "brownian") << summary.at("motion").dump(2);
  const auto& b = summary.at("brownian");
  const double d = b.at("D_um2_per_s").get<double>(), alpha = b.at("alpha").get<double>();
  std::printf("D %.4f +- %.4f um^2/s (Stokes-Einstein %.4f, %+.2f %%), alpha %.3f +- %.3f, sigma_loc %.4f um\n", d, b.at("D_se_um2_per_s").get<double>(), d_true,
              100 * (d / d_true - 1), alpha, b.at("alpha_se").get<double>(), b.at("sigma_loc_um").get<double>());
  EXPECT_NEAR(d, d_true, 0.02 * d_true);
  EXPECT_GE(alpha, 0.97);
  EXPECT_LE(alpha, 1.03);
  // The summary's own top-level MSD figures are the Brownian ones, drift removed.
  EXPECT_NEAR(summary.at("msd_exponent").get<double>(), alpha, 1e-12);
  // Free particles are not "immobile" because they stay within a fixed distance:
  // the statistical test calls a small share of them immobile, not a third.
  EXPECT_LT(summary.at("immobile").get<double>(), 0.01 * summary.at("tracks").get<double>());
  EXPECT_FALSE(fs::exists(dir / "track" / "retention.csv"));
}

}  // namespace
