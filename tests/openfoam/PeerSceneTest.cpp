// The OpenFOAM peer has no case schemas of its own: it reads the bundled case
// files through mmval's fluid kinds (simulate::registerFluidKinds). These
// tests load those files that way and check that the peer's scene carries
// what each file states (values quoted from the files), so a key the peer
// reads but the fluid schemas do not declare fails here, not in a long run.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>
#include <vector>

#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/openfoam/BlockMesh.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/simulate/FlowSolver.hpp"
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

TEST(PeerScene, SchaeferTurek2D2LadderJudgesCDMaxAgainstFeatflowAtTheSolversCpuTime) {
  // cases/fluid-schaefer-turek-2d2.toml: the same window and start as mmval's own run, forces
  // scaled by Ubar = 2/3 x 1.5 = 1 m/s and D = 0.1 m (c = 2 F / (rho Ubar^2 D), the benchmark's).
  const Case c = load("fluid-schaefer-turek-2d2.toml");
  const Scene s = peerScene(c);
  EXPECT_DOUBLE_EQ(s.statistics_from, 6.5);
  EXPECT_DOUBLE_EQ(s.initial_perturbation, 0.3);
  EXPECT_NEAR(s.u_ref, 1.0, 1e-15);
  EXPECT_DOUBLE_EQ(s.l_ref, 0.1);
  // A canned level (the values pimpleFoam gave at 64 cells around): the row's value is c_D max,
  // its error against FEATFLOW level 6's 3.22739 (the case lists the 1996 interval first, which
  // gives no relative error): (3.153023 - 3.22739) / 3.22739 = -0.0230424; its CPU seconds are
  // the solver's ExecutionTime, not the 116 s of wall time.
  PeerRunOptions o;
  o.levels = std::vector<int>{64};
  o.runner = [](const Scene&, const fs::path&, int) {
    Result r;
    r.ok = true;
    r.c_d = 3.117;
    r.c_d_max = 3.153023;
    r.c_d_mean = 3.133877;
    r.c_l_max = 0.883511;
    r.strouhal = 0.283089;
    r.shedding_periods = 4;
    r.solve_seconds = 116.24;
    r.cpu_seconds = 93.51;
    return r;
  };
  const RunOutput out = runPeer(c, RunContext{fs::temp_directory_path(), true, false, 0}, o);
  const auto& row = out.details.at("ladder").at(0);
  EXPECT_DOUBLE_EQ(row.at("value").get<double>(), 3.153023);
  EXPECT_NEAR(row.at("error").get<double>(), -0.0230424, 1e-7);
  EXPECT_DOUBLE_EQ(row.at("cpu_seconds").get<double>(), 93.51);
  EXPECT_DOUBLE_EQ(row.at("St").get<double>(), 0.283089);
}

TEST(PeerScene, UnsteadyLaddersOfBothSolversJudgeCDMaxAgainstTheSameReference) {
  // 2D-2 cut to 12 cells around and 0.15 s (a few seconds): mmval's own unsteady ladder row and
  // the peer's (a canned level with mmval's c_D max) carry the same error, c_D max against
  // FEATFLOW level 6's 3.22739 (reference-data/schaefer-turek-2d.toml), so the speed-against-error
  // plot compares like with like; mmval's row also has its CPU seconds, which one rank cannot
  // make exceed its wall time times the cores.
  Case c = load("fluid-schaefer-turek-2d2.toml");
  c.set("numerics.cells_around", std::int64_t{12});
  c.set("numerics.end_time", 0.15);         // s
  c.set("numerics.statistics_from", 0.05);  // s
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / "peer-scene-unsteady-rows";
  fs::remove_all(dir);
  fs::create_directories(dir);
  static const CaseKindRegistry kinds = [] {
    CaseKindRegistry r;
    simulate::registerFluidKinds(r);
    return r;
  }();
  const RunOutput own = kinds.find("cylinder-channel")->run(c, RunContext{dir, true, false, 0});
  const auto& own_row = own.details.at("ladder").at(0);
  const double cd_max = own_row.at("c_D_max").get<double>();
  ASSERT_TRUE(std::isfinite(cd_max));
  EXPECT_DOUBLE_EQ(own_row.at("value").get<double>(), cd_max);
  EXPECT_NEAR(own_row.at("error").get<double>(), (cd_max - 3.22739) / 3.22739, 1e-12);
  const double cpu = own_row.at("cpu_seconds").get<double>(), wall = own_row.at("wall_seconds").get<double>();
  EXPECT_GT(cpu, 0.0);
  EXPECT_LE(cpu, wall * std::max(1U, std::thread::hardware_concurrency()) + 0.05);
  PeerRunOptions o;
  o.levels = std::vector<int>{16};
  o.runner = [&](const Scene&, const fs::path&, int) {
    Result r;
    r.ok = true;
    r.c_d_max = cd_max;
    r.c_d_mean = 0.99 * cd_max;
    return r;
  };
  const RunOutput peer = runPeer(c, RunContext{dir, true, false, 0}, o);
  EXPECT_DOUBLE_EQ(peer.details.at("ladder").at(0).at("error").get<double>(), own_row.at("error").get<double>());
}

