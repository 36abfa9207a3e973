#include "mmval/particles/FlowField.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace mmval::particles {

double poiseuilleProfile(double z, double h) {
  if (z <= 0.0 || z >= h) return 0.0;
  return 6.0 * z * (h - z) / (h * h);
}

Vec3 FlowField::velocityAt(const Vec3& p) const {
  if (isSolid(p.x(), p.y())) return Vec3::Zero();
  const Vec2 u = meanVelocity(p.x(), p.y());
  const double f = poiseuilleProfile(p.z(), depth(p.x(), p.y()));
  return {f * u.x(), f * u.y(), 0.0};
}

Vec2 FlowField::wallNormal(double x, double y) const {
  // Gradient of the distance field by central differences; the step is small
  // against pore sizes (um) but large against round-off.
  const double e = 1e-8;
  Vec2 g((wallDistance(x + e, y) - wallDistance(x - e, y)) / (2 * e),
         (wallDistance(x, y + e) - wallDistance(x, y - e)) / (2 * e));
  const double n = g.norm();
  return n > 0 ? Vec2(g / n) : Vec2(0, 0);
}

UniformFlow::UniformFlow(Vec2 u_mean, double depth, Bounds2 bounds) : m_u(u_mean), m_h(depth), m_bounds(bounds) {
  if (!(depth > 0) || !u_mean.allFinite()) throw std::invalid_argument("UniformFlow: depth must be > 0 and velocity finite");
}

HeleShawChannel::HeleShawChannel(double length, double width, double depth, double u_mean)
    : m_length(length), m_width(width), m_h(depth), m_u(u_mean) {
  if (!(length > 0) || !(width > 0) || !(depth > 0) || !std::isfinite(u_mean))
    throw std::invalid_argument("HeleShawChannel: length, width, depth must be > 0 and u_mean finite");
}

Vec2 HeleShawChannel::meanVelocity(double x, double y) const { return isSolid(x, y) ? Vec2(0, 0) : Vec2(m_u, 0); }

bool HeleShawChannel::isSolid(double, double y) const { return y <= 0.0 || y >= m_width; }

double HeleShawChannel::wallDistance(double, double y) const {
  if (y <= 0.0 || y >= m_width) return 0.0;
  return std::min(y, m_width - y);
}

Vec2 HeleShawChannel::wallNormal(double, double y) const { return y < 0.5 * m_width ? Vec2(0, 1) : Vec2(0, -1); }

GriddedFlow::GriddedFlow(int nx, int ny, double x0, double y0, double dx, double dy)
    : m_nx(nx), m_ny(ny), m_x0(x0), m_y0(y0), m_dx(dx), m_dy(dy) {
  if (nx < 2 || ny < 2 || !(dx > 0) || !(dy > 0)) throw std::invalid_argument("GriddedFlow: need nx, ny >= 2 and dx, dy > 0");
  const auto n = static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny);
  m_ux.assign(n, 0.0);
  m_uy.assign(n, 0.0);
  m_h.assign(n, 0.0);
  m_dist.assign(n, 0.0);
  m_solid.assign(n, 1);
}

