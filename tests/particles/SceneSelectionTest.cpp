// Engine choice from dimensionless numbers on the paper's micromodel and on a
// dense, inertial scene.
#include <gtest/gtest.h>

#include "mmval/particles/SceneSelection.hpp"

namespace mmval::particles {
namespace {

SceneScales paperMicromodel() {
  // 5 um polystyrene, 20 um deep chip, 10 mm wide, porosity 0.58, 5 uL/min,
  // 2.9e7 particles/mL (reference-data/micromodel-experiment.toml).
  SceneScales s;
  s.particle.diameter = 5e-6;
  s.particle.density = 1050;
  const double q = 5e-9 / 60.0;
  s.velocity = q / (10e-3 * 20e-6 * 0.58);
  s.length = 20e-6;
  s.depth = 20e-6;
  s.cell_size = 2e-6;
  s.volume_fraction = 2.9e13 * s.particle.volume();
  return s;
}

TEST(SceneSelection, PaperMicromodelIsOverdamped) {
  const SceneScales s = paperMicromodel();
  EXPECT_NEAR(s.velocity, 7.18e-4, 0.01e-4);
  const EngineChoice c = chooseEngine(s);
  EXPECT_EQ(c.engine, EngineKind::overdamped) << c.reason;
  EXPECT_NEAR(c.numbers.stokes, 1.458e-6 * 7.18e-4 / 20e-6, 1e-3 * c.numbers.stokes);
  EXPECT_LT(c.numbers.reynolds, 0.02);
  EXPECT_NEAR(c.numbers.volume_fraction, 1.9e-3, 0.05e-3);
  EXPECT_TRUE(c.wall_hindrance);  // d/h = 0.25
  EXPECT_TRUE(c.brownian);        // settling Peclet ~165
  EXPECT_EQ(c.coupling, CouplingMode::dilated);  // 2.5 cells per diameter
  EXPECT_NE(c.reason.find("St = "), std::string::npos);
  EXPECT_NE(c.reason.find("overdamped"), std::string::npos);
}

TEST(SceneSelection, DenseInertialSceneIsLiggghts) {
  // 100 um glass beads at 0.1 m/s through 200 um throats, 30 % by volume.
  SceneScales s;
  s.particle.diameter = 100e-6;
  s.particle.density = 2500;
  s.velocity = 0.1;
  s.length = 200e-6;
  s.volume_fraction = 0.3;
  const EngineChoice c = chooseEngine(s);
  EXPECT_EQ(c.engine, EngineKind::liggghts) << c.reason;
  EXPECT_GT(c.numbers.stokes, 0.1);
  EXPECT_NE(c.reason.find("dense"), std::string::npos);
  EXPECT_FALSE(c.brownian);
}

TEST(SceneSelection, DenseButInertialessStillNeedsContacts) {
  SceneScales s = paperMicromodel();
  s.volume_fraction = 0.25;
  EXPECT_EQ(chooseEngine(s).engine, EngineKind::liggghts);
}

TEST(SceneSelection, RejectsNonPositiveScales) {
  SceneScales s = paperMicromodel();
  s.length = 0;
  EXPECT_THROW(chooseEngine(s), std::invalid_argument);
}

}  // namespace
}  // namespace mmval::particles
