// The LIGGGHTS input is generated from validated numbers only (no LIGGGHTS run here).
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <sstream>

#include <Eigen/Geometry>
#include <fmt/format.h>

#include "GridField.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/particles/LiggghtsInput.hpp"

#include "../TestScratch.hpp"

namespace mmval::particles {
namespace {

bool has(const std::vector<std::string>& c, const std::string& s) {
  return std::any_of(c.begin(), c.end(), [&](const std::string& x) { return x.find(s) != std::string::npos; });
}

SceneConfig scene() {
  SceneConfig c;
  c.work_dir = mmval::test::scratch("mmval-liggghts-input-test");
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

/// A field of nx x ny nodes 10 um apart, at rest, 20 um deep, solid at the listed nodes.
GriddedFlow gridWith(int nx, int ny, const std::vector<std::pair<int, int>>& solid_nodes) {
  return *test_support::gridField(nx, ny, 0.0, 20e-6, [&](int i, int j) { return std::find(solid_nodes.begin(), solid_nodes.end(), std::pair{i, j}) != solid_nodes.end(); });
}

/// Total area of the triangles of an ASCII STL and the largest edge ratio of one triangle.
double stlArea(const std::string& stl, double& worst_aspect) {
  std::istringstream in(stl);
  std::string word;
  std::vector<Eigen::Vector3d> v;
  double area = 0;
  worst_aspect = 0;
  while (in >> word)
    if (word == "vertex") {
      Eigen::Vector3d p;
      in >> p.x() >> p.y() >> p.z();
      v.push_back(p);
      if (v.size() == 3) {
        area += 0.5 * (v[1] - v[0]).cross(v[2] - v[0]).norm();
        const double e[3] = {(v[1] - v[0]).norm(), (v[2] - v[1]).norm(), (v[0] - v[2]).norm()};
        worst_aspect = std::max(worst_aspect, *std::max_element(e, e + 3) / *std::min_element(e, e + 3));
        v.clear();
      }
    }
  return area;
}

// Grains of a gridded field are the squares of one node spacing around solid nodes
// (GriddedFlow::isSolid takes the nearest node); LIGGGHTS gets exactly their side
// faces, extruded through the depth. Checked on hand-counted shapes: a 2 x 2 block
// has a perimeter of 8 spacings in 4 runs (8 triangles); a 6 x 1 bar with runs of at
// most 4 spacings has sides of 4 + 2 and two ends: 6 runs, 12 triangles, 14 spacings.
TEST(LiggghtsInput, GriddedGrainsBecomeAnStlMeshWall) {
  const double dx = 10e-6, z0 = -1e-6, z1 = 21e-6;
  {
    const GriddedFlow g = gridWith(20, 16, {{8, 6}, {9, 6}, {8, 7}, {9, 7}});
    long tris = 0;
    const std::string stl = grainWallStl(g, z0, z1, 4, tris);
    EXPECT_EQ(tris, 8);
    double aspect = 0;
    EXPECT_NEAR(stlArea(stl, aspect), 8 * dx * (z1 - z0), 1e-18);
    // The block's faces: x = 7.5 dx and 9.5 dx, y = 5.5 dx and 7.5 dx.
    EXPECT_NE(stl.find(fmt::format("vertex {:.12g} {:.12g}", 7.5 * dx, 5.5 * dx)), std::string::npos) << stl.substr(0, 400);
    EXPECT_NE(stl.find(fmt::format("vertex {:.12g} {:.12g}", 9.5 * dx, 7.5 * dx)), std::string::npos);
  }
  {
    std::vector<std::pair<int, int>> bar;
    for (int i = 5; i < 11; ++i) bar.emplace_back(i, 8);
    const GriddedFlow g = gridWith(20, 16, bar);
    long tris = 0;
    const std::string stl = grainWallStl(g, z0, z1, 4, tris);
    EXPECT_EQ(tris, 12);
    double aspect = 0;
    EXPECT_NEAR(stlArea(stl, aspect), 14 * dx * (z1 - z0), 1e-18);
    EXPECT_LT(aspect, 4.5);  // runs of <= 4 spacings against a 22 um height: no slivers
  }
  {
    // The setup writes the mesh into the work folder and adds the mesh wall fixes.
    const GriddedFlow g = gridWith(20, 16, {{8, 6}, {9, 6}, {8, 7}, {9, 7}});
    const LiggghtsSetup s = liggghtsSetupFor(g, scene(), 190e-6);
    EXPECT_EQ(s.grain_triangles, 8);
    ASSERT_TRUE(std::filesystem::exists(s.grain_stl));
    const auto c = liggghtsSetupCommands(s);
    EXPECT_TRUE(has(c, "mesh/surface file " + s.grain_stl.string()));
    EXPECT_TRUE(has(c, "mesh n_meshes 1 meshes grains"));
    EXPECT_LE(s.x0, -dx);  // the outermost node squares stay inside the box
  }
  {
    // No solid node: plates only, no mesh.
    const GriddedFlow g = gridWith(20, 16, {});
    const LiggghtsSetup s = liggghtsSetupFor(g, scene(), 190e-6);
    EXPECT_TRUE(s.grain_stl.empty());
    EXPECT_FALSE(has(liggghtsSetupCommands(s), "mesh/surface"));
  }
}

// The first line of a real LIGGGHTS 3.8.0 log (Debian libliggghts3 3.8.0+repack1-9+b2),
// and the text between its parentheses, which the library holds as its version.
TEST(LiggghtsInput, VersionComesFromTheLogHeader) {
  const std::string header = "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown)";
  const std::string version = "LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown";
  EXPECT_EQ(liggghtsVersionFromHeader(header), version);
  EXPECT_EQ(liggghtsVersionFromHeader(header + "\nCreated orthogonal box = (0 0 0) to (1 1 1)\n"), version);
  EXPECT_EQ(liggghtsVersionFromHeader(header + "\r\n"), version);
  EXPECT_EQ(liggghtsVersionFromHeader("Version " + version), version);
  EXPECT_EQ(liggghtsVersionFromHeader(version), version);
  // Not a header: another program's banner, a LIGGGHTS line without a version number, nothing.
  EXPECT_FALSE(liggghtsVersionFromHeader("LAMMPS (29 Oct 2020)").has_value());
  EXPECT_FALSE(liggghtsVersionFromHeader("LIGGGHTS (Version LIGGGHTS-PUBLIC)").has_value());
  EXPECT_FALSE(liggghtsVersionFromHeader("Created 1 atoms\n" + header).has_value());
  EXPECT_FALSE(liggghtsVersionFromHeader("").has_value());
}

}  // namespace
}  // namespace mmval::particles
