// The flow that moves particles, seen through a small interface so that the
// particle engines never depend on the fluid solver. All SI.
//
// The chip is quasi-2D: (x, y) in the plane, z across the depth from the
// bottom plate (z = 0) to the top plate (z = h(x, y)). A field gives the
// depth-averaged velocity; the particle engines put it on the parabolic
// Hele-Shaw profile across the depth,
//   u(z) = 6 u_mean z (h - z) / h^2        (plane Poiseuille, mean u_mean),
// which is exact between parallel plates and the standard closure of
// depth-averaged micromodel flow (Bruus 2008, Theoretical Microfluidics;
// reference-data/shallow-channels.toml).
#pragma once
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Core>

namespace mmval::particles {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;

/// Axis-aligned in-plane bounds of a field, m.
struct Bounds2 {
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0;
};

class FlowField {
 public:
  virtual ~FlowField() = default;
  /// Depth-averaged in-plane velocity at (x, y), m/s; zero in solid.
  virtual Vec2 meanVelocity(double x, double y) const = 0;
  /// Local depth h(x, y), m (> 0 in fluid).
  virtual double depth(double x, double y) const = 0;
  /// True where (x, y) is inside a grain or outside the chip.
  virtual bool isSolid(double x, double y) const = 0;
  /// In-plane distance from (x, y) to the nearest solid boundary (grain or
  /// side wall), m; 0 inside solid. The top and bottom plates are not walls
  /// in this sense (they are at z = 0 and z = h).
  virtual double wallDistance(double x, double y) const = 0;
  /// Unit in-plane normal pointing from the nearest wall into the fluid.
  virtual Vec2 wallNormal(double x, double y) const;
  /// Changes whenever the flow is re-solved, so that callers can drop caches.
  virtual std::uint64_t version() const = 0;
  virtual Bounds2 bounds() const = 0;

  /// The velocity at height z on the parabolic depth profile, m/s (z in [0, h]).
  Vec3 velocityAt(const Vec3& p) const;
};

/// Depth-profile factor 6 z (h - z) / h^2 (mean 1 over the depth); 0 outside [0, h].
double poiseuilleProfile(double z, double h);

/// Uniform depth-averaged flow in an unbounded slab of depth h (no side walls).
class UniformFlow final : public FlowField {
 public:
  UniformFlow(Vec2 u_mean, double depth, Bounds2 bounds = {-1, 1, -1, 1});
  Vec2 meanVelocity(double, double) const override { return m_u; }
  double depth(double, double) const override { return m_h; }
  bool isSolid(double, double) const override { return false; }
  double wallDistance(double, double) const override { return 1e300; }
  std::uint64_t version() const override { return 1; }
  Bounds2 bounds() const override { return m_bounds; }

 private:
  Vec2 m_u;
  double m_h;
  Bounds2 m_bounds;
};

/// Hele-Shaw channel: plates at z = 0 and z = depth, side walls at y = 0 and
/// y = width, flow along +x with depth-averaged speed u_mean, inlet x = 0,
/// outlet x = length. The depth-averaged velocity is a plug in y (the
/// side-wall boundary layers, ~ one depth thick, are left out: valid for
/// width >> depth; reference-data/shallow-channels.toml gives the duct correction).
class HeleShawChannel final : public FlowField {
 public:
  HeleShawChannel(double length, double width, double depth, double u_mean);
  Vec2 meanVelocity(double x, double y) const override;
  double depth(double, double) const override { return m_h; }
  bool isSolid(double x, double y) const override;
  double wallDistance(double x, double y) const override;
  Vec2 wallNormal(double x, double y) const override;
  std::uint64_t version() const override { return 1; }
  Bounds2 bounds() const override { return {0, m_length, 0, m_width}; }
  double meanSpeed() const { return m_u; }

