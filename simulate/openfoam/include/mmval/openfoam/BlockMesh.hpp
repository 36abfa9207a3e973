// blockMesh dictionaries for the geometries the OpenFOAM peer runs: a plain
// channel, a cylinder in a channel (a multi-block O-grid, so the peer runs at
// its best), and a periodic unit cell of a square cylinder array (O-grid with
// cyclic patch pairs). 2D cases are one cell thick with empty front and back.
#pragma once
#include <array>
#include <string>
#include <vector>

namespace mmval::openfoam {

struct Point {
  double x = 0, y = 0, z = 0;
};

struct Block {
  std::array<int, 8> v{};     ///< vertex ids: bottom face CCW seen from +z, then top face
  std::array<int, 3> cells{}; ///< along local x1, x2, x3
  std::array<double, 3> grading{1, 1, 1};  ///< simpleGrading: last/first cell size ratio
};

struct ArcEdge {
  int from = 0, to = 0;
  Point through;
};

struct Patch {
  std::string name, type;                  ///< patch, wall, empty, cyclic, symmetryPlane
  std::vector<std::array<int, 4>> faces;
  std::string neighbour;                   ///< cyclic partner
};

struct BlockMeshDict {
  std::vector<Point> vertices;
  std::vector<Block> blocks;
  std::vector<ArcEdge> arcs;
  std::vector<Patch> patches;
  long long cellCount() const;
  /// The dictionary text (system/blockMeshDict).
  std::string text() const;
};

/// Channel [0, length] x [0, height], one cell deep; patches inlet, outlet,
/// walls (top and bottom, of `side_type`: wall or symmetryPlane), frontAndBack.
BlockMeshDict channelMesh(double length, double height, double depth, int nx, int ny, const std::string& side_type = "wall");

struct CylinderChannel {
  double length = 2.2, height = 0.41;     ///< channel
  double cx = 0.2, cy = 0.2, diameter = 0.1;
  double depth = 0.1;                     ///< extrusion thickness (2D: any)
};

/// O-grid around the cylinder inside a square box of side 4r (clipped to the
/// channel), Cartesian blocks elsewhere, cells stretched downstream and, on a
/// far-field side more than 16 D from the box (unconfined flow), towards that side.
/// `cells_around` (multiple of 4) cells lie on the circumference, each pi D /
/// cells_around long (the surface spacing numerics.cells_around sets in mmval's
/// own grid too; simulate::surfaceSpacing); the box edge has cells_around / 4
/// cells per side. `radial_grading` is the ratio of the outer to the inner
/// radial cell size.
BlockMeshDict cylinderChannelMesh(const CylinderChannel& g, int cells_around, double radial_grading = 4.0);

/// Unit cell [0, L]^2 with a cylinder of radius a at its centre: four O-grid
/// blocks from the circle to the cell edges; cyclic pairs left/right and
/// bottom/top; patch "cylinder" is a wall. `cells_around` (multiple of 4) cells
/// lie on the circumference, cells_around / 4 on each cell edge.
BlockMeshDict periodicCellMesh(double cell, double radius, double depth, int cells_around, double radial_grading = 2.0);

/// The cells around a cylinder of diameter `diameter` whose arc length on the surface is
/// closest to `spacing` (same unit): pi D / spacing rounded to the nearest multiple of 4 (the
/// O-grid's four blocks), at least 8. The periodic array's numerics.cells_per_side sets
/// mmval's spacing h = L / cells_per_side; the peer's O-grid takes this many cells around so
/// that its surface spacing is h within the rounding: pi D / cells_around differs from h by at
/// most 2 / cells_around relative when pi D / h >= 6 (exactly h when pi D / h is a multiple of 4).
/// Throws std::invalid_argument unless both are positive and finite.
int cellsAroundForSpacing(double diameter, double spacing);

}  // namespace mmval::openfoam