void GriddedFlow::update(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<double>& depth,
                         const std::vector<std::uint8_t>& solid) {
  const auto n = static_cast<std::size_t>(m_nx) * static_cast<std::size_t>(m_ny);
  if (ux.size() != n || uy.size() != n || depth.size() != n || solid.size() != n)
    throw std::invalid_argument("GriddedFlow::update: every array needs nx * ny entries");
  for (std::size_t k = 0; k < n; ++k) {
    if (!std::isfinite(ux[k]) || !std::isfinite(uy[k]) || !std::isfinite(depth[k]))
      throw std::invalid_argument("GriddedFlow::update: non-finite value at node " + std::to_string(k));
    if (!solid[k] && !(depth[k] > 0)) throw std::invalid_argument("GriddedFlow::update: fluid node with depth <= 0 at " + std::to_string(k));
  }
  m_ux = ux;
  m_uy = uy;
  m_h = depth;
  m_solid = solid;
  // Distance of each fluid node to the nearest solid node, minus half a cell
  // (the wall sits between a solid and a fluid node): exact Euclidean distance
  // transform by lower envelopes of parabolas, one pass per axis (Felzenszwalb &
  // Huttenlocher 2012, Theory of Computing 8:415), O(N): image-sized fields
  // (1e6 nodes) update in milliseconds, so re-solves after deposition are cheap.
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::vector<double> d2(n);
  for (std::size_t k = 0; k < n; ++k) d2[k] = m_solid[k] ? 0.0 : inf;
  std::vector<double> f;
  std::vector<int> v;
  std::vector<double> zb;
  const auto pass = [&](int len, double s, auto&& get, auto&& set) {
    // 1D squared distance with node spacing s over the finite entries of f.
    f.resize(len);
    for (int q = 0; q < len; ++q) f[q] = get(q);
    v.assign(len, 0);
    zb.assign(len + 1, 0.0);
    int k = -1;
    const double s2 = s * s;
    for (int q = 0; q < len; ++q) {
      if (!std::isfinite(f[q])) continue;
      while (k >= 0) {
        const int p = v[k];
        const double x = ((f[q] + s2 * q * q) - (f[p] + s2 * p * p)) / (2.0 * s2 * (q - p));
        if (x <= zb[k]) --k;
        else break;
      }
      ++k;
      v[k] = q;
      zb[k] = k == 0 ? -inf : ((f[q] + s2 * q * q) - (f[v[k - 1]] + s2 * v[k - 1] * v[k - 1])) / (2.0 * s2 * (q - v[k - 1]));
      zb[k + 1] = inf;
    }
    if (k < 0) {
      for (int q = 0; q < len; ++q) set(q, inf);
      return;
    }
    int j = 0;
    for (int q = 0; q < len; ++q) {
      while (zb[j + 1] < q) ++j;
      const double dq = q - v[j];
      set(q, s2 * dq * dq + f[v[j]]);
    }
  };
  for (int i = 0; i < m_nx; ++i)
    pass(m_ny, m_dy, [&](int q) { return d2[static_cast<std::size_t>(q) * m_nx + i]; },
         [&](int q, double val) { d2[static_cast<std::size_t>(q) * m_nx + i] = val; });
  for (int j = 0; j < m_ny; ++j)
    pass(m_nx, m_dx, [&](int q) { return d2[static_cast<std::size_t>(j) * m_nx + q]; },
         [&](int q, double val) { d2[static_cast<std::size_t>(j) * m_nx + q] = val; });
  const double half = 0.5 * std::min(m_dx, m_dy);
  for (std::size_t k = 0; k < n; ++k) {
    if (m_solid[k]) m_dist[k] = 0.0;
    else m_dist[k] = std::isfinite(d2[k]) ? std::sqrt(d2[k]) - half : 1e300;
  }
  ++m_version;
}

double GriddedFlow::bilinear(const std::vector<double>& a, double x, double y) const {
  const double fx = std::clamp((x - m_x0) / m_dx, 0.0, m_nx - 1.0), fy = std::clamp((y - m_y0) / m_dy, 0.0, m_ny - 1.0);
  const int i = std::min(static_cast<int>(fx), m_nx - 2), j = std::min(static_cast<int>(fy), m_ny - 2);
  const double s = fx - i, t = fy - j;
  const auto at = [&](int ii, int jj) { return a[static_cast<std::size_t>(jj) * m_nx + ii]; };
  return (1 - s) * (1 - t) * at(i, j) + s * (1 - t) * at(i + 1, j) + (1 - s) * t * at(i, j + 1) + s * t * at(i + 1, j + 1);
}

bool GriddedFlow::isSolid(double x, double y) const {
  const double fx = (x - m_x0) / m_dx, fy = (y - m_y0) / m_dy;
  if (fx < -0.5 || fy < -0.5 || fx > m_nx - 0.5 || fy > m_ny - 0.5) return true;
  const int i = std::clamp(static_cast<int>(std::lround(fx)), 0, m_nx - 1), j = std::clamp(static_cast<int>(std::lround(fy)), 0, m_ny - 1);
  return m_solid[static_cast<std::size_t>(j) * m_nx + i] != 0;
}

Vec2 GriddedFlow::meanVelocity(double x, double y) const {
  if (isSolid(x, y)) return {0, 0};
  return {bilinear(m_ux, x, y), bilinear(m_uy, x, y)};
}

double GriddedFlow::depth(double x, double y) const { return bilinear(m_h, x, y); }

double GriddedFlow::wallDistance(double x, double y) const {
  if (isSolid(x, y)) return 0.0;
  return std::max(0.0, bilinear(m_dist, x, y));
}

Bounds2 GriddedFlow::bounds() const {
  return {m_x0, m_x0 + (m_nx - 1) * m_dx, m_y0, m_y0 + (m_ny - 1) * m_dy};
}

}  // namespace mmval::particles
