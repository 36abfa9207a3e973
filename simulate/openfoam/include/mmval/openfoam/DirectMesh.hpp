// The OpenFOAM peer's own mesher for image geometries, on the smooth grain boundary or on the
// pixel staircase itself (pixelImageMesh): a uniform
// Cartesian grid over the image, one cell deep, whose cells on the fluid side of a level function
// are kept and whose wall vertices are moved onto the level (the boundary mmval's solver cuts its
// cells against). It writes constant/polyMesh directly, so no blockMesh or snappyHexMesh runs, and
// meshes a 500 x 500 px chip in seconds where snapping takes hours (docs/validation/peer-smooth.md).
#pragma once
#include <array>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace mmval::openfoam {

struct MaskGeometry;

/// The geometry's level function at (x, y) in metres (origin at the image's bottom-left corner,
/// y up): > 0 in grain, <= 0 in fluid; the 0 level is the grain boundary. Continuous (the smooth
/// mask field is C1), so a sign change along a segment brackets a boundary point.
using LevelFunction = std::function<double(double, double)>;

struct Vertex2 {
  double x = 0, y = 0;  ///< m
};

/// A planar quad mesh: cells are counter-clockwise vertex quadruples (seen from +z), faces of
/// neighbouring cells share vertices. Grid cell (i, j) (i along x from the inlet, j along y from the
/// bottom) is kept cell `cell_of[j * nx + i]` or -1.
struct DirectMesh2D {
  int nx = 0, ny = 0;
  double width = 0, height = 0;       ///< m
  std::vector<Vertex2> vertices;      ///< (nx + 1) (ny + 1) grid vertices, index j (nx + 1) + i; unused ones unmoved
  std::vector<std::array<int, 4>> cells;
  std::vector<int> cell_of;           ///< grid cell -> kept cell index, -1 if dropped
  std::vector<std::array<int, 2>> grid_cell;  ///< kept cell -> (i, j)
  // What the snapping did (counts of wall vertices)
  int wall_vertices = 0;              ///< vertices on a face between a kept and a dropped cell
  int snapped = 0;                    ///< moved onto the level (|level| ~ 1e-10 of its range)
  int pulled_back = 0;                ///< moved only part of the way: a full move would have spoilt a cell's shape
  int pinned = 0;                     ///< left where they were: image corners, diagonal contacts, no crossing in reach
  int dropped_disconnected = 0;       ///< fluid cells not connected to both the inlet and the outlet
  double max_move_cells = 0;          ///< largest vertex move, in cell sizes
  double dx() const { return width / nx; }
  double dy() const { return height / ny; }
  /// Total area of the kept cells (shoelace), m^2.
  double area() const;
  /// Smallest cell area over dx dy.
  double minCellAreaRatio() const;
};

/// Meshes the fluid side of `level` on [0, width] x [0, height] with nx x ny cells:
/// 1. A grid cell is fluid when the level at its centre is <= 0; fluid cells not joined through
///    faces to both the inlet (x = 0) and the outlet (x = width) columns are dropped.
/// 2. Every vertex on a face between a kept and a dropped cell moves onto the 0 level: along the
///    level's gradient (the nearest crossing within 0.75 cell), else towards an adjacent cell centre
///    on the other side; on the image's left, right, top or bottom edge it slides along that edge.
///    Image corners and vertices where two kept cells touch only diagonally stay.
/// 3. The wall vertices' spacing along the level is evened out (short grain faces are skewed).
/// 4. Moves that would leave a cell under a tenth of dx dy in area, or its centre (vertex mean)
///    closer than a tenth of a cell to a side's line, are halved, cell by cell, until every cell
///    passes. Corners of 180 degrees and slightly more are allowed: an oblique crossing turns
///    staircase cells into triangles.
/// The boundary is then a polyline through points on the level spaced ~h, so the meshed area
/// converges at second order in h. Throws std::invalid_argument for a non-positive size or fewer
/// than 2 cells along an axis, std::runtime_error when no cell connects inlet and outlet.
DirectMesh2D directMesh2D(const LevelFunction& level, double width, double height, int nx, int ny);

/// directMesh2D of mmval's smooth boundary of an image (simulate::SmoothMaskShape of the connected
/// pores, Gaussian of sigma_px pixels) at `cells_per_pixel`: nx = round(cols cpp), ny = round(rows cpp),
/// at least 4, as mmval's own image grid.
DirectMesh2D directImageMesh(const MaskGeometry& g, double sigma_px, double cells_per_pixel);

/// The pixel staircase of an image (geometry.boundary = "pixels"), meshed exactly: a Cartesian grid
/// of `cells_per_pixel` (a whole number >= 1) cells per pixel edge, a cell kept when its pixel is
/// pore and joined through faces to both inlet and outlet; no vertex moves (snapped, pulled_back,
/// pinned stay 0; wall_vertices counts the staircase's vertices). The mesh's area is the connected
/// pore pixels' area, the geometry mmval's sharp solver cuts against at these resolutions.
DirectMesh2D pixelImageMesh(const MaskGeometry& g, int cells_per_pixel);

/// mmval's smooth boundary of an image as a level function (simulate::SmoothMaskShape::level of
/// the connected pores, Gaussian of sigma_px pixels); the same field smoothGrainPolygons traces.
LevelFunction smoothLevel(const MaskGeometry& g, double sigma_px);

struct PolyPatch {
  std::string name, type;  ///< type: patch, wall, symmetry, empty
  int start = 0, size = 0;
};

/// An OpenFOAM polyMesh: points, faces (point ids, right-hand normal out of the owner), owner and
/// neighbour (internal faces first, in upper-triangular order: by owner, then by neighbour), then
/// the boundary faces patch by patch.
struct PolyMesh {
  std::vector<std::array<double, 3>> points;
  std::vector<std::array<int, 4>> faces;
  std::vector<int> owner, neighbour;
  std::vector<PolyPatch> patches;
  int cells = 0;
};

/// The 2D mesh extruded by `thickness` along z (one cell deep) with patches inlet (x = 0), outlet
/// (x = width), walls (y = 0 and y = height, type `side_type`), grains (wall), back (z = 0) and
/// front (z = thickness), both empty.
PolyMesh extrude(const DirectMesh2D& m, double thickness, const std::string& side_type = "symmetry");

/// Writes dir/constant/polyMesh/{points, faces, owner, neighbour, boundary} (ASCII).
void writePolyMesh(const PolyMesh& mesh, const std::filesystem::path& case_dir);

}  // namespace mmval::openfoam
