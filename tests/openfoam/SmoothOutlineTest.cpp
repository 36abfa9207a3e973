// The OpenFOAM peer's smooth grain outline (smoothGrainPolygons) against the boundary mmval's
// solver cuts its cells against (simulate::SmoothMaskShape's 1/2 level), and against the discs a
// mask was rendered from; and the case the peer writes for it. Masks are drawn here; no OpenFOAM
// needed.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/openfoam/ImageGeometry.hpp"
#include "mmval/openfoam/Peer.hpp"
#include "mmval/simulate/Geometry.hpp"

#include "../TestScratch.hpp"

namespace mmval::openfoam {
namespace {

struct Disc {
  double x_px, y_px, r_px;  ///< centre in pixel coordinates (column, row; pixel edges at integers), radius
};

/// A cols x rows mask: a pixel is grain when its centre lies inside a disc.
MaskGeometry discMask(int cols, int rows, const std::vector<Disc>& discs, double pixel_m) {
  MaskGeometry g;
  g.pixel = pixel_m;
  g.fluid = cv::Mat(rows, cols, CV_8U, cv::Scalar(255));
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      for (const Disc& d : discs)
        if (std::hypot(c + 0.5 - d.x_px, r + 0.5 - d.y_px) < d.r_px) g.fluid.at<unsigned char>(r, c) = 0;
  return g;
}

/// Five discs of radius 5-9 px, none touching the edges or each other.
const std::vector<Disc> kPacking = {{14.2, 13.7, 8.3}, {40.6, 15.1, 6.9}, {16.4, 42.8, 7.4}, {43.3, 44.2, 9.1}, {29.5, 29.1, 4.6}};

TEST(SmoothOutline, EnclosesTheSmoothFieldsGrainArea) {
  const double sigma = 0.75;  // the geometry.smoothing default
  const MaskGeometry g = discMask(60, 60, kPacking, 10e-6);
  const auto polys = smoothGrainPolygons(g, sigma);
  ASSERT_EQ(polys.size(), kPacking.size());  // one outline per grain, no fluid holes
  double area = 0;
  for (const auto& p : polys) {
    EXPECT_GT(polygonArea(p), 0) << "outlines are counter-clockwise";
    area += polygonArea(p);
  }
  // Reference: the grain area of the same field by the midpoint rule on 32 x 32 points per pixel
  // (its own error, ~(perimeter x h^2) random-signed over ~10^4 boundary samples, is ~1e-5 of the area).
  const double image = g.width() * g.height();
  const double field = (1 - smoothPoreFraction(g, sigma, 32)) * image;
  // 0.1 %: the outline's error is the chords between vertices (<= 0.002 px from the level after
  // Douglas-Peucker, on a ~250 px perimeter: 0.5 px^2 of ~800 px^2 at most, 0.06 %) plus the
  // field integration's; it is the brief's bound on the peer meeting the solver's geometry.
  std::printf("outline area / field grain area = %.6f\n", area / field);
  EXPECT_NEAR(area / field, 1.0, 1e-3) << "outline " << area << " m2, field " << field << " m2";
}

TEST(SmoothOutline, VerticesLieOnTheSolversLevel) {
  const double sigma = 0.75;
  const MaskGeometry g = discMask(60, 60, kPacking, 10e-6);
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> solid(60, 60);
  for (int r = 0; r < 60; ++r)
    for (int c = 0; c < 60; ++c) solid(r, c) = g.fluid.at<unsigned char>(r, c) == 0;
  const simulate::SmoothMaskShape field(solid, g.pixel, sigma);
  double worst = 0;
  for (const auto& p : smoothGrainPolygons(g, sigma))
    for (const auto& v : p) worst = std::max(worst, std::abs(field.level(v.x, v.y)));
  // Bisection to 2^-32 of a 1/8 px lattice edge, then float storage of the pixel coordinates
  // (~4e-6 px at 60 px) times the field's slope (<~0.5 per px): the level is zero to ~1e-5.
  EXPECT_LT(worst, 1e-4);
}

TEST(SmoothOutline, MatchesAnAnalyticDiscToAFractionOfAPixel) {
  const Disc d{31.3, 30.7, 12.0};
  const double px = 5e-6;
  const MaskGeometry g = discMask(64, 64, {d}, px);
  const auto polys = smoothGrainPolygons(g, 0.75);
  ASSERT_EQ(polys.size(), 1u);
  const double cx = d.x_px * px, cy = (64 - d.y_px) * px;
  double lo = 1e9, hi = -1e9;
  for (const auto& v : polys[0]) {
    const double r = std::hypot(v.x - cx, v.y - cy) / px;
    lo = std::min(lo, r);
    hi = std::max(hi, r);
  }
  // The mask is the disc sampled at pixel centres: its staircase strays up to ~0.7 px from the
  // circle; the smoothing (which keeps every pixel centre on its side) leaves ripples of about a
  // third of a pixel (0.35 px measured) and pulls a convex boundary in by ~sigma^2 / (2 R) =
  // 0.02 px. 0.4 px bounds the local deviation; the area, which averages the ripples, gives the
  // equivalent radius to 0.05 px.
  EXPECT_GT(lo, d.r_px - 0.4);
  EXPECT_LT(hi, d.r_px + 0.4);
  const double r_eq = std::sqrt(polygonArea(polys[0]) / M_PI) / px;
  std::printf("disc R %.3f px: outline radius %.4f .. %.4f px, equivalent radius %.4f px\n", d.r_px, lo, hi, r_eq);
  EXPECT_NEAR(r_eq, d.r_px, 0.05) << "equivalent radius " << r_eq << " px, disc " << d.r_px << " px; min " << lo << ", max " << hi;
}

TEST(SmoothOutline, EdgeGrainsRunOnBeyondTheImageAndClose) {
  // A wall along the top edge and a disc cut by the left edge: outlines close outside the image.
  MaskGeometry g = discMask(40, 30, {{1.0, 18.0, 6.0}}, 1e-5);
  g.fluid.rowRange(0, 4).setTo(0);
  const auto polys = smoothGrainPolygons(g, 0.75);
  ASSERT_EQ(polys.size(), 2u);
  for (const auto& p : polys) {
    double xmin = 1e9, ymax = -1e9;
    for (const auto& v : p) {
      xmin = std::min(xmin, v.x);
      ymax = std::max(ymax, v.y);
    }
    EXPECT_TRUE(xmin < -1e-5 || ymax > 30e-6 + 1e-5) << "each outline leaves the image by more than a pixel";
  }
}

}  // namespace
}  // namespace mmval::openfoam

