// The OpenFOAM case writer, checked without running OpenFOAM: block
// topology, patch names and types, boundary conditions per scene kind.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <vector>

#include <unistd.h>

#include "mmval/openfoam/BlockMesh.hpp"
#include "mmval/openfoam/Peer.hpp"

namespace mmval::openfoam {
namespace {

using ::testing::HasSubstr;

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream b;
  b << in.rdbuf();
  return b.str();
}

/// Each interior face of a valid 2D block layout is shared by exactly two
/// blocks and each boundary face belongs to exactly one patch.
void expectClosedTopology(const BlockMeshDict& d) {
  std::map<std::set<int>, int> faces;
  for (const auto& b : d.blocks) {
    const int f[6][4] = {{0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {1, 2, 6, 5}, {2, 3, 7, 6}, {3, 0, 4, 7}};
    for (const auto& face : f) faces[{b.v[face[0]], b.v[face[1]], b.v[face[2]], b.v[face[3]]}]++;
  }
  std::map<std::set<int>, int> patch_faces;
  for (const auto& p : d.patches)
    for (const auto& f : p.faces) patch_faces[{f[0], f[1], f[2], f[3]}]++;
  for (const auto& [face, count] : faces) {
    if (count == 2) {
      EXPECT_EQ(patch_faces.count(face), 0u) << "interior face listed in a patch";
    } else {
      EXPECT_EQ(count, 1);
      EXPECT_EQ(patch_faces[face], 1) << "boundary face not in exactly one patch";
    }
  }
  for (const auto& [face, count] : patch_faces) EXPECT_EQ(faces.count(face), 1u) << "patch face is not a block face";
}

TEST(BlockMesh, CylinderChannelIsClosedAndNamesItsPatches) {
  const CylinderChannel g;  // Schaefer-Turek geometry
  const BlockMeshDict d = cylinderChannelMesh(g, 64);
  EXPECT_EQ(d.blocks.size(), 12u);
  EXPECT_EQ(d.arcs.size(), 8u);
  expectClosedTopology(d);
  const std::string text = d.text();
  for (const char* name : {"inlet", "outlet", "walls", "cylinder", "frontAndBack"}) EXPECT_THAT(text, HasSubstr(name));
  EXPECT_THAT(text, HasSubstr("type empty;"));
  // Arc mid-points lie on the cylinder: |p - c| = r.
  for (const auto& a : d.arcs) EXPECT_NEAR(std::hypot(a.through.x - 0.2, a.through.y - 0.2), 0.05, 1e-12);
  EXPECT_GT(d.cellCount(), 2000);
  EXPECT_LT(d.cellCount(), 20000);
}

TEST(BlockMesh, CellsAroundMustBeAMultipleOfFour) {
  EXPECT_THROW(cylinderChannelMesh(CylinderChannel{}, 30), std::invalid_argument);
  EXPECT_THROW(periodicCellMesh(1.0, 0.6, 0.1, 32), std::invalid_argument);  // radius too large for the cell
}

TEST(BlockMesh, PeriodicCellHasCyclicPairs) {
  const BlockMeshDict d = periodicCellMesh(1.0, std::sqrt(0.2 / M_PI), 0.1, 32);
  expectClosedTopology(d);
  const std::string text = d.text();
  EXPECT_THAT(text, HasSubstr("type cyclic;"));
  EXPECT_THAT(text, HasSubstr("neighbourPatch right;"));
  EXPECT_THAT(text, HasSubstr("neighbourPatch top;"));
}

TEST(BlockMesh, CellsAroundForASpacingAreTheNearestMultipleOfFour) {
  // pi D / h for D = 1: 10 pi = 31.4 -> 32; 8 pi = 25.1 -> 24; 2 pi = 6.28 -> 8 (the floor).
  EXPECT_EQ(cellsAroundForSpacing(1.0, 0.1), 32);
  EXPECT_EQ(cellsAroundForSpacing(1.0, 0.125), 24);
  EXPECT_EQ(cellsAroundForSpacing(1.0, 0.5), 8);
  EXPECT_EQ(cellsAroundForSpacing(1.0, 10.0), 8);
  // pi D / h exactly 100: the surface spacing is h itself.
  EXPECT_EQ(cellsAroundForSpacing(100 / M_PI, 1.0), 100);
  EXPECT_THROW(cellsAroundForSpacing(0.0, 0.1), std::invalid_argument);
  EXPECT_THROW(cellsAroundForSpacing(1.0, -0.1), std::invalid_argument);
  EXPECT_THROW(cellsAroundForSpacing(1.0, std::nan("")), std::invalid_argument);
  // Within the rounding: |pi D / n - h| / h <= 2 / n whenever pi D / h >= 6.
  for (double h = 0.01; h < 0.5; h *= 1.07) {
    const int n = cellsAroundForSpacing(1.0, h);
    EXPECT_EQ(n % 4, 0);
    EXPECT_LE(std::abs(M_PI / n - h) / h, 2.0 / n + 1e-12) << "h " << h << " n " << n;
  }
}

TEST(CaseWriter, CylinderCaseHasParabolicInletForcesAndProbes) {
  Scene s;
  s.pressure_probes = {{0.15, 0.2}, {0.25, 0.2}};
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "foam-writer-cyl";
  std::filesystem::remove_all(dir);
  const long long cells = writeCase(s, dir, 2);
  EXPECT_GT(cells, 0);
  for (const char* f : {"system/blockMeshDict", "system/controlDict", "system/fvSchemes", "system/fvSolution",
                        "system/decomposeParDict", "constant/transportProperties", "constant/turbulenceProperties", "0/U", "0/p", "Allrun", "Allclean", "case.foam"})
    EXPECT_TRUE(std::filesystem::exists(dir / f)) << f;
  const std::string allrun = slurp(dir / "Allrun");
  EXPECT_THAT(allrun, HasSubstr("checkMesh > log.checkMesh 2>&1 || exit 1\n"));
  EXPECT_THAT(allrun, HasSubstr("reconstructPar -latestTime > log.reconstructPar 2>&1 || exit 1\n"));  // written for 2 ranks
  EXPECT_THAT(slurp(dir / "Allclean"), HasSubstr("rm -rf constant/polyMesh postProcessing processor[0-9]* log.*"));
  const std::string u = slurp(dir / "0/U");
  EXPECT_THAT(u, HasSubstr("exprFixedValue"));
  EXPECT_THAT(u, HasSubstr("4*0.3*pos().y()*(0.41-pos().y())"));
  EXPECT_THAT(slurp(dir / "0/p"), HasSubstr("outlet\n    {\n        type fixedValue;"));
  const std::string control = slurp(dir / "system/controlDict");
  EXPECT_THAT(control, HasSubstr("application     simpleFoam;"));
  EXPECT_THAT(control, HasSubstr("type forceCoeffs;"));
  EXPECT_THAT(control, HasSubstr("Aref 0.01;"));  // D * depth = 0.1 * 0.1
  EXPECT_THAT(control, HasSubstr("type probes;"));
  EXPECT_THAT(slurp(dir / "system/decomposeParDict"), HasSubstr("method simple;"));
  EXPECT_THAT(slurp(dir / "constant/transportProperties"), HasSubstr("nu 0.001;"));
}

TEST(CaseWriter, PeriodicCaseDrivesTheMeanVelocity) {
  Scene s;
  s.kind = Scene::Kind::periodic_array;
  s.radius = std::sqrt(0.2 / M_PI);
  s.cells_around = 32;
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "foam-writer-array";
  std::filesystem::remove_all(dir);
  writeCase(s, dir);
  EXPECT_THAT(slurp(dir / "constant/fvOptions"), HasSubstr("type meanVelocityForce;"));
  EXPECT_THAT(slurp(dir / "system/fvSolution"), HasSubstr("pRefCell 0;"));
  EXPECT_THAT(slurp(dir / "0/p"), HasSubstr("type cyclic;"));
}

TEST(CaseWriter, UnsteadyCaseUsesPimpleFoam) {
  Scene s;
  s.unsteady = true;
  s.end_time = 1.0;
  s.dt = 1e-3;
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "foam-writer-pimple";
  std::filesystem::remove_all(dir);
  writeCase(s, dir);
  EXPECT_THAT(slurp(dir / "system/controlDict"), HasSubstr("application     pimpleFoam;"));
  EXPECT_THAT(slurp(dir / "system/fvSchemes"), HasSubstr("default backward;"));
  EXPECT_THAT(slurp(dir / "system/fvSolution"), HasSubstr("PIMPLE"));
}

TEST(CaseWriter, DepthAveragedSceneHasTheHeleShawFrictionOnEveryCell) {
  // mmval's depth-averaged model (FlowOperator: friction 12 mu u / h^2; docs/validation/depth-model.md)
  // as OpenFOAM's Darcy porosity: d = 12 / h^2 along x and y, none along z (the empty direction),
  // on the cellZone that topoSet makes of every cell before checkMesh and the solve.
  Scene s;
  s.kind = Scene::Kind::channel;
  s.length = 80e-6;
  s.height = 40e-6;
  s.depth = 5e-6;
  s.hele_shaw_depth = 17e-6;  // 12 / h^2 = 4.15224913495e10 m^-2
  s.cells_around = 16;
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "foam-writer-hele-shaw";
  std::filesystem::remove_all(dir);
  writeCase(s, dir);
  const std::string fv = slurp(dir / "constant/fvOptions");
  EXPECT_THAT(fv, HasSubstr("type explicitPorositySource;"));
  EXPECT_THAT(fv, HasSubstr("type DarcyForchheimer;"));
  EXPECT_THAT(fv, HasSubstr("cellZone depthAveraged;"));
  EXPECT_THAT(fv, HasSubstr("f (0 0 0);"));
  const std::string key = "\n        d (";
  const auto at = fv.find(key);
  ASSERT_NE(at, std::string::npos) << fv;
  std::istringstream d(fv.substr(at + key.size()));
  double dx = 0, dy = 0, dz = -1;
  d >> dx >> dy >> dz;
  const double expected = 12.0 / (17e-6 * 17e-6);
  // Written with 12 significant digits: round-off class.
  EXPECT_NEAR(dx, expected, 1e-11 * expected);
  EXPECT_NEAR(dy, expected, 1e-11 * expected);
  EXPECT_EQ(dz, 0.0);
  const std::string topo = slurp(dir / "system/topoSetDict");
  EXPECT_THAT(topo, HasSubstr("name depthAveraged; type cellSet; action new; source boxToCell;"));
  EXPECT_THAT(topo, HasSubstr("name depthAveraged; type cellZoneSet; action new; source setToCellZone; set depthAveraged;"));
  const std::string allrun = slurp(dir / "Allrun");
  const auto topo_at = allrun.find("topoSet > log.topoSet 2>&1 || exit 1\n"), check_at = allrun.find("checkMesh > log.checkMesh");
  ASSERT_NE(topo_at, std::string::npos) << allrun;
  EXPECT_LT(allrun.find("blockMesh > log.blockMesh"), topo_at);
  EXPECT_LT(topo_at, check_at);

  // Plane 2D (depth 0) has no friction and no zone; a negative depth and a cylinder scene are refused.
  s.hele_shaw_depth = 0;
  const auto plane = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "foam-writer-plane";
  std::filesystem::remove_all(plane);
  writeCase(s, plane);
  EXPECT_FALSE(std::filesystem::exists(plane / "constant/fvOptions"));
  EXPECT_FALSE(std::filesystem::exists(plane / "system/topoSetDict"));
  EXPECT_THAT(slurp(plane / "Allrun"), ::testing::Not(HasSubstr("topoSet")));
  s.hele_shaw_depth = -1e-6;
  EXPECT_THROW(writeCase(s, plane), std::invalid_argument);
  Scene cyl;
  cyl.hele_shaw_depth = 20e-6;
  EXPECT_THROW(writeCase(cyl, plane), std::invalid_argument);
}

TEST(BlockMesh, ChannelSidesKeepUniformCells) {
  // Schaefer-Turek (2.2 m x 0.41 m, D 0.1 m at (0.2, 0.2)) at 64 cells around: box half side
  // a = D, h = 2a / 16 = 0.0125 m; left 8, below 8, above round(0.11 / h) = 9 columns/rows of
  // uniform cells, downstream round(1.9 / (h (1 + 3.8) / 2)) = 63 cells growing 3.8x:
  // (8 + 16 + 63) (8 + 16 + 9) - 16^2 + 4 16^2 = 3,639 cells, the 2D-2 study's coarsest O-grid
  // (docs/validation/cylinder-unsteady.md). Only the four O-grid blocks (radially) and the three
  // downstream ones (along x) are graded.
  const BlockMeshDict d = cylinderChannelMesh(CylinderChannel{}, 64);
  EXPECT_EQ(d.cellCount(), 3639);
  int graded_x = 0, graded_y = 0;
  for (const auto& b : d.blocks) {
    graded_x += b.grading[0] != 1.0;
    graded_y += b.grading[1] != 1.0;
  }
  EXPECT_EQ(graded_x, 3);
  EXPECT_EQ(graded_y, 4);
  // The paper's channel (5 mm x 6.3 mm, D 0.2 mm at (2.3, 3.15) mm): its sides lie 10.5 D and
  // 14.75 D from the box, inside the 16 D below which a side is a channel's, so they stay uniform.
  const BlockMeshDict paper = cylinderChannelMesh(CylinderChannel{5e-3, 6.3e-3, 2.3e-3, 3.15e-3, 0.2e-3, 0.2e-4}, 64);
  for (const auto& b : paper.blocks) EXPECT_TRUE(b.grading[1] == 1.0 || b.grading[1] == 0.25);  // 1 / radial_grading in the O-grid
}

/// Sizes of the first and last of n cells along a block edge of length len with simpleGrading e
/// (last / first, a geometric progression): first = len (r - 1) / (r^n - 1), r = e^(1 / (n - 1)).
std::pair<double, double> endCells(double len, int n, double e) {
  const double r = std::pow(e, 1.0 / (n - 1));
  const double first = std::abs(r - 1) < 1e-15 ? len / n : len * (r - 1) / (std::pow(r, n) - 1);
  return {first, first * std::pow(r, n - 1)};
}

TEST(BlockMesh, FarFieldSidesGrowTheirCellsToAtMostFourBoxCells) {
  // cases/fluid-cylinder-unconfined-re100.toml: 6 m x 8 m, D 0.1 m at (2, 4): the box (a = D)
  // lies 19 D from the inlet and 39 D from each slip side. At 48 cells around, h = D / 6: the
  // sides grow 39 / 10 = 3.9x over round(234 / 2.45) = 96 rows, the inlet side 1.9x over
  // round(114 / 1.45) = 79 columns, downstream 4x over 94: (79 + 12 + 94) (96 + 12 + 96) - 144 + 576
  // = 38,172 cells (checkMesh counted the same for the generated case).
  const CylinderChannel g{6.0, 8.0, 2.0, 4.0, 0.1, 0.01};
  const BlockMeshDict d = cylinderChannelMesh(g, 48);
  expectClosedTopology(d);
  EXPECT_EQ(d.cellCount(), 38172);
  const double h = 0.1 / 6;
  // The cells next to the box are near h and the last ones at most ~4 h: the cell counts come from
  // the arithmetic mean cell (1 + e) h / 2, larger than the progression's, so the first cell is
  // up to ~15 % above h (3.9x: (e - 1) / ln e = 2.13 against 2.45).
  bool top_seen = false, left_seen = false;
  for (const auto& b : d.blocks) {
    if (b.grading[1] > 1.0 && b.cells[0] == 12) {  // above the box: from y = 4.1 m to the side at 8 m
      const auto [first, last] = endCells(3.9, b.cells[1], b.grading[1]);
      EXPECT_NEAR(first / h, 1.0, 0.2);
      EXPECT_NEAR(last / h, 3.9, 0.6);
      top_seen = true;
    }
    if (b.grading[0] < 1.0 && b.cells[1] == 12) {  // upstream of the box: from the inlet at x = 0 to 1.9 m
      const auto [first, last] = endCells(1.9, b.cells[0], b.grading[0]);
      EXPECT_NEAR(first / h, 1.9, 0.3);  // at the inlet
      EXPECT_NEAR(last / h, 1.0, 0.2);   // at the box
      left_seen = true;
    }
  }
  EXPECT_TRUE(top_seen);
  EXPECT_TRUE(left_seen);
}

TEST(CaseWriter, UnsteadyCylinderStartsFromMmvalsVortex) {
  // mmval's numerics.initial_perturbation 0.3 (KindsCylinderUnsteady.cpp): u = A (-Y, X)
  // exp(-(X^2 + Y^2)), X, Y in diameters from (cx + 1.5 D, cy), A = 0.3 U sqrt(e / 2) = 0.349747 m/s.
  Scene s;
  s.unsteady = true;
  s.end_time = 1.0;
  s.dt = 1e-3;
  s.cx = 0.2;
  s.cy = 0.2;
  s.diameter = 0.1;
  s.u_ref = 1.0;
  s.initial_perturbation = 0.3;
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / "foam-writer-vortex";
  std::filesystem::remove_all(dir);
  writeCase(s, dir);
  const std::string dict = slurp(dir / "system/setExprFieldsDict");
  EXPECT_THAT(dict, HasSubstr("\"X = (pos().x() - 0.35) / 0.1\""));
  EXPECT_THAT(dict, HasSubstr("\"Y = (pos().y() - 0.2) / 0.1\""));
  EXPECT_THAT(dict, HasSubstr("\"g = 0.3497465972"));
  EXPECT_THAT(dict, HasSubstr("vector(-Y * g, X * g, 0)"));
  EXPECT_THAT(slurp(dir / "Allrun"), HasSubstr("setExprFields > log.setExprFields"));
  // Without a perturbation the flow starts from rest and no field is set.
  s.initial_perturbation = 0;
  std::filesystem::remove_all(dir);
  writeCase(s, dir);
  EXPECT_FALSE(std::filesystem::exists(dir / "system/setExprFieldsDict"));
  EXPECT_THAT(slurp(dir / "Allrun"), ::testing::Not(HasSubstr("setExprFields")));
}

TEST(Results, SheddingStatisticsUseTheCasesWindowAndWholePeriods) {
  // A start-up (c_D 1.6, dense samples every 1 ms to 6 s) then periodic shedding sampled every 4 ms:
  // c_L = 0.33 sin(2 pi f t), c_D = 1.35 + 0.01 sin(4 pi f t), f = 1.65 Hz, so with D 0.1 m and
  // U 1 m/s St = 0.165; over whole c_L periods c_D's mean is 1.35 exactly. The last half of the
  // samples (the peer's statistics before) reaches back into the start-up.
  Scene s;
  s.unsteady = true;
  s.end_time = 12.0;
  s.statistics_from = 7.0;
  s.diameter = 0.1;
  s.u_ref = 1.0;
  const double f = 1.65;
  std::vector<Coefficients> h;
  for (double t = 1e-3; t <= 12.0 + 1e-9; t += t < 6.0 ? 1e-3 : 4e-3)
    h.push_back({t, t < 5.0 ? 1.6 : 1.35 + 0.01 * std::sin(4 * M_PI * f * t), 0.33 * std::sin(2 * M_PI * f * t)});
  Result r;
  addSheddingStatistics(s, h, r);
  EXPECT_EQ(r.shedding_periods, 4);
  ASSERT_TRUE(r.strouhal.has_value());
  EXPECT_NEAR(*r.strouhal, 0.165, 1e-5);  // crossings interpolated linearly on a sine: error O(dt^3)
  // The window's ends fall between samples (up to 4 ms of 2.4 s): c_D's mean is off by at most
  // 0.01 x 2 x 4 ms / 2.4 s ~ 3e-5.
  ASSERT_TRUE(r.c_d_mean.has_value());
  EXPECT_NEAR(*r.c_d_mean, 1.35, 1e-4);
  EXPECT_NEAR(*r.c_d_max, 1.36, 1e-4);
  EXPECT_NEAR(*r.c_l_max, 0.33, 1e-4);
  // No shedding (a steady lift): no St, no periods.
  for (auto& c : h) c.cl = 0.01;
  Result steady;
  addSheddingStatistics(s, h, steady);
  EXPECT_EQ(steady.shedding_periods, 0);
  EXPECT_FALSE(steady.strouhal.has_value());
}

TEST(Results, ExecutionTimeIsTheSolversLastOne) {
  // pimpleFoam prints its CPU seconds so far after every step; the last one is the solve's.
  const std::string log = "Time = 0.01\n\nsmoothSolver:  Solving for Ux\nExecutionTime = 0.05 s  ClockTime = 0 s\n\n"
                          "Time = 0.02\n\nExecutionTime = 93.51 s  ClockTime = 116 s\n\nEnd\n";
  ASSERT_TRUE(executionTime(log).has_value());
  EXPECT_DOUBLE_EQ(*executionTime(log), 93.51);
  EXPECT_FALSE(executionTime("Time = 0.01\nFOAM FATAL ERROR\n").has_value());
}

TEST(Results, FluxChangeIsTheGeometricTailOfTheLastChanges) {
  // Q_i = 1 + 2^-i converges geometrically (r = 1/2): at i = 29 the rest of the series is
  // 2^-29 = |d_29| r / (1 - r), relative to Q_29.
  std::vector<double> q;
  for (int i = 0; i < 30; ++i) q.push_back(1 + std::ldexp(1.0, -i));
  ASSERT_TRUE(fluxChange(q));
  EXPECT_NEAR(*fluxChange(q), std::ldexp(1.0, -29) / (1 + std::ldexp(1.0, -29)), 1e-12 * std::ldexp(1.0, -29));
  // Changes that do not shrink (here growing: 1, 2, 4, ..., 2^29): the change over the last 20
  // entries, (2^30 - 2^10) / 2^30; two entries: their change; one entry or a zero flux: nothing.
  std::vector<double> growing;
  for (int i = 0; i < 30; ++i) growing.push_back(std::ldexp(1.0, i + 1) - 1);  // sum of 1, 2, ..., 2^i
  EXPECT_NEAR(*fluxChange(growing), (std::ldexp(1.0, 30) - std::ldexp(1.0, 10)) / (std::ldexp(1.0, 30) - 1), 1e-15);
  EXPECT_NEAR(*fluxChange({2.0, 1.0}), 1.0, 1e-15);
  EXPECT_FALSE(fluxChange({1.0}));
  EXPECT_FALSE(fluxChange({1.0, 0.0}));
}

TEST(Results, FatalMessageIsExtracted) {
  const std::string log = "Create time\n\n--> FOAM FATAL ERROR:\ncannot find file \"0/U\"\n\n    From function x\n\n\nFOAM exiting\n";
  EXPECT_THAT(fatalMessage(log), HasSubstr("cannot find file \"0/U\""));
}


/// One SIMPLE iteration of a simpleFoam v1912 log (2D: Ux, Uy; two p solves with the non-orthogonal corrector).
std::string simpleIteration(int time, double ux, double uy, double p) {
  std::ostringstream o;
  o.precision(6);
  o << "Time = " << time << "\n\n"
    << "smoothSolver:  Solving for Ux, Initial residual = " << ux << ", Final residual = 1e-05, No Iterations 3\n"
    << "smoothSolver:  Solving for Uy, Initial residual = " << uy << ", Final residual = 2e-05, No Iterations 3\n"
    << "GAMG:  Solving for p, Initial residual = " << p << ", Final residual = 0.0001, No Iterations 7\n"
    << "GAMG:  Solving for p, Initial residual = 0.001, Final residual = 1e-05, No Iterations 4\n"
    << "time step continuity errors : sum local = 1e-09, global = 1e-20, cumulative = 1e-19\n"
    << "ExecutionTime = 1.5 s  ClockTime = 2 s\n\n";
  return o.str();
}

TEST(Results, SimpleSolveThatMetResidualControlIsConverged) {
  const std::string log = "Create time\n\nSIMPLE: convergence criteria\n    field p\t tolerance 1e-07\n\n" + simpleIteration(1, 1, 1, 1) +
                          simpleIteration(2, 1e-6, 2e-6, 5e-6) + simpleIteration(3, 5e-8, 6e-8, 9e-8) +
                          "\nSIMPLE solution converged in 3 iterations\n\nEnd\n\n";
  const SimpleConvergence c = simpleConvergence(log, 1e-7);
  EXPECT_TRUE(c.converged);
  EXPECT_EQ(c.iterations, 3);
  ASSERT_EQ(c.residuals.size(), 3u);
  EXPECT_NEAR(c.residuals.at("Ux"), 5e-8, 1e-12);  // the first p solve's residual is what residualControl reads, not the corrector's
  EXPECT_NEAR(c.residuals.at("p"), 9e-8, 1e-12);
}

TEST(Results, SimpleSolveStoppedAtItsIterationCapIsNotConverged) {
  // The square array at phi 0.6 / 0.7 on fine meshes can end at the cap with residuals near 0.9 and
  // F* = 1.45e5 / -6.5e5 in its last iterate: that must not be reported as a value.
  std::string log = "Create time\n\n";
  for (int k = 1; k <= 5; ++k) log += simpleIteration(k, 0.9, 0.88, 0.93 - 0.01 * k);
  log += "End\n\n";
  const SimpleConvergence c = simpleConvergence(log, 1e-7);
  EXPECT_FALSE(c.converged);
  EXPECT_EQ(c.iterations, 5);
  EXPECT_NEAR(c.residuals.at("Ux"), 0.9, 1e-9);
  EXPECT_NEAR(c.residuals.at("Uy"), 0.88, 1e-9);
  EXPECT_NEAR(c.residuals.at("p"), 0.88, 1e-9);  // the last iteration's first p solve
  EXPECT_EQ(residualText(c.residuals), "Ux 0.9, Uy 0.88, p 0.88");
}

TEST(Results, SimpleSolveMeetingItsTargetOnTheLastIterationIsConverged) {
  // At the cap simpleFoam stops without its "converged" line even when the last iteration met the target.
  const std::string log = simpleIteration(1, 1, 1, 1) + simpleIteration(2, 9e-8, 8e-8, 1e-7) + "End\n";
  EXPECT_TRUE(simpleConvergence(log, 1e-7).converged);
  EXPECT_FALSE(simpleConvergence(log, 5e-8).converged);
  // A diverged solve (nan residuals) is not converged, and an empty log has nothing to show.
  EXPECT_FALSE(simpleConvergence("Time = 1\n\nsmoothSolver:  Solving for Ux, Initial residual = nan, Final residual = nan, No Iterations 1000\n", 1e-7).converged);
  EXPECT_FALSE(simpleConvergence("", 1e-7).converged);
}

TEST(Installation, VersionIsReadFromTheInstallationNotAssumed) {
  // A stand-in installation folder whose etc/bashrc says v2312, as OpenFOAM's own files set it.
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("mmval-foam-version-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir / "etc");
  std::ofstream(dir / "etc" / "bashrc") << "# export WM_PROJECT_VERSION=commented\n"
                                           "export WM_PROJECT=OpenFOAM\n"
                                           "export WM_PROJECT_VERSION=v2312   # the release\n";
  const char* saved = std::getenv("WM_PROJECT_VERSION");
  const std::string kept = saved != nullptr ? saved : "";
  ::unsetenv("WM_PROJECT_VERSION");
  EXPECT_EQ(installedVersion(dir), "v2312");
  EXPECT_EQ(installedVersion(dir / "nowhere"), "unknown");
  ::setenv("WM_PROJECT_VERSION", "v2406", 1);  // a sourced environment wins
  EXPECT_EQ(installedVersion(dir), "v2406");
  if (saved != nullptr) ::setenv("WM_PROJECT_VERSION", kept.c_str(), 1); else ::unsetenv("WM_PROJECT_VERSION");
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace mmval::openfoam