 private:
  double m_length, m_width, m_h, m_u;
};

/// How a GriddedFlow's arrays make velocities and walls for particles.
enum class GridWalls {
  /// Velocities at the nodes, bilinear in between, solid nodes (zero) included: the
  /// velocity is not zero at the wall itself. wallDistance: bilinear interpolation of each
  /// node's Euclidean distance to the nearest solid node minus half a cell (exact beside
  /// walls along grid lines; near a convex corner of the solid it reads up to ~0.5 cell too far).
  nodes,
  /// Walls at the edges of the solid nodes' cells (the region isSolid() reports; for nodes
  /// at pixel centres, the pixel mask's edges). ux and uy of update() are face velocities:
  /// ux[j * nx + i] on the x-face between nodes i and i + 1 (the right edge of node i's
  /// cell), uy[j * nx + i] on the y-face between nodes j and j + 1 (its top edge); a cell's
  /// left (bottom) face on the grid's edge takes its right (top) face's value, and faces
  /// touching a solid cell are set to zero. In a cell the velocity is interpolated from its
  /// faces (x linearly between its x-faces, y between its y-faces: Pollock 1988, Ground
  /// Water 26:743), which is divergence-free wherever the faces' fluxes balance, follows
  /// the walls and so never carries a point across streamlines into one (the bilinear node
  /// interpolation of a field that turns around corners does). Near a wall (distance d,
  /// normal from the nearest wall point, l = half the smaller spacing) the no-slip
  /// expansion u_t ~ d, u_n ~ d^2 is imposed on that: the normal part (linear in d beside a
  /// face) is scaled by d / (2 l) within 2 l, the tangential part by d / l within l; both
  /// factors reach 1 there, so the field stays continuous in d and a face one spacing from
  /// the wall keeps its flux. Beside a straight wall this reproduces a no-slip field that is linear
  /// (tangential) and quadratic (normal) in d exactly. wallDistance is the exact
  /// distance to the solid within kExactCells cells of the point's node (the distance to
  /// each solid cell, a rectangle, is exact); beyond that reach the node transform's value,
  /// never less than the reach. wallNormal points from the nearest wall point.
  cells,
  /// As cells (same walls, distances and face velocities), but near a wall the velocity is
  /// the Brinkman-Hele-Shaw boundary layer instead of the linear no-slip expansion. The
  /// depth-averaged flow (Hele-Shaw friction 12 mu u / h^2 plus the in-plane viscous term mu
  /// lap u) rises from a straight wall as u(d) = U (1 - exp(-d / delta)), delta = h / sqrt(12)
  /// (5.8 um in a 20 um chip), a layer that 5-20 um fluid cells do not resolve. Within the
  /// match distance d_m = max(delta, resolved) + spacing / 2 of the nearest wall point q
  /// (`resolved` m: beyond it the fluid grid's velocity is trusted, e.g. the larger of its
  /// cell and the pixel; the half spacing puts the match point at the middle of the first
  /// pixel beyond it), the pore is taken as a straight slot across the normal n: its
  /// half-width D is the distance along n from q to the medial axis (where another wall
  /// becomes as near, counting only walls that face the ray, i.e. whose direction to the ray point
  /// is more than 96 degrees from n, so that a step or kink of the same wall is no slot while the
  /// converging gap between two grains is; D = infinity if that is beyond d_m), and across it the
  /// exact slot profile g(d) = 1 - cosh((D - d) / delta) / cosh(D / delta) holds (-> 1 - exp(-d /
  /// delta) for D >> delta), with G(d) its integral from the wall. The layer is the curl of a stream
  /// function (u h = curl psi, so div(h u) = 0 and no flux through the wall): psi of the faces'
  /// fluxes h_f u_f at the cell corners (single-valued where the faces balance, as MicromodelFlow's
  /// do), psi_l = psi_w + B G(d), psi_w the wall's value. B: in a slot the half-slot's flux, psi at
  /// q + D n (Catmull-Rom of the corners) minus psi_w over G(D), so psi_l is the corners' psi on the
  /// medial axis from both sides; at an open wall the flux through the strip of one spacing around
  /// d_m, across the smoothed normal (the gradient of the nodes' distance transform, continuous where
  /// q jumps at a concave corner or kink), over G's share of it, and over the outer half spacing
  /// psi_l goes into the corners' bilinear psi (smoothstep in d). The velocity: the derivative along
  /// q's normal analytically, the one along the wall by a central difference of psi (0.002
  /// spacings either side; each point with its own nearest wall, D and B), one-sided where psi
  /// jumps between the points (FlowFieldLayer.cpp, jumpFreeDerivative); slots under a quarter
  /// spacing have B tapered as (D / D0)^2. Beyond d_m: the face velocity
  /// unchanged (the curl of the bilinear psi where the depth is uniform). Assumes the depth uniform
  /// across the layer's shape (the flux h u is conserved where it is not).
  brinkman,
};

/// Grain walls below the grid's resolution for a GriddedFlow (GridWalls::cells, brinkman): the
/// grains are where `level` > 0 (e.g. simulate::SmoothMaskShape::level, the 1/2 level of the
/// smoothed mask), not their nodes' cells. `grain` (one flag per node, row-major as update()'s
/// arrays) marks the solid nodes whose cells are replaced by that region; every other solid node
/// (deposits, closed pockets, side-wall padding) stays a closed square cell. Grain nodes must be
/// solid in every update(), and the level must keep each node's centre on its node's side (as
/// SmoothMaskShape keeps pixel centres), so that the region differs from the cells only near
/// where grain and non-grain nodes meet.
struct SmoothGrainWalls {
  std::function<double(double, double)> level;  ///< > 0 inside grains, at (x, y) in m
  std::vector<std::uint8_t> grain;              ///< per node: 1 grain (the level's region), 0 not
  int samples_per_cell = 4;                     ///< contour sampling: marching squares on this many sub-cells per cell and axis (1-4)
};

/// A field on a regular grid of nodes (the fluid solver fills it): depth-averaged
/// velocity, depth and a solid mask at nodes (x0 + i dx, y0 + j dy). A point is solid
/// when its nearest node is (each node owns the cell of size dx x dy around it); outside
/// the nodes' cells is solid as well, but does not count in the wall distance. The
/// node distance transform (Felzenszwalb & Huttenlocher 2012) is computed once per
/// update, O(N). Depth: bilinear (GridWalls::cells: over the fluid corners only).
class GriddedFlow final : public FlowField {
 public:
  /// Cells around a point's node searched for the exact wall distance (GridWalls::cells);
  /// GridWalls::brinkman searches at least its match distance.
  static constexpr int kExactCells = 3;

