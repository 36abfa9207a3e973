// simulate::readPeriodicArrayScene: the one reader of a periodic-array case the
// OpenFOAM peer builds from. Values quoted from cases/fluid-square-array-phi020.toml.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "mmval/core/Run.hpp"
#include "mmval/openfoam/BlockMesh.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/PeriodicArrayScene.hpp"

namespace mmval::simulate {
namespace {

Case loadArray(const char* name) {
  static const CaseKindRegistry registry = [] {
    CaseKindRegistry k;
    registerFluidKinds(k);
    return k;
  }();
  return Case::load(std::filesystem::path(MMVAL_SOURCE_DIR) / "cases" / name, registry);
}

constexpr double kRoundOff = 1e-12;

TEST(PeriodicArrayScene, SolidFractionGivesTheRadius) {
  const PeriodicArrayScene s = readPeriodicArrayScene(loadArray("fluid-square-array-phi020.toml"));
  EXPECT_DOUBLE_EQ(s.cell_m, 100e-6);
  EXPECT_DOUBLE_EQ(s.solid_fraction, 0.2);
  EXPECT_NEAR(M_PI * s.radius() * s.radius() / (s.cell_m * s.cell_m), 0.2, kRoundOff);  // phi = pi a^2 / L^2
  EXPECT_NEAR(s.kinematicViscosity(), 1e-6, 1e-6 * kRoundOff);                          // 1e-3 Pa s over 1000 kg/m3
  EXPECT_DOUBLE_EQ(s.mean_velocity_m_s, 1e-4);
}

TEST(PeriodicArrayScene, PeerSceneAndMeshAreTheSameScene) {
  const Case c = loadArray("fluid-square-array-phi020.toml");
  const PeriodicArrayScene s = readPeriodicArrayScene(c);
  const openfoam::Scene p = openfoam::peerScene(c);
  EXPECT_DOUBLE_EQ(p.cell, s.cell_m);
  EXPECT_DOUBLE_EQ(p.radius, s.radius());
  EXPECT_DOUBLE_EQ(p.nu, s.kinematicViscosity());
  EXPECT_DOUBLE_EQ(p.mean_velocity, s.mean_velocity_m_s);
  const openfoam::BlockMeshDict d = openfoam::periodicCellMesh(p.cell, p.radius, p.depth, 32);
  for (const auto& a : d.arcs) EXPECT_NEAR(std::hypot(a.through.x - 0.5 * s.cell_m, a.through.y - 0.5 * s.cell_m), s.radius(), s.cell_m * kRoundOff);
  double x_hi = 0;
  for (const auto& v : d.vertices) x_hi = std::max(x_hi, v.x);
  EXPECT_NEAR(x_hi, s.cell_m, s.cell_m * kRoundOff);
}

}  // namespace
}  // namespace mmval::simulate
