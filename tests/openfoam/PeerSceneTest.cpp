// The OpenFOAM peer has no case schemas of its own: it reads the bundled case
// files through mmval's fluid kinds (simulate::registerFluidKinds). These
// tests load those files that way and check that the peer's scene carries
// what each file states (values quoted from the files), so a key the peer
// reads but the fluid schemas do not declare fails here, not in a long run.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "mmval/core/Error.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/simulate/Kinds.hpp"

namespace mmval::openfoam {
namespace {

namespace fs = std::filesystem;

Case load(const char* name) {
  static const CaseKindRegistry registry = [] {
    CaseKindRegistry r;
    simulate::registerFluidKinds(r);
    return r;
  }();
  return Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / name, registry);
}

TEST(PeerScene, SchaeferTurek2D1IsSteadyWithItsProbes) {
  const Scene s = peerScene(load("fluid-schaefer-turek-2d1.toml"));
  EXPECT_EQ(s.kind, Scene::Kind::cylinder_channel);
  EXPECT_DOUBLE_EQ(s.length, 2.2);
  EXPECT_DOUBLE_EQ(s.height, 0.41);
  EXPECT_DOUBLE_EQ(s.cx, 0.2);
  EXPECT_DOUBLE_EQ(s.cy, 0.2);
  EXPECT_DOUBLE_EQ(s.diameter, 0.1);
  EXPECT_DOUBLE_EQ(s.nu, 1e-3);  // viscosity 1e-3 Pa s over density 1 kg/m3
  EXPECT_DOUBLE_EQ(s.inflow_max, 0.3);
  EXPECT_FALSE(s.uniform_inflow);
  EXPECT_FALSE(s.slip_walls);
  EXPECT_NEAR(s.u_ref, 0.2, 1e-15);  // mean of the parabola: 2/3 of 0.3 m/s (Re 20 with D 0.1 m)
  EXPECT_DOUBLE_EQ(s.l_ref, 0.1);
  ASSERT_EQ(s.pressure_probes.size(), 2u);
  EXPECT_DOUBLE_EQ(s.pressure_probes[0][0], 0.15);
  EXPECT_DOUBLE_EQ(s.pressure_probes[1][0], 0.25);
  EXPECT_DOUBLE_EQ(s.pressure_probes[1][1], 0.2);
  EXPECT_FALSE(s.unsteady);
}

TEST(PeerScene, SchaeferTurek2D2IsUnsteadyAtRe100) {
  const Scene s = peerScene(load("fluid-schaefer-turek-2d2.toml"));
  EXPECT_TRUE(s.unsteady);
  EXPECT_DOUBLE_EQ(s.end_time, 8.0);
  EXPECT_DOUBLE_EQ(s.dt, 2e-4);
  EXPECT_DOUBLE_EQ(s.inflow_max, 1.5);
  EXPECT_NEAR(s.u_ref * s.diameter / s.nu, 100.0, 1e-9);  // Re = Ubar D / nu
}

TEST(PeerScene, SquareArrayRadiusFollowsTheSolidFraction) {
  const Scene s = peerScene(load("fluid-square-array-phi020.toml"));
  EXPECT_EQ(s.kind, Scene::Kind::periodic_array);
  EXPECT_DOUBLE_EQ(s.cell, 100e-6);
  EXPECT_NEAR(M_PI * s.radius * s.radius / (s.cell * s.cell), 0.20, 1e-12);  // phi = pi a^2 / L^2
  EXPECT_DOUBLE_EQ(s.mean_velocity, 1e-4);
  EXPECT_DOUBLE_EQ(s.nu, 1e-6);  // 1e-3 Pa s over 1000 kg/m3
}

TEST(PeerScene, Pore2ChipMaskPixelAndDrive) {
  const Scene s = peerScene(load("fluid-pore2chip.toml"));
  EXPECT_EQ(s.kind, Scene::Kind::image);
  EXPECT_EQ(s.mask.filename(), "grain_network.png");
  EXPECT_DOUBLE_EQ(s.pixel, 10e-6);
  EXPECT_TRUE(s.grain_dark);
  EXPECT_DOUBLE_EQ(s.cells_per_pixel, 0.5);
  EXPECT_DOUBLE_EQ(s.pressure_drop, 1e-3);  // 1 Pa over 1000 kg/m3: the peer's pressures are kinematic
}

TEST(PeerScene, OtherKindsAreRefusedNamingTheKind) {
  try {
    peerScene(load("fluid-poiseuille.toml"));
    FAIL() << "a channel case reached the peer";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("case.kind"), std::string::npos) << e.what();
    EXPECT_EQ(e.got(), "channel");
  }
}

}  // namespace
}  // namespace mmval::openfoam