  /// `resolved_m` (GridWalls::brinkman only, >= 0): distance from a wall beyond which the
  /// face velocities are trusted (see GridWalls::brinkman). Throws std::invalid_argument on
  /// nx, ny < 2, dx, dy <= 0 or resolved_m < 0.
  GriddedFlow(int nx, int ny, double x0, double y0, double dx, double dy, GridWalls walls = GridWalls::nodes, double resolved_m = 0.0);
  /// Replaces the field (arrays row-major, index j * nx + i; ux, uy at nodes or faces as
  /// walls() says) and bumps version(). Throws std::invalid_argument on wrong sizes or non-finite values.
  void update(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<double>& depth,
              const std::vector<std::uint8_t>& solid);
  /// Grain walls at the contour level = 0 of `walls` (see SmoothGrainWalls) instead of the grain
  /// nodes' cell edges, for isSolid, wallDistance, wallNormal and the near-wall velocity (the
  /// velocities themselves stay the face velocities of update()). The contour: marching squares
  /// on samples_per_cell^2 sub-cells of every cell within two nodes of a grain/non-grain change,
  /// each crossing bisected onto the level (to ~1e-5 of a sub-cell), saddles split by the
  /// sub-cell centre's sign; its segments are kept per cell (the cell of their midpoint). Their
  /// union with the non-grain solid cells is the solid: the distance to it is the least distance
  /// to a segment or a non-grain solid cell (exact for that polygonal contour). Call once, before
  /// or after an update(); later updates keep it. isSolid: the level's sign in the sub-cells the
  /// contour cuts, the samples' side in the others (so that it agrees with the contour). Throws
  /// std::invalid_argument for GridWalls::nodes, without a level, a wrong-sized grain mask, or
  /// samples_per_cell outside [1, 4].
  void setSmoothWalls(SmoothGrainWalls walls);
  bool smoothWalls() const { return m_smooth; }
  /// The contour's segments (x0, y0, x1, y1 each, m), for tests and pictures.
  const std::vector<double>& contourSegments() const { return m_seg; }
  Vec2 meanVelocity(double x, double y) const override;
  double depth(double x, double y) const override;
  bool isSolid(double x, double y) const override;
  double wallDistance(double x, double y) const override;
  Vec2 wallNormal(double x, double y) const override;
  std::uint64_t version() const override { return m_version; }
  /// The nodes' extent, or the domain set by setDomain.
  Bounds2 bounds() const override;
  /// Reports `domain` as bounds() instead of the nodes' extent: a field padded beyond its
  /// domain (mirror images of the pore space beyond a mirror plane, MicromodelFlow with slip
  /// sides) keeps its padding for the wall searches and velocities near the plane, while
  /// insertion and the engines' bounds stay in the domain. Walls, velocities and isSolid are
  /// unchanged: they read the nodes.
  void setDomain(const Bounds2& domain);
  int nx() const { return m_nx; }
  int ny() const { return m_ny; }
  GridWalls walls() const { return m_walls; }
  /// GridWalls::brinkman: the match distance at depth h, m: max(h / sqrt(12), resolved) + spacing / 2.
  double matchDistance(double h) const;
  /// GridWalls::cells, brinkman: the squared distance to the nearest wall within reach and its nearest
  /// point q (false: none within reach), searched without nearestWallPoint's memo. `bound2`: a
  /// squared distance known to be above the nearest wall's (a wall point's, plus a margin): cells
  /// no nearer than it are passed over on their box alone. The answer is the same with any bound
  /// (the first wall in the search's order at the least distance); with none found under it, the
  /// search runs again without it.
  bool searchNearestWall(double x, double y, double& d2, Vec2& q, double bound2 = std::numeric_limits<double>::infinity()) const;
  /// GridWalls::brinkman: whether the ray point p = q + s n still has q as its nearest wall
  /// point (p fluid, a wall within reach, none nearer than s (1 - 1e-9)); the same answer as
  /// nearestWallPoint's distance tested against s, without finding the minimum. `hint`: a wall
  /// cell (i, j) nearer than s at an earlier point of the same ray, tried first ({-1, -1}: none),
  /// set to the cell that answered false; the answer is the same with any hint (a wall cell nearer
  /// than s <= the match distance lies in the searched block).
  /// `facing_cos` < 1: only walls that face the ray count, i.e. whose direction from their point
  /// nearest p to p has a cosine below facing_cos with n (a slot's other side faces it; the same
  /// wall turned by a step or a kink does not).
  bool nearestWallIsAt(const Vec2& p, double s, std::pair<int, int>& hint, const Vec2& n = Vec2::Zero(), double facing_cos = 2.0) const;
  /// GridWalls::brinkman: the slot half-width along the ray q + s n, 0 < s <= s_max: the first s
  /// (to within tol) at which q stops being the nearest facing wall point (nearestWallIsAt's
  /// answer turns false), given that it is not q's at s_max. (The ray can pass beside a corner
  /// that faces it and come out where q is nearest again: the slot ends at the first switch.)
  double slotSwitch(const Vec2& q, const Vec2& n, double s_max, double tol, double facing_cos) const;