namespace mmval::openfoam {
namespace {

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p);
  std::stringstream b;
  b << in.rdbuf();
  return b.str();
}

TEST(SmoothOutline, SmoothImageCaseRefinesAtTheGrainsAndExtrudesBackToOneCell) {
  // A scene on the smooth boundary: its STL is the smooth outline, snappyHexMesh refines once at
  // the grains, extrudeMesh restores one cell of depth from the back patch.
  const MaskGeometry g = discMask(60, 60, kPacking, 10e-6);
  const std::filesystem::path dir = mmval::test::scratch("smooth-case");
  cv::imwrite((dir.parent_path() / "smooth-mask.png").string(), g.fluid);
  Scene s;
  s.kind = Scene::Kind::image;
  s.mask = dir.parent_path() / "smooth-mask.png";
  s.pixel = 10e-6;
  s.cells_per_pixel = 2;
  s.smooth_boundary = true;
  s.surface_level = 1;
  writeCase(s, dir);
  const std::string snappy = slurp(dir / "system" / "snappyHexMeshDict");
  EXPECT_NE(snappy.find("level (1 1)"), std::string::npos);
  EXPECT_NE(snappy.find("nCellsBetweenLevels 3"), std::string::npos);
  EXPECT_NE(slurp(dir / "system" / "extrudeMeshDict").find("sourcePatches (back)"), std::string::npos);
  const std::string block = slurp(dir / "system" / "blockMeshDict");
  EXPECT_NE(block.find("(60 60 1)"), std::string::npos) << "background at half the grains' 2 cells per pixel";
  EXPECT_NE(slurp(dir / "Allrun").find("extrudeMesh"), std::string::npos);
  // The STL's side walls are the smooth outlines: facet count 2 per outline edge plus the caps.
  std::size_t edges = 0;
  for (const auto& p : smoothGrainPolygons(g, s.smoothing_px)) edges += p.size();
  const std::string stl = slurp(dir / "constant" / "triSurface" / "grains.stl");
  std::size_t facets = 0;
  for (std::size_t at = stl.find("facet normal"); at != std::string::npos; at = stl.find("facet normal", at + 1)) ++facets;
  EXPECT_GE(facets, 2 * edges);
  EXPECT_LE(facets, 4 * edges);  // caps: n - 2 triangles per outline, twice
}

}  // namespace
}  // namespace mmval::openfoam
