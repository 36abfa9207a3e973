// The OpenFOAM peer has no case schemas of its own: it reads the bundled case
// files through mmval's fluid kinds (simulate::registerFluidKinds). These
// tests load those files that way and check that the peer's scene carries
// what each file states (values quoted from the files), so a key the peer
// reads but the fluid schemas do not declare fails here, not in a long run.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>

#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
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


TEST(PeerScene, UnconvergedLevelsAreReportedWithoutAValue) {
  // Canned Results (no OpenFOAM) for a three-level square-array ladder whose finest
  // SIMPLE solve stopped at its cap with residuals near 0.9 and F* = 1.45e5 in its last iterate.
  // That level's row says "not converged" with its residuals and has no value or error (so no
  // observed order), and the run's metrics are null, never 1.45e5.
  const Case c = load("fluid-square-array-phi020.toml");
  const double converged_fstar[] = {52.10, 51.80, 0.0};
  int level = 0;
  PeerRunOptions o;
  o.levels = std::vector<int>{32, 64, 128};
  o.runner = [&](const Scene&, const fs::path&, int) {
    Result r;
    r.ok = true;
    r.cells = 1000 << level;
    r.iterations = level == 2 ? 2000 : 400;
    r.converged = level != 2;
    r.residuals = level == 2 ? std::map<std::string, double>{{"Ux", 0.91}, {"Uy", 0.88}, {"p", 0.93}}
                             : std::map<std::string, double>{{"Ux", 8e-8}, {"Uy", 9e-8}, {"p", 9e-8}};
    r.f_star = level == 2 ? 1.45e5 : converged_fstar[level];
    r.permeability = 1e-8 / *r.f_star;
    ++level;
    return r;
  };
  const RunOutput out = runPeer(c, RunContext{fs::temp_directory_path(), true, false, 0}, o);
  const auto& ladder = out.details.at("ladder");
  ASSERT_EQ(ladder.size(), 3u);
  EXPECT_NEAR(ladder[0].at("value").get<double>(), 52.10, 1e-12);
  EXPECT_FALSE(ladder[2].contains("value"));
  EXPECT_FALSE(ladder[2].contains("error"));
  EXPECT_FALSE(ladder[2].contains("observed_order"));
  EXPECT_EQ(ladder[2].at("status"), "not converged");
  EXPECT_NEAR(ladder[2].at("residuals").at("p").get<double>(), 0.93, 1e-12);
  EXPECT_EQ(out.details.at("status"), "not converged");
  ASSERT_TRUE(out.details.contains("warnings"));
  const std::string w = out.details.at("warnings")[0].get<std::string>();
  EXPECT_NE(w.find("numerics.max_iterations"), std::string::npos) << w;
  EXPECT_NE(w.find("Ux 0.91, Uy 0.88, p 0.93"), std::string::npos) << w;
  ASSERT_TRUE(out.metrics.count("F_star"));
  EXPECT_TRUE(std::isnan(out.metrics.at("F_star")));  // written as null in result.json
  for (const auto& m : evaluateMetrics(c, out)) {
    if (m.name.rfind("F_star", 0) == 0) {
      EXPECT_FALSE(std::isfinite(m.value)) << m.name;
    }
  }
}

TEST(PeerScene, ConvergedLaddersKeepTheirValuesAndOrder) {
  // The same ladder with every level converged: values, errors and the observed order are there.
  const Case c = load("fluid-square-array-phi020.toml");
  const double fstar[] = {52.40, 51.90, 51.775};
  int level = 0;
  PeerRunOptions o;
  o.levels = std::vector<int>{32, 64, 128};
  o.runner = [&](const Scene&, const fs::path&, int) {
    Result r;
    r.ok = true;
    r.f_star = fstar[level++];
    r.permeability = 1e-8 / *r.f_star;
    return r;
  };
  const RunOutput out = runPeer(c, RunContext{fs::temp_directory_path(), true, false, 0}, o);
  const auto& ladder = out.details.at("ladder");
  EXPECT_NEAR(out.metrics.at("F_star"), 51.775, 1e-12);
  EXPECT_FALSE(out.details.contains("status"));
  // p = log2((52.40 - 51.90) / (51.90 - 51.775)) = log2(4) = 2.
  EXPECT_NEAR(ladder[2].at("observed_order").get<double>(), 2.0, 1e-9);
}

}  // namespace
}  // namespace mmval::openfoam