TEST(PeerScene, UnconfinedCylinderLadderKeepsTheMeanDragAgainstPark) {
  // cases/fluid-cylinder-unconfined-re100.toml judges c_D mean against Park et al.'s 1.33 and has no
  // single value for c_D max: the row's value stays c_D mean, (1.3151 - 1.33) / 1.33 = -0.0112030.
  const Case c = load("fluid-cylinder-unconfined-re100.toml");
  PeerRunOptions o;
  o.levels = std::vector<int>{48};
  o.runner = [](const Scene&, const fs::path&, int) {
    Result r;
    r.ok = true;
    r.c_d_max = 1.3370;
    r.c_d_mean = 1.3151;
    r.strouhal = 0.15438;
    r.shedding_periods = 4;
    return r;
  };
  const RunOutput out = runPeer(c, RunContext{fs::temp_directory_path(), true, false, 0}, o);
  const auto& row = out.details.at("ladder").at(0);
  EXPECT_DOUBLE_EQ(row.at("value").get<double>(), 1.3151);
  EXPECT_NEAR(row.at("error").get<double>(), -0.0112030, 1e-7);
  EXPECT_FALSE(row.contains("cpu_seconds"));  // a log without ExecutionTime
}

TEST(PeerScene, SquareArrayRadiusFollowsTheSolidFraction) {
  const Scene s = peerScene(load("fluid-square-array-phi020.toml"));
  EXPECT_EQ(s.kind, Scene::Kind::periodic_array);
  EXPECT_DOUBLE_EQ(s.cell, 100e-6);
  EXPECT_NEAR(M_PI * s.radius * s.radius / (s.cell * s.cell), 0.20, 1e-12);  // phi = pi a^2 / L^2
  EXPECT_DOUBLE_EQ(s.mean_velocity, 1e-4);
  EXPECT_DOUBLE_EQ(s.nu, 1e-6);  // 1e-3 Pa s over 1000 kg/m3
}

