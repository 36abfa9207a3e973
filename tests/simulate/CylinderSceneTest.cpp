// simulate::readCylinderScene: the one reader of a cylinder-channel case that
// mmval's own solver and the OpenFOAM peer both build from. Values are quoted
// from the bundled case files; the peer's scene and its blockMesh must carry
// the same numbers, and numerics.cells_around must set the same surface
// spacing pi D / cells_around in both.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>
#include <string>

#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/openfoam/BlockMesh.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/simulate/CylinderScene.hpp"
#include "mmval/simulate/Kinds.hpp"

namespace mmval::simulate {
namespace {

namespace fs = std::filesystem;

const CaseKindRegistry& registry() {
  static const CaseKindRegistry r = [] {
    CaseKindRegistry k;
    registerFluidKinds(k);
    return k;
  }();
  return r;
}

Case load(const char* name) { return Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / name, registry()); }

constexpr double kRoundOff = 1e-12;  // deterministic algebra on O(1) SI values

TEST(CylinderScene, SchaeferTurek2D1AsTheFileStatesIt) {
  const CylinderScene s = readCylinderScene(load("fluid-schaefer-turek-2d1.toml"));
  EXPECT_DOUBLE_EQ(s.length_m, 2.2);
  EXPECT_DOUBLE_EQ(s.height_m, 0.41);
  EXPECT_DOUBLE_EQ(s.centre_x_m, 0.2);
  EXPECT_DOUBLE_EQ(s.centre_y_m, 0.2);
  EXPECT_DOUBLE_EQ(s.diameter_m, 0.1);
  EXPECT_DOUBLE_EQ(s.depth_m, 0.1);  // the schema's default
  EXPECT_DOUBLE_EQ(s.inflow_max_m_s, 0.3);
  EXPECT_FALSE(s.uniform_inflow);
  EXPECT_FALSE(s.slip_walls);
  // Schaefer & Turek (1996) 2D-1: U_mean = 2/3 U_max = 0.2 m/s, Re = U_mean D / nu = 20, D / H = 0.1 / 0.41.
  EXPECT_NEAR(s.u_ref_m_s, 0.2, kRoundOff);
  EXPECT_DOUBLE_EQ(s.l_ref_m, 0.1);
  EXPECT_NEAR(s.reynolds(), 20.0, kRoundOff);
  EXPECT_NEAR(s.blockage(), 0.1 / 0.41, kRoundOff);
  EXPECT_NEAR(s.forceCoefficient(), 500.0, 500.0 * kRoundOff);  // 2 / (1 kg/m3 x (0.2 m/s)^2 x 0.1 m)
  ASSERT_EQ(s.pressure_probes.size(), 2u);
  EXPECT_DOUBLE_EQ(s.pressure_probes[0][0], 0.15);
  EXPECT_DOUBLE_EQ(s.pressure_probes[0][1], 0.2);
  EXPECT_DOUBLE_EQ(s.pressure_probes[1][0], 0.25);
  // The parabola: zero at the walls, U_max at mid-height.
  EXPECT_NEAR(s.inflowAt(0.0), 0.0, kRoundOff);
  EXPECT_NEAR(s.inflowAt(0.205), 0.3, kRoundOff);
}

TEST(CylinderScene, PeerSceneIsTheSameScene) {
  for (const char* file : {"fluid-schaefer-turek-2d1.toml", "fluid-schaefer-turek-2d2.toml", "fluid-cylinder-paper-re40.toml"}) {
    SCOPED_TRACE(file);
    const Case c = load(file);
    const CylinderScene s = readCylinderScene(c);
    const openfoam::Scene p = openfoam::peerScene(c);
    EXPECT_DOUBLE_EQ(p.length, s.length_m);
    EXPECT_DOUBLE_EQ(p.height, s.height_m);
    EXPECT_DOUBLE_EQ(p.depth, s.depth_m);
    EXPECT_DOUBLE_EQ(p.cx, s.centre_x_m);
    EXPECT_DOUBLE_EQ(p.cy, s.centre_y_m);
    EXPECT_DOUBLE_EQ(p.diameter, s.diameter_m);
    EXPECT_DOUBLE_EQ(p.rho, s.density_kg_m3);
    EXPECT_NEAR(p.nu, s.viscosity_pa_s / s.density_kg_m3, kRoundOff * p.nu);
    EXPECT_DOUBLE_EQ(p.inflow_max, s.inflow_max_m_s);
    EXPECT_EQ(p.uniform_inflow, s.uniform_inflow);
    EXPECT_EQ(p.slip_walls, s.slip_walls);
    EXPECT_DOUBLE_EQ(p.u_ref, s.u_ref_m_s);
    EXPECT_DOUBLE_EQ(p.l_ref, s.l_ref_m);
    EXPECT_EQ(p.pressure_probes, s.pressure_probes);
  }
}

TEST(CylinderScene, PeerMeshSpansTheSceneWithCellsAroundOnTheCircumference) {
  const CylinderScene s = readCylinderScene(load("fluid-schaefer-turek-2d1.toml"));
  const openfoam::CylinderChannel g{s.length_m, s.height_m, s.centre_x_m, s.centre_y_m, s.diameter_m, s.depth_m};
  for (const int n : {32, 64, 128}) {
    SCOPED_TRACE(n);
    const openfoam::BlockMeshDict d = openfoam::cylinderChannelMesh(g, n);
    double x_lo = 1e300, x_hi = -1e300, y_lo = 1e300, y_hi = -1e300, z_hi = -1e300;
    for (const auto& v : d.vertices) {
      x_lo = std::min(x_lo, v.x), x_hi = std::max(x_hi, v.x), y_lo = std::min(y_lo, v.y), y_hi = std::max(y_hi, v.y);
      z_hi = std::max(z_hi, v.z);
    }
    EXPECT_NEAR(x_lo, 0.0, kRoundOff);
    EXPECT_NEAR(x_hi, s.length_m, kRoundOff);
    EXPECT_NEAR(y_lo, 0.0, kRoundOff);
    EXPECT_NEAR(y_hi, s.height_m, kRoundOff);
    EXPECT_NEAR(z_hi, s.depth_m, kRoundOff);
    for (const auto& a : d.arcs) EXPECT_NEAR(std::hypot(a.through.x - s.centre_x_m, a.through.y - s.centre_y_m), 0.5 * s.diameter_m, kRoundOff);
    // Cells on the circumference: the tangential cells of the blocks that touch the cylinder patch
    // (blockMesh spaces an arc's points evenly, so each is pi D / n long, as mmval's cells there).
    std::set<int> on_cylinder;
    for (const auto& p : d.patches)
      if (p.name == "cylinder")
        for (const auto& f : p.faces) on_cylinder.insert(f[0]);
    int around = 0;
    for (const auto& b : d.blocks)
      if (on_cylinder.count(b.v[2]) != 0 && on_cylinder.count(b.v[3]) != 0) around += b.cells[0];
    EXPECT_EQ(around, n);
    EXPECT_NEAR(M_PI * s.diameter_m / around, surfaceSpacing(s, n), kRoundOff);
  }
}

TEST(CylinderScene, CylinderOutsideTheChannelNamesTheKey) {
  const std::string text = R"(
[case]
name = "outside"
kind = "cylinder-channel"
[geometry]
cylinder_y = "0.38 m"
[inflow]
max_velocity = "0.3 m/s"
)";
  const Case c = Case::parse(text, "outside.toml", registry());
  try {
    readCylinderScene(c);
    FAIL() << "a cylinder reaching past the top wall (0.38 + 0.05 > 0.41 m) was accepted";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().key, "geometry.cylinder_x") << e.what();
    EXPECT_NE(e.problem().find("does not fit"), std::string::npos) << e.what();
  }
  EXPECT_THROW(openfoam::peerScene(c), InputError);
}

