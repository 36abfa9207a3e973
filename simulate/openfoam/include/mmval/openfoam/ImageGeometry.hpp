// Image geometries for the OpenFOAM peer, the paper's route: a binary pore
// image -> grain outlines -> simplified polygons -> a closed, extruded,
// triangulated surface (ASCII STL) that snappyHexMesh cuts out of a
// Cartesian background mesh.
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

/// Closed ASCII STL of the grains, extruded from z0 to z1 (m), polygons
/// simplified to `tolerance_px`. Grains touching the image edge are extended
/// a few pixels beyond it so no surface lies on the domain boundary.
std::string grainStl(const MaskGeometry& g, double z0, double z1, double tolerance_px = 0.7);

/// Ear-clipping triangulation of a simple polygon (counter-clockwise or not);
/// returns index triples.
std::vector<std::array<int, 3>> triangulate(const std::vector<cv::Point2d>& polygon);

}  // namespace mmval::openfoam