TEST(PeerScene, SquareArraySurfaceSpacingIsMmvalsCellSize) {
  // cases/fluid-square-array-phi020.toml: L = 100 um, phi = 0.2, numerics.levels [32, 64, 128,
  // 192] cells along the side. D = 2 L sqrt(phi / pi) = 50.46 um, so pi D / h = 1.5853 n: 50.7,
  // 101.5, 202.9, 304.4, whose nearest multiples of 4 are 52, 100, 204, 304 (worked by hand).
  const Case c = load("fluid-square-array-phi020.toml");
  const double L = 100e-6, D = 2 * L * std::sqrt(0.2 / M_PI);
  const std::vector<int> per_side{32, 64, 128, 192}, around{52, 100, 204, 304};
  std::vector<BlockMeshDict> meshes;
  PeerRunOptions o;
  o.runner = [&](const Scene& s, const fs::path&, int) {
    meshes.push_back(periodicCellMesh(s.cell, s.radius, s.depth, s.cells_around));  // the mesh the peer would write
    Result r;
    r.ok = true;
    r.f_star = 51.53;
    r.permeability = L * L / *r.f_star;
    return r;
  };
  const RunOutput out = runPeer(c, RunContext{fs::temp_directory_path(), true, false, 0}, o);
  const auto& ladder = out.details.at("ladder");
  ASSERT_EQ(ladder.size(), per_side.size());
  ASSERT_EQ(meshes.size(), per_side.size());
  for (std::size_t i = 0; i < per_side.size(); ++i) {
    // mmval's grid at this level: uniform cells of side h = L / n.
    const simulate::FlowProblem p = simulate::squareArrayProblem(L, per_side[i], 0.2, 1e-3, 1.0);
    const double h = p.x.maxWidth();
    EXPECT_NEAR(h, L / per_side[i], 1e-12 * L);
    EXPECT_NEAR(p.y.minWidth(), h, 1e-12 * L);
    // The peer's O-grid: its cells on the circumference are the tangential cells of its four blocks.
    int on_circle = 0;
    for (const Block& b : meshes[i].blocks) on_circle += b.cells[0];
    EXPECT_EQ(on_circle, around[i]) << "cells_per_side " << per_side[i];
    // Same spacing within the rounding to a multiple of 4: |pi D / n_around - h| / h <= 2 / n_around.
    const double surface = M_PI * D / on_circle;
    EXPECT_LE(std::abs(surface - h) / h, 2.0 / on_circle) << "surface " << surface << " m, h " << h << " m";
    // result.json's ladder row carries both numbers and both spacings.
    EXPECT_EQ(ladder[i].at("cells_per_side").get<int>(), per_side[i]);
    EXPECT_EQ(ladder[i].at("cells_around").get<int>(), around[i]);
    EXPECT_NEAR(ladder[i].at("spacing_m").get<double>(), h, 1e-12 * h);
    EXPECT_NEAR(ladder[i].at("surface_spacing_m").get<double>(), surface, 1e-12 * surface);
  }
  // A scene read on its own takes the file's numerics.cells_per_side (64): 100 cells around.
  EXPECT_EQ(peerScene(c).cells_around, 100);
}