TEST(CylinderScene, StartVortexPeaksAtHalfTheInflowTimesEps) {
  // u = A (-Y, X) exp(-(X^2 + Y^2)), A = eps U sqrt(e / 2): |u| = A rho exp(-rho^2) (rho = r / D)
  // peaks at rho = 1 / sqrt 2 with A exp(-1/2) / sqrt 2 = eps U / 2, 1.5 D behind the centre.
  const double D = 0.1, eps = 0.3, U = 2.0;
  const auto v = startVortex(0.2, 0.25, D, eps, U);
  EXPECT_DOUBLE_EQ(v.x_m, 0.35);
  EXPECT_DOUBLE_EQ(v.y_m, 0.25);
  double peak = 0, peak_r = 0;
  for (int k = 1; k <= 4000; ++k) {
    const double r = k * 1e-3 * D;
    const auto u = v.velocity(v.x_m + r, v.y_m);
    EXPECT_DOUBLE_EQ(u[0], 0.0);  // on the axis through the vortex the flow is across it
    if (std::abs(u[1]) > peak) peak = std::abs(u[1]), peak_r = r;
  }
  EXPECT_NEAR(peak, eps * U / 2, 1e-6);
  EXPECT_NEAR(peak_r, D / std::sqrt(2.0), 1e-3 * D);
  // Counter-clockwise: above the vortex the flow goes upstream.
  EXPECT_LT(v.velocity(v.x_m, v.y_m + 0.5 * D)[0], 0.0);
}

}  // namespace
}  // namespace mmval::simulate
