// The OpenFOAM peer's direct image mesher (directMesh2D, extrude, writePolyMesh): the pore area of
// a disc in a box against pi r^2 (second order in h), the cells' shapes, OpenFOAM's face order and
// patch counts, closed cells; the smooth boundary of a rendered disc packing against its pore
// fraction (midpoint rule); and checkMesh on a written mesh (skipped without OpenFOAM).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/openfoam/DirectMesh.hpp"
#include "mmval/openfoam/FoamFile.hpp"
#include "mmval/openfoam/ImageGeometry.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/openfoam/Peer.hpp"
#include "mmval/simulate/Kinds.hpp"

#include "../TestScratch.hpp"

namespace mmval::openfoam {
namespace {

namespace fs = std::filesystem;

constexpr double kWidth = 100e-6;  // m: a 100 um box
constexpr double kRadius = 31e-6;  // a disc off the grid's symmetry so no vertex sits on it by design
constexpr double kCx = 51.3e-6, kCy = 48.9e-6;

LevelFunction disc() {
  return [](double x, double y) { return kRadius - std::hypot(x - kCx, y - kCy); };
}

double exactPoreArea() { return kWidth * kWidth - M_PI * kRadius * kRadius; }

std::array<double, 3> sub(const std::array<double, 3>& a, const std::array<double, 3>& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
std::array<double, 3> crossp(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

/// Area vector of a planar-or-not quad face (half the cross product of its diagonals).
std::array<double, 3> areaVector(const PolyMesh& m, const std::array<int, 4>& f) {
  const auto c = crossp(sub(m.points[f[2]], m.points[f[0]]), sub(m.points[f[3]], m.points[f[1]]));
  return {0.5 * c[0], 0.5 * c[1], 0.5 * c[2]};
}

TEST(DirectMesh, DiscInABoxConvergesAtSecondOrder) {
  // Pore area against pi r^2 on 16, 32 and 64 cells across: the boundary is a polygon with its
  // vertices on the circle, so the area misses by O(h^2) (an inscribed polygon: r^2 (pi - n sin(pi/n) cos(pi/n)) ~ pi^3 r^2 / (3 n^2)).
  std::vector<double> err;
  for (int n : {16, 32, 64}) {
    const DirectMesh2D m = directMesh2D(disc(), kWidth, kWidth, n, n);
    const double e = (m.area() - exactPoreArea()) / (M_PI * kRadius * kRadius);
    std::printf("%d cells across: pore area error %+.3e of the disc's area; wall vertices %d, snapped %d, pulled back %d, pinned %d, max move %.2f cells, "
                "smallest cell %.3f dx dy\n",
                n, e, m.wall_vertices, m.snapped, m.pulled_back, m.pinned, m.max_move_cells, m.minCellAreaRatio());
    err.push_back(e);
    EXPECT_EQ(m.pinned, 0) << n;
    // Every cell keeps a positive area, at least the mesher's bound (0.1 dx dy).
    EXPECT_GT(m.minCellAreaRatio(), 0.1 - 1e-9) << n;
    // h^2 bound: the polygon's chords (spacing ~h, ~2 pi r / h of them) each cut a segment of
    // area <= h^3 / (12 r), so the missed area is under (pi / 6) h^2; relative to pi r^2 that is
    // h^2 / (6 r^2) (0.011 at 16 cells).
    const double h = kWidth / n;
    EXPECT_LE(std::abs(e), h * h / (6 * kRadius * kRadius)) << n;
  }
  // Observed order from the three levels: second order (the area is a sum of chord segments).
  const double order = std::log(std::abs(err[0] / err[1])) / std::log(2.0), order_fine = std::log(std::abs(err[1] / err[2])) / std::log(2.0);
  std::printf("observed order %.2f, %.2f\n", order, order_fine);
  EXPECT_GT(order_fine, 1.6);
}

TEST(DirectMesh, FacesFollowOpenFoamOrderAndCloseEveryCell) {
  const int n = 24;
  const DirectMesh2D m = directMesh2D(disc(), kWidth, kWidth, n, n);
  const double t = m.dx();
  const PolyMesh p = extrude(m, t);
  ASSERT_EQ(p.cells, static_cast<int>(m.cells.size()));
  ASSERT_EQ(p.owner.size(), p.faces.size());
  const std::size_t n_internal = p.neighbour.size();
  // Internal faces: owner < neighbour, sorted by owner then neighbour (upper-triangular order).
  for (std::size_t f = 0; f < n_internal; ++f) {
    ASSERT_LT(p.owner[f], p.neighbour[f]) << f;
    if (f > 0) {
      ASSERT_TRUE(p.owner[f - 1] < p.owner[f] || (p.owner[f - 1] == p.owner[f] && p.neighbour[f - 1] < p.neighbour[f])) << f;
    }
  }
  // Patches: contiguous after the internal faces, in order, their counts those of the box.
  int next = static_cast<int>(n_internal);
  std::map<std::string, int> size;
  for (const auto& patch : p.patches) {
    EXPECT_EQ(patch.start, next) << patch.name;
    next += patch.size;
    size[patch.name] = patch.size;
  }
  EXPECT_EQ(next, static_cast<int>(p.faces.size()));
  EXPECT_EQ(size["inlet"], n);   // the disc does not reach the box's edges
  EXPECT_EQ(size["outlet"], n);
  EXPECT_EQ(size["walls"], 2 * n);
  EXPECT_EQ(size["back"], p.cells);
  EXPECT_EQ(size["front"], p.cells);
  EXPECT_GT(size["grains"], 0);
  // Each cell has 6 faces (internal faces count for both cells): 6 cells = 2 internal + boundary.
  EXPECT_EQ(6 * p.cells, static_cast<int>(2 * n_internal + (p.faces.size() - n_internal)));
  // Closed cells with outward normals: the face area vectors of a cell (owner +, neighbour -)
  // sum to zero (round-off of the face areas), and its volume (1/3 sum x_f . S_f) is positive
  // and adds up to area x thickness.
  std::vector<std::array<double, 3>> sum(p.cells, {0, 0, 0});
  std::vector<double> vol(p.cells, 0.0);
  for (std::size_t f = 0; f < p.faces.size(); ++f) {
    const auto s = areaVector(p, p.faces[f]);
    std::array<double, 3> c{0, 0, 0};
    for (int v : p.faces[f])
      for (int k = 0; k < 3; ++k) c[k] += 0.25 * p.points[v][k];
    const double flux = (c[0] * s[0] + c[1] * s[1] + c[2] * s[2]) / 3;
    for (int k = 0; k < 3; ++k) sum[p.owner[f]][k] += s[k];
    vol[p.owner[f]] += flux;
    if (f < n_internal) {
      for (int k = 0; k < 3; ++k) sum[p.neighbour[f]][k] -= s[k];
      vol[p.neighbour[f]] -= flux;
    }
  }
  double total = 0;
  const double face = m.dx() * t;
  for (int c = 0; c < p.cells; ++c) {
    for (int k = 0; k < 3; ++k) ASSERT_NEAR(sum[c][k], 0.0, 1e-9 * face) << "cell " << c;
    ASSERT_GT(vol[c], 0.0) << "cell " << c;
    total += vol[c];
  }
  EXPECT_NEAR(total / (m.area() * t), 1.0, 1e-9);
}

TEST(DirectMesh, DropsFluidNotJoiningInletAndOutlet) {
  // A ring of grain around a fluid pocket: the pocket's cells are fluid but closed off.
  const LevelFunction ring = [](double x, double y) {
    const double r = std::hypot(x - 50e-6, y - 50e-6);
    return 6e-6 - std::abs(r - 25e-6);  // grain for 19 um < r < 31 um
  };
  const DirectMesh2D m = directMesh2D(ring, kWidth, kWidth, 40, 40);
  EXPECT_GT(m.dropped_disconnected, 0);
  for (const auto& ij : m.grid_cell) {
    const double x = (ij[0] + 0.5) * m.dx() - 50e-6, y = (ij[1] + 0.5) * m.dy() - 50e-6;
    EXPECT_GT(std::hypot(x, y), 19e-6) << "kept cell inside the ring";
  }
}

/// Nine discs on a jittered 20 px lattice in a 60 x 60 px mask (tests/openfoam/PeerSmoothTest.cpp's packing).
MaskGeometry discPacking(double pixel_m) {
  struct Disc {
    double x, y, r;
  };
  const std::vector<Disc> discs = {{10.2, 10.8, 7.6}, {30.9, 9.7, 6.9}, {50.1, 11.2, 7.2}, {9.6, 30.4, 7.0}, {29.8, 31.1, 8.2},
                                   {50.7, 29.6, 6.5}, {11.1, 50.3, 7.4}, {31.2, 49.4, 7.1}, {49.5, 50.6, 7.8}};
  MaskGeometry g;
  g.pixel = pixel_m;
  g.fluid = cv::Mat(60, 60, CV_8U, cv::Scalar(255));
  for (int r = 0; r < 60; ++r)
    for (int c = 0; c < 60; ++c)
      for (const Disc& d : discs)
        if (std::hypot(c + 0.5 - d.x, r + 0.5 - d.y) < d.r) g.fluid.at<unsigned char>(r, c) = 0;
  return g;
}

TEST(DirectMesh, ImageMeshHoldsTheSmoothBoundarysPoreFraction) {
  // Reference: the smooth boundary's pore fraction by the midpoint rule on 32 x 32 points per
  // pixel (its own error ~1e-4). The mesh converges on it at second order: within 0.3 % at 1 cell
  // per pixel and 0.1 % at 2 (the peer's warning bound is 0.5 %).
  const MaskGeometry g = discPacking(10e-6);
  const double boundary = smoothPoreFraction(g, 0.75, 32);
  for (double cpp : {1.0, 2.0}) {
    const DirectMesh2D m = directImageMesh(g, 0.75, cpp);
    const double phi = m.area() / (g.width() * g.height());
    std::printf("%.0f cells/px: pore fraction mesh %.5f, smooth boundary %.5f (%+.3f %%); pinned %d, pulled back %d of %d\n", cpp, phi, boundary,
                100 * (phi / boundary - 1), m.pinned, m.pulled_back, m.wall_vertices);
    EXPECT_NEAR(phi / boundary, 1.0, cpp < 1.5 ? 3e-3 : 1e-3) << cpp;
  }
}

TEST(DirectMesh, PixelMeshIsTheStaircaseExactly) {
  // geometry.boundary = "pixels": the mesh is the connected pore pixels, cell for cell. Reference:
  // a pixel count of the mask (every pore pixel of the disc packing is connected), plus a pocket
  // walled off on purpose, which the mesh drops.
  MaskGeometry g = discPacking(10e-6);
  const int pocket_r = 2, pocket_c = 57;  // a pore pixel boxed in by grain pixels near the top right
  for (int r = pocket_r - 1; r <= pocket_r + 1; ++r)
    for (int c = pocket_c - 1; c <= pocket_c + 1; ++c) g.fluid.at<unsigned char>(r, c) = (r == pocket_r && c == pocket_c) ? 255 : 0;
  const int pore = cv::countNonZero(g.fluid);
  for (int cpp : {1, 2, 3}) {
    const DirectMesh2D m = pixelImageMesh(g, cpp);
    EXPECT_EQ(m.nx, 60 * cpp);
    EXPECT_EQ(static_cast<int>(m.cells.size()), (pore - 1) * cpp * cpp) << cpp;
    EXPECT_NEAR(m.area(), (pore - 1) * g.pixel * g.pixel, 1e-9 * g.width() * g.height()) << cpp;
    EXPECT_EQ(m.dropped_disconnected, cpp * cpp) << "the walled-off pore pixel";
    EXPECT_EQ(m.snapped + m.pulled_back + m.pinned, 0);
    EXPECT_NEAR(m.minCellAreaRatio(), 1.0, 1e-9);
    // The pocket's cells are not in the mesh; a grain pixel's centre neither.
    EXPECT_LT(m.cell_of[static_cast<std::size_t>((59 - pocket_r) * cpp) * m.nx + pocket_c * cpp], 0);
  }
  EXPECT_THROW(pixelImageMesh(g, 0), std::invalid_argument);
}

TEST(DirectMesh, PeerMeshesPixelImagesDirectlyAtWholeCellsPerPixel) {
  // A canned runner records the scene each level gets: no OpenFOAM needed. Pixels at 1, 2 cells
  // per pixel: the direct mesher; a level at 1.5 cannot follow pixel edges: snappyHexMesh.
  const fs::path mask = mmval::test::scratch("pixel-route.png");
  cv::imwrite(mask.string(), discPacking(10e-6).fluid);
  CaseKindRegistry reg;
  simulate::registerFluidKinds(reg);
  for (const std::string levels : {"[1, 2]", "[1, 1.5]"}) {
    const Case c = Case::parse("[case]\nname = \"route\"\nkind = \"image-permeability\"\n[geometry]\nmask = \"" + mask.string() +
                                   "\"\npixel_size = \"10 um\"\nboundary = \"pixels\"\n[numerics]\ndepth_model = \"2d\"\ncells_per_pixel_levels = " + levels + "\n",
                               mmval::test::scratch("pixel-route.toml"), reg);
    std::vector<Scene> seen;
    PeerRunOptions o;
    o.runner = [&seen](const Scene& s, const fs::path&, int) {
      seen.push_back(s);
      Result r;
      r.ok = true;
      r.permeability = 1e-12 * (1 + 0.1 * static_cast<double>(seen.size()));
      return r;
    };
    const RunOutput out = runPeer(c, RunContext{mmval::test::scratch("pixel-route-out"), true, false, 0}, o);
    ASSERT_EQ(seen.size(), 2u);
    const bool whole = levels == "[1, 2]";
    for (const Scene& s : seen) EXPECT_EQ(s.direct_mesh, whole) << levels;
    EXPECT_EQ(out.details.at("ladder")[0].at("mesher").get<std::string>(), whole ? "direct" : "snappyHexMesh") << levels;
    EXPECT_EQ(out.details.at("boundary").get<std::string>().rfind("pixels (mmval's direct mesher", 0) == 0, whole) << levels;
  }
}

TEST(DirectMesh, CheckMeshAcceptsTheWrittenMesh) {
  if (!detect().available) GTEST_SKIP() << detect().reason;
  const fs::path dir = mmval::test::scratch("direct-mesh-case");
  fs::remove_all(dir);
  const DirectMesh2D m = directMesh2D(disc(), kWidth, kWidth, 24, 24);
  writePolyMesh(extrude(m, m.dx()), dir);
  // checkMesh needs a controlDict; the peer's case writer would add the rest.
  fs::create_directories(dir / "system");
  std::ofstream(dir / "system" / "controlDict") << foamHeader("dictionary", "controlDict", "system")
                                                << "application simpleFoam;\nstartTime 0;\nendTime 1;\ndeltaT 1;\nwriteInterval 1;\n";
  std::ofstream(dir / "system" / "fvSchemes") << foamHeader("dictionary", "fvSchemes", "system")
                                              << "ddtSchemes { default steadyState; }\ngradSchemes { default Gauss linear; }\ndivSchemes { default none; }\n"
                                                 "laplacianSchemes { default Gauss linear corrected; }\ninterpolationSchemes { default linear; }\n"
                                                 "snGradSchemes { default corrected; }\n";
  std::ofstream(dir / "system" / "fvSolution") << foamHeader("dictionary", "fvSolution", "system");
  const std::string cmd = "cd '" + dir.string() + "' && WM_PROJECT_DIR=" + detect().project_dir.string() + " checkMesh > log.checkMesh 2>&1";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream in(dir / "log.checkMesh");
  std::stringstream log;
  log << in.rdbuf();
  EXPECT_NE(log.str().find("Mesh OK."), std::string::npos) << log.str();
  EXPECT_NE(log.str().find("cells:            " + std::to_string(m.cells.size())), std::string::npos) << log.str();
}

TEST(DirectMesh, PeerUsesItForSmoothImagesUnlessSnappyIsAsked) {
  // A canned runner records the scene each level gets: no OpenFOAM needed.
  const fs::path mask = mmval::test::scratch("direct-route.png");
  cv::imwrite(mask.string(), discPacking(10e-6).fluid);
  CaseKindRegistry reg;
  simulate::registerFluidKinds(reg);
  const Case c = Case::parse("[case]\nname = \"route\"\nkind = \"image-permeability\"\n[geometry]\nmask = \"" + mask.string() +
                                 "\"\npixel_size = \"10 um\"\nboundary = \"smooth\"\n[numerics]\ndepth_model = \"2d\"\n",
                             mmval::test::scratch("route.toml"), reg);
  for (const bool snappy : {false, true}) {
    std::vector<Scene> seen;
    PeerRunOptions o;
    o.snappy_image_mesh = snappy;
    o.runner = [&seen](const Scene& s, const fs::path&, int) {
      seen.push_back(s);
      Result r;
      r.ok = true;
      r.permeability = 1e-12;
      return r;
    };
    const RunOutput out = runPeer(c, RunContext{mmval::test::scratch("route-out"), true, false, 0}, o);
    ASSERT_EQ(seen.size(), 1u);
    EXPECT_EQ(seen[0].direct_mesh, !snappy);
    EXPECT_EQ(out.details.at("ladder")[0].at("mesher").get<std::string>(), snappy ? "snappyHexMesh" : "direct");
  }
}

}  // namespace
}  // namespace mmval::openfoam