TEST(PeerScene, CellsAroundOnAnArrayIsRefusedNamingCellsPerSide) {
  // numerics.cells_around is the cylinder kinds' key (cells around the circumference); an array's
  // resolution is numerics.cells_per_side. A file that still sets the former is refused (exit 2
  // from the command line), naming the file, the line, the key and the key to use.
  const fs::path dir = fs::temp_directory_path() / "mmval-peer-scene-old-key";
  fs::create_directories(dir);
  const fs::path file = dir / "array-cells-around.toml";
  std::ofstream(file) << "[case]\nname = \"array\"\nkind = \"periodic-array\"\n"
                         "[geometry]\ncell = \"100 um\"\nsolid_fraction = 0.2\n"
                         "[numerics]\ncells_around = 64\n";
  try {
    load(file.string().c_str());
    FAIL() << "numerics.cells_around was accepted on a periodic-array case";
  } catch (const InputError& e) {
    const std::string m = e.what();
    EXPECT_EQ(e.where().key, "numerics.cells_around") << m;
    EXPECT_NE(m.find("array-cells-around.toml:8"), std::string::npos) << m;
    EXPECT_NE(m.find("numerics.cells_per_side"), std::string::npos) << m;
  }
  fs::remove_all(dir);
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

TEST(PeerScene, DepthModelsOfAnImageCaseRunAsMmvalsDo) {
  // cases/fluid-pore2chip-peer.toml (ladder 0.25 / 0.5 / 1 cells per pixel) with depth_model
  // "both": the peer solves plane 2D, then the depth-averaged model with the friction of
  // geometry.depth (default 20 um), each on the whole ladder, as mmval's image kind does; its
  // `permeability` is the depth-averaged one and each model has its own extrapolated metrics.
  Case c = load("fluid-pore2chip-peer.toml");
  c.set("numerics.depth_model", std::string("both"));
  // Canned levels: k_2d = 30 + 8 h^2 and k_da = 3 + 0.4 h^2 darcy (h = 1 / cells_per_pixel), so
  // the Richardson values of the three levels (second order, smooth boundary) are 30 and 3 D.
  constexpr double kDarcy = 9.869233e-13;
  std::vector<std::pair<double, fs::path>> seen;  // (hele_shaw_depth, folder) of each run
  PeerRunOptions o;
  o.runner = [&](const Scene& s, const fs::path& dir, int) {
    seen.emplace_back(s.hele_shaw_depth, dir.filename());
    const double h = 1 / s.cells_per_pixel;
    Result r;
    r.ok = true;
    r.cells = 1000;
    r.permeability = (s.hele_shaw_depth > 0 ? 3 + 0.4 * h * h : 30 + 8 * h * h) * kDarcy;
    return r;
  };
  const RunOutput out = runPeer(c, RunContext{fs::temp_directory_path(), true, false, 0}, o);
  ASSERT_EQ(seen.size(), 6u);
  for (std::size_t i = 0; i < 6; ++i) EXPECT_DOUBLE_EQ(seen[i].first, i < 3 ? 0.0 : 20e-6) << i;
  EXPECT_EQ(seen[0].second, "openfoam-2d-level0");
  EXPECT_EQ(seen[5].second, "openfoam-depth-averaged-level2");
  EXPECT_NEAR(out.metrics.at("permeability") / kDarcy, 3.4, 1e-9);
  EXPECT_NEAR(out.metrics.at("permeability_depth_averaged") / kDarcy, 3.4, 1e-9);
  EXPECT_NEAR(out.metrics.at("permeability_2d") / kDarcy, 38.0, 1e-9);
  EXPECT_NEAR(out.metrics.at("depth_model_ratio"), 3.4 / 38.0, 1e-12);
  EXPECT_NEAR(out.metrics.at("permeability_depth_averaged_extrapolated") / kDarcy, 3.0, 1e-9);
  EXPECT_NEAR(out.metrics.at("permeability_2d_extrapolated") / kDarcy, 30.0, 1e-9);
  EXPECT_NEAR(out.metrics.at("permeability_depth_averaged_observed_order"), 2.0, 1e-9);
  EXPECT_EQ(out.details.at("grid_convergence").at("depth-averaged").at("status"), "monotone");
  EXPECT_EQ(out.details.at("grid_convergence").at("2d").at("status"), "monotone");
  const auto& ladder = out.details.at("ladder");
  ASSERT_EQ(ladder.size(), 3u);
  EXPECT_EQ(ladder[2].at("depth_model"), "depth-averaged");
  EXPECT_NEAR(ladder[2].at("value").get<double>() / kDarcy, 3.4, 1e-9);
  EXPECT_EQ(out.details.at("runs").size(), 6u);

  // "depth-averaged" alone: one ladder in the plain folders; "3d" is refused naming the key.
  c.set("numerics.depth_model", std::string("depth-averaged"));
  seen.clear();
  const RunOutput da = runPeer(c, RunContext{fs::temp_directory_path(), true, false, 0}, o);
  ASSERT_EQ(seen.size(), 3u);
  EXPECT_EQ(seen[0].second, "openfoam-level0");
  EXPECT_DOUBLE_EQ(peerScene(c).hele_shaw_depth, 20e-6);
  EXPECT_FALSE(da.metrics.count("permeability_2d"));
  c.set("numerics.depth_model", std::string("3d"));
  try {
    peerScene(c);
    FAIL() << "a 3d-only case reached the peer";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("numerics.depth_model"), std::string::npos) << e.what();
  }
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
  // The O-grids refine as their cells around: 52, 100, 204 at cells_per_side 32, 64, 128, so
  // p = log((52.40 - 51.90) / (51.90 - 51.775)) / log(204 / 100) = log 4 / log 2.04 = 1.9439.
  EXPECT_NEAR(ladder[2].at("observed_order").get<double>(), std::log(4.0) / std::log(2.04), 1e-9);
}

}  // namespace
}  // namespace mmval::openfoam
