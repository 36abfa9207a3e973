// Image geometries for the OpenFOAM peer: a binary pore image -> grain
// outlines -> a closed, extruded, triangulated surface (ASCII STL) that
// snappyHexMesh cuts out of a Cartesian background mesh. The outlines are the
// mask's pixel outlines (the paper's route) or, for geometry.boundary =
// "smooth", the sub-pixel boundary mmval's own solver cuts its cells against.
#pragma once
#include <array>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

namespace mmval::openfoam {

struct MaskGeometry {
  cv::Mat fluid;                  ///< CV_8U, 255 = pore, 0 = grain; row 0 is the top of the image
  double pixel = 1e-6;            ///< m
  double porosity_total = 0;      ///< pore pixels / all pixels
  double porosity_connected = 0;  ///< pore pixels connected to both inlet (left) and outlet (right)
  cv::Point2d inside;             ///< a point (m, y up) well inside the connected pore space
  double width() const { return fluid.cols * pixel; }
  double height() const { return fluid.rows * pixel; }
};

/// Reads a mask; `grain_dark` says grains are the dark pixels. Throws
/// InputError naming the file when it cannot be read or has no pore path
/// from the left (inlet) to the right (outlet) edge.
MaskGeometry loadMask(const std::filesystem::path& file, double pixel, bool grain_dark = true);

/// A closed grain outline: vertices in metres (y up, origin at the image's bottom-left corner),
/// counter-clockwise (the grain on the left), the last vertex joined to the first.
using Polygon = std::vector<cv::Point2d>;

/// The staircase route: outlines of the connected-pore mask's grain pixels, simplified to
/// `tolerance_px` (Douglas-Peucker). Grains touching the image edge are extended a few pixels
/// beyond it so no surface lies on the domain boundary.
std::vector<Polygon> pixelGrainPolygons(const MaskGeometry& g, double tolerance_px = 0.7);

/// The smooth route, the boundary mmval's fluid solver cuts its cells against with
/// geometry.boundary = "smooth" (simulate::SmoothMaskShape: the connected-pore mask smoothed by a
/// Gaussian of `sigma_px` pixels, cubic interpolation, its 1/2 level): that level's outlines by
/// marching squares on a lattice of `samples_per_pixel` nodes per pixel, every vertex moved onto
/// the level by bisection along its lattice edge (to ~1e-9 px), then simplified by Douglas-Peucker
/// to 0.002 px (the area it removes is ~1e-4 of a 3 px grain's). Beyond the image the field
/// continues as at the edge (an edge grain runs on straight out) for 2 pixels, where the outlines
/// close. Saddle cells are resolved by the field at the cell centre. Fluid holes inside a grain
/// (disconnected pore: no flow reaches it) are dropped.
std::vector<Polygon> smoothGrainPolygons(const MaskGeometry& g, double sigma_px, int samples_per_pixel = 8);

/// Pore fraction of the image rectangle on the fluid side of that smooth boundary (field <= 1/2),
/// by the midpoint rule on `samples_per_pixel`^2 points per pixel.
double smoothPoreFraction(const MaskGeometry& g, double sigma_px, int samples_per_pixel = 16);

/// Enclosed area of a polygon (m^2, positive when counter-clockwise), the shoelace formula.
double polygonArea(const Polygon& p);

/// Closed ASCII STL of the polygons extruded from z0 to z1 (m): side walls with outward normals,
/// caps by ear clipping.
std::string extrudedStl(const std::vector<Polygon>& polygons, double z0, double z1);

/// extrudedStl of pixelGrainPolygons: the staircase route.
std::string grainStl(const MaskGeometry& g, double z0, double z1, double tolerance_px = 0.7);

/// Ear-clipping triangulation of a simple polygon (counter-clockwise or not);
/// returns index triples.
std::vector<std::array<int, 3>> triangulate(const std::vector<cv::Point2d>& polygon);

}  // namespace mmval::openfoam
