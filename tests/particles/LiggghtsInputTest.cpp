// The LIGGGHTS input is generated from validated numbers only (no LIGGGHTS run here).
#include <gtest/gtest.h>

#include <algorithm>

#include "mmval/core/Error.hpp"
#include "mmval/particles/LiggghtsInput.hpp"

namespace mmval::particles {
namespace {

bool has(const std::vector<std::string>& c, const std::string& s) {
  return std::any_of(c.begin(), c.end(), [&](const std::string& x) { return x.find(s) != std::string::npos; });
}

SceneConfig scene() {
  SceneConfig c;
  c.work_dir = std::filesystem::temp_directory_path() / "mmval-liggghts-input-test";
  return c;
}

TEST(LiggghtsInput, ChannelGetsPlatesSideWallsAndSoftParticles) {
  HeleShawChannel ch(200e-6, 100e-6, 20e-6, 7e-4);
  const LiggghtsSetup s = liggghtsSetupFor(ch, scene(), 200e-6);
  const auto c = liggghtsSetupCommands(s);
  EXPECT_TRUE(has(c, "soft_particles yes"));
  EXPECT_TRUE(has(c, "atom_modify map array"));
  EXPECT_TRUE(has(c, "zplane 0.0"));
  EXPECT_TRUE(has(c, "yplane"));
  EXPECT_TRUE(has(c, "pair_style gran model hertz tangential history"));
  EXPECT_FALSE(has(c, "sjkr"));
  EXPECT_NEAR(s.dt, 4.43e-8, 0.01e-8);  // 10 % Rayleigh at E = 1e6 Pa
}

TEST(LiggghtsInput, CohesionAddsSjkrAndItsProperty) {
  HeleShawChannel ch(200e-6, 100e-6, 20e-6, 7e-4);
  SceneConfig sc = scene();
  sc.cohesion_energy_density = 1e5;
  const auto c = liggghtsSetupCommands(liggghtsSetupFor(ch, sc, 200e-6));
  EXPECT_TRUE(has(c, "cohesion sjkr"));
  EXPECT_TRUE(has(c, "cohesionEnergyDensity"));
}

TEST(LiggghtsInput, BadValuesAreInputErrorsBeforeAnyCommand) {
  HeleShawChannel ch(200e-6, 100e-6, 20e-6, 7e-4);
  LiggghtsSetup s = liggghtsSetupFor(ch, scene(), 200e-6);
  LiggghtsSetup bad = s;
  bad.particle.youngs_modulus = 10;
  EXPECT_THROW(liggghtsSetupCommands(bad), InputError);
  bad = s;
  bad.particle.poisson_ratio = 0.5;
  EXPECT_THROW(liggghtsSetupCommands(bad), InputError);
  bad = s;
  bad.x1 = 1.0;  // a metre-long box of 5 um particles: too many neighbour bins
  bad.y1 = 1.0;
  EXPECT_THROW(liggghtsSetupCommands(bad), InputError);
  bad = s;
  bad.log_file = "/tmp/with space/log";
  EXPECT_THROW(liggghtsSetupCommands(bad), InputError);
  EXPECT_THROW(liggghtsInsertCommands(s, {Vec3(1e-5, 1e-5, 1e-6)}, 1), InputError);  // crosses the bottom plate
  EXPECT_THROW(liggghtsInsertCommands(s, {Vec3(5e-3, 1e-5, 1e-5)}, 1), InputError);  // outside the box
  const auto ok = liggghtsInsertCommands(s, {Vec3(1e-5, 1e-5, 1e-5), Vec3(2e-5, 1e-5, 1e-5)}, 3);
  ASSERT_EQ(ok.size(), 3u);
  EXPECT_NE(ok[2].find("set atom 3*4 diameter"), std::string::npos);
}

TEST(LiggghtsInput, GrainFieldsAreRefusedWithAReason) {
  GriddedFlow g(4, 4, 0, 0, 1e-5, 1e-5);
  std::vector<double> z(16, 0.0), h(16, 20e-6);
  g.update(z, z, h, std::vector<std::uint8_t>(16, 0));
  try {
    liggghtsSetupFor(g, scene(), 3e-5);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("STL"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mmval::particles
