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
#include <memory>
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

/// A field on a regular grid of nodes (the fluid solver fills it): depth-averaged
/// velocity, depth and a solid mask at nodes (x0 + i dx, y0 + j dy), bilinear
/// interpolation in between. A cell with any solid corner counts as solid at
/// points closer to that corner than to a fluid corner (nearest-node mask).
/// The wall distance is a brute-force Euclidean distance transform of the
/// mask, computed once per update (O(N * boundary nodes), fine up to ~1e5 nodes).
class GriddedFlow final : public FlowField {
 public:
  GriddedFlow(int nx, int ny, double x0, double y0, double dx, double dy);
  /// Replaces the field (arrays row-major, index j * nx + i) and bumps version().
  /// Throws std::invalid_argument on wrong sizes or non-finite values.
  void update(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<double>& depth,
              const std::vector<std::uint8_t>& solid);
  Vec2 meanVelocity(double x, double y) const override;
  double depth(double x, double y) const override;
  bool isSolid(double x, double y) const override;
  double wallDistance(double x, double y) const override;
  std::uint64_t version() const override { return m_version; }
  Bounds2 bounds() const override;
  int nx() const { return m_nx; }
  int ny() const { return m_ny; }

 private:
  double bilinear(const std::vector<double>& a, double x, double y) const;
  int m_nx, m_ny;
  double m_x0, m_y0, m_dx, m_dy;
  std::vector<double> m_ux, m_uy, m_h, m_dist;
  std::vector<std::uint8_t> m_solid;
  std::uint64_t m_version = 0;
};

}  // namespace mmval::particles