 private:
  double bilinear(const std::vector<double>& a, double x, double y) const;
  /// Bilinear over the fluid corners of the cell of (x, y) only; false when it has none.
  bool fluidBilinear(const std::vector<double>& a, double x, double y, double& value) const;
  /// GridWalls::cells: squared distance to the nearest solid cell within reach and the
  /// nearest point on it; false when none is within kExactCells cells.
  /// The answer is remembered per thread for the last points asked of this update (by the
  /// exact bits of x and y), so that the distance, the normal and the velocity of one point
  /// search the wall cells once: the engines ask all three at each particle's position.
  bool nearestWallPoint(double x, double y, double& d2, Vec2& q) const;
  int nearestNode(double f, int n) const;
  /// GridWalls::cells, brinkman: fills m_wall_start and m_wall_cells from m_edge and m_reach.
  void indexWallCells();
  /// GridWalls::brinkman: fills m_psi from the face velocities and depths.
  void integrateStream();
  /// The face velocities interpolated in the cell of (x, y) (Pollock), nothing imposed at walls.
  Vec2 faceVelocity(double x, double y) const;
  /// GridWalls::brinkman: the velocity at wall distance d < match distance d_m (see there) at depth h.
  Vec2 layerVelocity(double x, double y, double d, const Vec2& q, double h, double d_m) const;
  /// GridWalls::brinkman: the layer's stream function (of h u) at p, whose nearest wall point is q at
  /// distance 0 < d < d_m, and its derivative along the wall normal (if asked).
  double layerStream(const Vec2& p, double d, const Vec2& q, double h, double d_m, double* dpsi_dn) const;
  /// The stream function at any fluid point p (the layer's within d_m of a wall, else the corners'
  /// bilinear one); false in solid.
  bool streamAt(const Vec2& p, double h, double d_m, double& psi, double bound2 = std::numeric_limits<double>::infinity()) const;
  /// The corners' stream function: Catmull-Rom (C1) and bilinear (its curl is the faces' Pollock
  /// field of h u; `grad` its gradient).
  double psiCubic(const Vec2& p) const;
  double psiBilinear(const Vec2& p, Vec2* grad) const;
  /// The unit gradient of the nodes' distance transform, Catmull-Rom interpolated (continuous
  /// where the nearest wall point jumps); `fallback` where it vanishes.
  Vec2 smoothNormal(const Vec2& p, const Vec2& fallback) const;
  /// The stream function's value on the wall through q (its solid cells' corners).
  double wallPsi(const Vec2& q, const Vec2& n) const;
  int m_nx, m_ny;
  double m_x0, m_y0, m_dx, m_dy;
  GridWalls m_walls;
  double m_resolved = 0;  ///< m, GridWalls::brinkman
  int m_reach = kExactCells;  ///< cells searched around a node for the exact wall distance
  std::vector<double> m_ux, m_uy, m_h, m_dist;
  /// GridWalls::brinkman: the stream function of the face fluxes h_f u_f at the cell corners,
  /// (nx + 1) x (ny + 1), corner (I, J) at (x0 + (I - 1/2) dx, y0 + (J - 1/2) dy).
  std::vector<double> m_psi;
  std::vector<std::uint8_t> m_solid;
  std::vector<std::uint8_t> m_edge;  ///< GridWalls::cells, brinkman: solid nodes with a fluid 4-neighbour (only they can be nearest)
  std::vector<std::uint8_t> m_near;  ///< GridWalls::cells, brinkman: fluid nodes with a solid 8-neighbour (only their cells come within l of a wall)
  /// GridWalls::cells, brinkman: for each node, the m_edge nodes within m_reach cells of it
  /// (row by row, as nearestWallPoint scans them), nodes m_wall_start[k] to m_wall_start[k + 1]
  /// of m_wall_cells; built by update(), so that a wall search visits only wall cells.
  std::vector<std::size_t> m_wall_start;
  std::vector<std::int32_t> m_wall_cells;  ///< pairs (i, j)
  /// setSmoothWalls: whether it was called, the level, the grain nodes, the nodes whose cells the
  /// contour can cross (within two nodes of a grain/non-grain change: there isSolid asks the
  /// level), the contour's segments sorted by cell and each cell's first segment (m_seg_start[k]
  /// to m_seg_start[k + 1], in segments).
  bool m_smooth = false;
  std::function<double(double, double)> m_level;
  std::vector<std::uint8_t> m_grain, m_mixed;
  std::vector<double> m_seg;
  std::vector<std::uint32_t> m_seg_start;
  /// Smooth walls, mixed nodes: 2 bits per sub-cell (a + S b, S = m_samples): 0 fluid, 1 solid (its
  /// four samples on one side, no segment), 2 cut by the contour (isSolid asks the level there).
  std::vector<std::uint32_t> m_subcells;
  int m_samples = 4;
  /// Smooth walls: whether node k is a wall square (solid, not a grain: its cell is solid).
  bool squareWall(std::size_t k) const { return m_solid[k] && !(m_smooth && m_grain[k]); }
  /// Smooth walls: the nearest point of node (i, j)'s walls (its cell if squareWall, its contour
  /// segments) to (x, y) if nearer than d2 (squared), which it then lowers.
  void nearestOfNode(int i, int j, double x, double y, double& d2, Vec2& q) const;
  std::uint64_t m_version = 0;
  bool m_has_domain = false;
  Bounds2 m_domain;  ///< setDomain
  /// Unique in the process per constructed or updated field (nearestWallPoint's memo key).
  std::uint64_t m_stamp = 0;
};

}  // namespace mmval::particles
