#include "mmval/particles/FlowField.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

namespace mmval::particles {

namespace {
/// Stamps of GriddedFlow states (construction, each update), unique in the process.
std::atomic<std::uint64_t> g_field_stamps{0};
std::uint64_t nextFieldStamp() { return ++g_field_stamps; }

/// nearestWallPoint's answers for the last two points asked, per thread, keyed by the field's
/// stamp and the bits of (x, y), so that a hit is the search's own result for that field state.
/// Two points: an engine asks the distance, normal and velocity of one point in a row, and a
/// bigger, hashed memo costs more in cache misses than the searches it saves.
struct NearestWallMemo {
  struct Entry {
    std::uint64_t stamp = 0, bx = 0, by = 0;
    double d2 = 0;
    Vec2 q = Vec2::Zero();
    bool found = false;
  };
  Entry slots[2];
  int next = 0;  ///< the slot the next miss overwrites
};
/// The squared distance from x to the segment c = (x0, y0, x1, y1) and the segment's point qq nearest x.
double segmentNearest(const double* c, const Vec2& x, Vec2& qq) {
  const double ex = c[2] - c[0], ey = c[3] - c[1], l2 = ex * ex + ey * ey;
  const double t = l2 > 0 ? std::clamp(((x.x() - c[0]) * ex + (x.y() - c[1]) * ey) / l2, 0.0, 1.0) : 0.0;
  qq = Vec2(c[0] + t * ex, c[1] + t * ey);
  return (x - qq).squaredNorm();
}

/// The least s in (lo, hi] at which A s^2 + B s + C (positive at lo) reaches 0, +infinity if none:
/// the stable pair of roots (one of them C / q, accurate when A is tiny).
double firstRootAfter(double A, double B, double C, double lo, double hi) {
  const double disc = B * B - 4 * A * C;
  if (!(disc >= 0)) return std::numeric_limits<double>::infinity();
  const double qq = -0.5 * (B + std::copysign(std::sqrt(disc), B));
  double best = std::numeric_limits<double>::infinity();
  for (const double r : {A != 0 ? qq / A : best, qq != 0 ? C / qq : best})
    if (r > lo && r <= hi) best = std::min(best, r);
  return best;
}

/// The least s in [0, s_max] at which the point c lies within kappa s of q + s n (+infinity if
/// none; 0 if q is c): |w + s n|^2 = kappa^2 s^2 with w = q - c.
double pointReach(const double* c, const Vec2& q, const Vec2& n, double kappa, double s_max) {
  const Vec2 w(q.x() - c[0], q.y() - c[1]);
  const double C = w.squaredNorm();
  if (!(C > 0)) return 0.0;
  return firstRootAfter(1 - kappa * kappa, 2 * n.dot(w), C, 0.0, s_max);
}

/// The least s in [0, s_max] at which q + s n, projected inside the segment c = (x0, y0, x1, y1),
/// lies within kappa s of its line (+infinity if none).
double lineReach(const double* c, const Vec2& q, const Vec2& n, double kappa, double s_max) {
  const double inf = std::numeric_limits<double>::infinity();
  const Vec2 e(c[2] - c[0], c[3] - c[1]);
  const double len = e.norm();
  if (!(len > 0)) return inf;
  const Vec2 u = e / len, m(-u.y(), u.x());
  // Along the ray the projection's parameter on the segment is t0 + t1 s, in [0, len] on [s0, s1].
  const Vec2 w(q.x() - c[0], q.y() - c[1]);
  const double t0 = w.dot(u), t1 = n.dot(u);
  double s0 = 0, s1 = s_max;
  if (t1 != 0) {
    const double sa = -t0 / t1, sb = (len - t0) / t1;
    s0 = std::max(s0, std::min(sa, sb));
    s1 = std::min(s1, std::max(sa, sb));
  } else if (t0 < 0 || t0 > len) {
    return inf;
  }
  if (!(s0 <= s1)) return inf;
  // The line's distance |alpha + beta s|; within kappa s where (alpha + beta s)^2 <= kappa^2 s^2.
  const double alpha = w.dot(m), beta = n.dot(m);
  const double A = beta * beta - kappa * kappa, B = 2 * alpha * beta, C = alpha * alpha;
  if (A * s0 * s0 + B * s0 + C <= 0) return s0;
  return firstRootAfter(A, B, C, s0, s1);
}

/// The least s in [0, s_max] at which the segment c lies within kappa s of q + s n (+infinity if
/// none): its distance is the least of its ends' and, where the point projects inside it, its
/// line's. An estimate for slotSwitch, which checks it on the distance itself.
double segmentReach(const double* c, const Vec2& q, const Vec2& n, double kappa, double s_max) {
  return std::min({pointReach(c, q, n, kappa, s_max), pointReach(c + 2, q, n, kappa, s_max), lineReach(c, q, n, kappa, s_max)});
}
}  // namespace

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

GriddedFlow::GriddedFlow(int nx, int ny, double x0, double y0, double dx, double dy, GridWalls walls, double resolved_m)
    : m_nx(nx), m_ny(ny), m_x0(x0), m_y0(y0), m_dx(dx), m_dy(dy), m_walls(walls), m_resolved(resolved_m), m_stamp(nextFieldStamp()) {
  if (nx < 2 || ny < 2 || !(dx > 0) || !(dy > 0)) throw std::invalid_argument("GriddedFlow: need nx, ny >= 2 and dx, dy > 0");
  if (!(resolved_m >= 0) || !std::isfinite(resolved_m))
    throw std::invalid_argument("GriddedFlow: the resolved distance must be finite and >= 0 m, got " + std::to_string(resolved_m));
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
    if (m_smooth && m_grain[k] && !solid[k])
      throw std::invalid_argument("GriddedFlow::update: grain node " + std::to_string(k) + " of the smooth walls is not solid");
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
  if (m_walls != GridWalls::nodes) {
    m_edge.assign(n, 0);
    m_near.assign(n, 0);
    const auto at = [&](int i, int j) { return static_cast<std::size_t>(j) * m_nx + i; };
    const auto fluid = [&](int i, int j) { return i >= 0 && j >= 0 && i < m_nx && j < m_ny && !m_solid[at(i, j)]; };
    const auto solid = [&](int i, int j) { return i >= 0 && j >= 0 && i < m_nx && j < m_ny && m_solid[at(i, j)]; };
    for (int j = 0; j < m_ny; ++j)
      for (int i = 0; i < m_nx; ++i) {
        if (m_smooth) {
          // Smooth walls: a wall square with a neighbour that is not one (fluid, or a grain whose
          // contour may leave its cell's edge bare), and every cell holding contour segments.
          const std::size_t k = at(i, j);
          const auto open = [&](int ii, int jj) { return ii >= 0 && jj >= 0 && ii < m_nx && jj < m_ny && !squareWall(at(ii, jj)); };
          m_edge[k] = (squareWall(k) && (open(i - 1, j) || open(i + 1, j) || open(i, j - 1) || open(i, j + 1))) ||
                      m_seg_start[k + 1] > m_seg_start[k];
          if (!m_solid[k]) m_near[k] = m_mixed[k];
        }
        if (m_solid[at(i, j)]) {
          if (!m_smooth) m_edge[at(i, j)] = fluid(i - 1, j) || fluid(i + 1, j) || fluid(i, j - 1) || fluid(i, j + 1);
          continue;
        }
        for (int b = -1; b <= 1; ++b)
          for (int c = -1; c <= 1; ++c) m_near[at(i, j)] |= solid(i + c, j + b) ? 1 : 0;
        // No flow through a wall: faces touching a solid cell carry nothing.
        if (solid(i + 1, j)) m_ux[at(i, j)] = 0.0;
        if (solid(i, j + 1)) m_uy[at(i, j)] = 0.0;
      }
    for (std::size_t k = 0; k < n; ++k)
      if (m_solid[k]) m_ux[k] = m_uy[k] = 0.0;
  }
  if (m_walls == GridWalls::brinkman) integrateStream();
  m_reach = kExactCells;
  if (m_walls == GridWalls::brinkman) {
    // Search far enough that every point up to the deepest place's match distance from a wall
    // gets its exact distance (the match point and the medial-axis search stand there).
    double h_max = 0;
    for (std::size_t k = 0; k < n; ++k)
      if (!m_solid[k]) h_max = std::max(h_max, m_h[k]);
    m_reach = std::max(kExactCells, static_cast<int>(std::ceil(matchDistance(h_max) / std::min(m_dx, m_dy))));
  }
  if (m_walls != GridWalls::nodes) indexWallCells();
  ++m_version;
  m_stamp = nextFieldStamp();
}

void GriddedFlow::indexWallCells() {
  // The wall search visits the (2 reach + 1)^2 nodes around a point's node, of which only the
  // solid ones with a fluid neighbour count (a few per block beside a wall): list those once
  // per update, in the search's order, so that equal distances resolve to the same wall point.
  const auto n = static_cast<std::size_t>(m_nx) * static_cast<std::size_t>(m_ny);
  m_wall_start.assign(n + 1, 0);
  m_wall_cells.clear();
  for (int jc = 0; jc < m_ny; ++jc)
    for (int ic = 0; ic < m_nx; ++ic) {
      m_wall_start[static_cast<std::size_t>(jc) * m_nx + ic] = m_wall_cells.size() / 2;
      for (int j = std::max(0, jc - m_reach); j <= std::min(m_ny - 1, jc + m_reach); ++j)
        for (int i = std::max(0, ic - m_reach); i <= std::min(m_nx - 1, ic + m_reach); ++i) {
          if (!m_edge[static_cast<std::size_t>(j) * m_nx + i]) continue;
          m_wall_cells.push_back(i);
          m_wall_cells.push_back(j);
        }
    }
  m_wall_start[n] = m_wall_cells.size() / 2;
}

double GriddedFlow::bilinear(const std::vector<double>& a, double x, double y) const {
  const double fx = std::clamp((x - m_x0) / m_dx, 0.0, m_nx - 1.0), fy = std::clamp((y - m_y0) / m_dy, 0.0, m_ny - 1.0);
  const int i = std::min(static_cast<int>(fx), m_nx - 2), j = std::min(static_cast<int>(fy), m_ny - 2);
  const double s = fx - i, t = fy - j;
  const auto at = [&](int ii, int jj) { return a[static_cast<std::size_t>(jj) * m_nx + ii]; };
  return (1 - s) * (1 - t) * at(i, j) + s * (1 - t) * at(i + 1, j) + (1 - s) * t * at(i, j + 1) + s * t * at(i + 1, j + 1);
}

int GriddedFlow::nearestNode(double f, int n) const {
  // std::lround (halves away from zero) without the library call or a branch: the truncation,
  // then its fraction (exact) decides. The same value as lround for every f (NaN and huge: lround).
  long r = 0;
  if (std::abs(f) < 1e18) [[likely]] {
    r = static_cast<long>(f);
    const double frac = f - static_cast<double>(r);
    r += static_cast<long>(frac >= 0.5) - static_cast<long>(frac <= -0.5);
  } else {
    r = std::lround(f);
  }
  return std::clamp(static_cast<int>(r), 0, n - 1);
}

bool GriddedFlow::isSolid(double x, double y) const {
  const double fx = (x - m_x0) / m_dx, fy = (y - m_y0) / m_dy;
  if (fx < -0.5 || fy < -0.5 || fx > m_nx - 0.5 || fy > m_ny - 0.5) return true;
  const std::size_t k = static_cast<std::size_t>(nearestNode(fy, m_ny)) * m_nx + nearestNode(fx, m_nx);
  // Smooth walls: where the contour can pass, a wall square's cell is solid, elsewhere the level says.
  if (m_smooth && m_mixed[k]) {
    if (squareWall(k)) return true;
    // The sub-cell's state from the contour's samples: uniform (all four corners on one side, no
    // segment: the contour's side), or cut (the level's sign).
    const int S = m_samples, i = static_cast<int>(k % m_nx), j = static_cast<int>(k / m_nx);
    const int a = std::clamp(static_cast<int>(std::floor((fx - i + 0.5) * S)), 0, S - 1);
    const int b = std::clamp(static_cast<int>(std::floor((fy - j + 0.5) * S)), 0, S - 1);
    const unsigned state = (m_subcells[k] >> (2 * (b * S + a))) & 3u;
    return state == 2u ? m_level(x, y) > 0 : state == 1u;
  }
  return m_solid[k] != 0;
}

void GriddedFlow::setSmoothWalls(SmoothGrainWalls walls) {
  const auto n = static_cast<std::size_t>(m_nx) * static_cast<std::size_t>(m_ny);
  if (m_walls == GridWalls::nodes) throw std::invalid_argument("GriddedFlow::setSmoothWalls: needs GridWalls::cells or brinkman");
  if (!walls.level) throw std::invalid_argument("GriddedFlow::setSmoothWalls: no level function");
  if (walls.grain.size() != n) throw std::invalid_argument("GriddedFlow::setSmoothWalls: the grain mask needs nx * ny entries");
  if (walls.samples_per_cell < 1 || walls.samples_per_cell > 4)
    throw std::invalid_argument("GriddedFlow::setSmoothWalls: samples_per_cell must be in [1, 4], got " + std::to_string(walls.samples_per_cell));
  m_level = std::move(walls.level);
  m_grain = std::move(walls.grain);
  const auto at = [&](int i, int j) { return static_cast<std::size_t>(j) * m_nx + i; };
  // Nodes whose cells the contour can cross: within two nodes of a grain/non-grain change (the
  // level keeps node centres on their sides, and its cubic interpolation reaches two nodes).
  std::vector<std::uint8_t> change(n, 0);
  for (int j = 0; j < m_ny; ++j)
    for (int i = 0; i < m_nx; ++i)
      for (int b = -1; b <= 1 && !change[at(i, j)]; ++b)
        for (int c = -1; c <= 1; ++c) {
          const int ii = i + c, jj = j + b;
          if (ii < 0 || jj < 0 || ii >= m_nx || jj >= m_ny) continue;
          if (m_grain[at(ii, jj)] != m_grain[at(i, j)]) change[at(i, j)] = 1;
        }
  m_mixed.assign(n, 0);
  for (int j = 0; j < m_ny; ++j)
    for (int i = 0; i < m_nx; ++i)
      for (int b = -1; b <= 1 && !m_mixed[at(i, j)]; ++b)
        for (int c = -1; c <= 1; ++c) {
          const int ii = i + c, jj = j + b;
          if (ii >= 0 && jj >= 0 && ii < m_nx && jj < m_ny && change[at(ii, jj)]) m_mixed[at(i, j)] = 1;
        }
  // Marching squares on the sub-cells of the mixed cells. Sample (m, l) sits at
  // (x0 + (m / S - 1/2) dx, y0 + (l / S - 1/2) dy): each sub-cell lies in one node's cell, and
  // a sample shared by two cells is computed from the same indices, so their segments meet.
  const int S = walls.samples_per_cell;
  const auto X = [&](int m) { return m_x0 + (static_cast<double>(m) / S - 0.5) * m_dx; };
  const auto Y = [&](int l) { return m_y0 + (static_cast<double>(l) / S - 0.5) * m_dy; };
  // The level's crossing on the segment from a to b (a sample edge, always given from its lower
  // to its upper end, so that both sub-cells sharing it find the same point): bisection, then the
  // chord of the last bracket.
  const auto crossing = [&](Vec2 a, Vec2 b, double fa, double fb) {
    const bool in_a = fa > 0;
    for (int it = 0; it < 16; ++it) {
      const Vec2 mid = 0.5 * (a + b);
      const double fm = m_level(mid.x(), mid.y());
      if ((fm > 0) == in_a) {
        a = mid;
        fa = fm;
      } else {
        b = mid;
        fb = fm;
      }
    }
    const double t = fa != fb ? std::clamp(fa / (fa - fb), 0.0, 1.0) : 0.5;
    return Vec2(a + t * (b - a));
  };
  m_seg.clear();
  m_seg_start.assign(n + 1, 0);
  m_subcells.assign(n, 0);
  m_samples = S;
  std::vector<double> v(static_cast<std::size_t>((S + 1) * (S + 1)));
  for (int j = 0; j < m_ny; ++j)
    for (int i = 0; i < m_nx; ++i) {
      const std::size_t k = at(i, j);
      m_seg_start[k] = static_cast<std::uint32_t>(m_seg.size() / 4);
      if (!m_mixed[k]) continue;
      for (int b = 0; b <= S; ++b)
        for (int a = 0; a <= S; ++a) v[static_cast<std::size_t>(b * (S + 1) + a)] = m_level(X(i * S + a), Y(j * S + b));
      for (int b = 0; b < S; ++b)
        for (int a = 0; a < S; ++a) {
          const int m = i * S + a, l = j * S + b;
          // Corners 0 (m, l), 1 (m + 1, l), 2 (m + 1, l + 1), 3 (m, l + 1).
          const Vec2 p[4] = {{X(m), Y(l)}, {X(m + 1), Y(l)}, {X(m + 1), Y(l + 1)}, {X(m), Y(l + 1)}};
          const double f[4] = {v[static_cast<std::size_t>(b * (S + 1) + a)], v[static_cast<std::size_t>(b * (S + 1) + a + 1)],
                               v[static_cast<std::size_t>((b + 1) * (S + 1) + a + 1)], v[static_cast<std::size_t>((b + 1) * (S + 1) + a)]};
          const bool in[4] = {f[0] > 0, f[1] > 0, f[2] > 0, f[3] > 0};
          const bool uniform = in[0] == in[1] && in[1] == in[2] && in[2] == in[3];
          m_subcells[k] |= (uniform ? (in[0] ? 1u : 0u) : 2u) << (2 * (b * S + a));
          // Edges 0 (0-1), 1 (1-2), 2 (3-2), 3 (0-3), each from its lower (left or bottom) end.
          static constexpr int ea[4] = {0, 1, 3, 0}, eb[4] = {1, 2, 2, 3};
          Vec2 cut[4];
          int cuts = 0;
          for (int e = 0; e < 4; ++e)
            if (in[ea[e]] != in[eb[e]]) {
              cut[e] = crossing(p[ea[e]], p[eb[e]], f[ea[e]], f[eb[e]]);
              ++cuts;
            }
          const auto add = [&](int e1, int e2) {
            m_seg.insert(m_seg.end(), {cut[e1].x(), cut[e1].y(), cut[e2].x(), cut[e2].y()});
          };
          if (cuts == 2) {
            int e1 = -1, e2 = -1;
            for (int e = 0; e < 4; ++e)
              if (in[ea[e]] != in[eb[e]]) (e1 < 0 ? e1 : e2) = e;
            add(e1, e2);
          } else if (cuts == 4) {
            // Saddle: the centre's side joins corners 0 and 2 (then 1 and 3 are cut off) or not.
            const bool centre_in = m_level(0.5 * (p[0].x() + p[2].x()), 0.5 * (p[0].y() + p[2].y())) > 0;
            if (centre_in == in[0]) {
              add(0, 1);
              add(2, 3);
            } else {
              add(0, 3);
              add(1, 2);
            }
          }
        }
    }
  m_seg_start[n] = static_cast<std::uint32_t>(m_seg.size() / 4);
  m_smooth = true;
  // An earlier update's wall index is of the cells: rebuild it (update is idempotent on its arrays).
  if (m_version > 0) {
    const std::vector<double> ux = m_ux, uy = m_uy, h = m_h;
    const std::vector<std::uint8_t> solid = m_solid;
    update(ux, uy, h, solid);
  }
}

void GriddedFlow::nearestOfNode(int i, int j, double x, double y, double& d2, Vec2& q) const {
  const std::size_t k = static_cast<std::size_t>(j) * m_nx + i;
  // Everything of the node lies in its cell: no nearer than the cell's nearest point.
  const double hx = 0.5 * m_dx, hy = 0.5 * m_dy, cx = m_x0 + i * m_dx, cy = m_y0 + j * m_dy;
  const double px = std::clamp(x, cx - hx, cx + hx), py = std::clamp(y, cy - hy, cy + hy);
  const double box2 = (x - px) * (x - px) + (y - py) * (y - py);
  if (!(box2 < d2)) return;
  if (squareWall(k)) {
    d2 = box2;
    q = Vec2(px, py);
    return;  // the contour's segments in a solid square are no nearer than the square
  }
  Vec2 qq;
  for (std::uint32_t s = m_seg_start[k]; s < m_seg_start[k + 1]; ++s) {
    const double e2 = segmentNearest(&m_seg[4 * static_cast<std::size_t>(s)], Vec2(x, y), qq);
    if (e2 < d2) {
      d2 = e2;
      q = qq;
    }
  }
}

bool GriddedFlow::fluidBilinear(const std::vector<double>& a, double x, double y, double& value) const {
  const double fx = std::clamp((x - m_x0) / m_dx, 0.0, m_nx - 1.0), fy = std::clamp((y - m_y0) / m_dy, 0.0, m_ny - 1.0);
  const int i = std::min(static_cast<int>(fx), m_nx - 2), j = std::min(static_cast<int>(fy), m_ny - 2);
  const double s = fx - i, t = fy - j;
  const double w[4] = {(1 - s) * (1 - t), s * (1 - t), (1 - s) * t, s * t};
  const std::size_t k[4] = {static_cast<std::size_t>(j) * m_nx + i, static_cast<std::size_t>(j) * m_nx + i + 1,
                            static_cast<std::size_t>(j + 1) * m_nx + i, static_cast<std::size_t>(j + 1) * m_nx + i + 1};
  double sw = 0, sum = 0;
  for (int c = 0; c < 4; ++c) {
    if (m_solid[k[c]]) continue;
    sw += w[c];
    sum += w[c] * a[k[c]];
  }
  if (sw > 0) {
    value = sum / sw;
    return true;
  }
  // On the edge of the cell that only solid corners span: the nearest node, if fluid.
  const std::size_t kk = static_cast<std::size_t>(nearestNode((y - m_y0) / m_dy, m_ny)) * m_nx + nearestNode((x - m_x0) / m_dx, m_nx);
  if (m_solid[kk]) return false;
  value = a[kk];
  return true;
}

bool GriddedFlow::nearestWallPoint(double x, double y, double& d2, Vec2& q) const {
  thread_local NearestWallMemo memo;
  std::uint64_t bx = 0, by = 0;
  std::memcpy(&bx, &x, sizeof bx);
  std::memcpy(&by, &y, sizeof by);
  const auto hit = [&](const NearestWallMemo::Entry& s) { return s.stamp == m_stamp && s.bx == bx && s.by == by; };
  NearestWallMemo::Entry* slot = hit(memo.slots[0]) ? &memo.slots[0] : hit(memo.slots[1]) ? &memo.slots[1] : nullptr;
  if (slot == nullptr) {
    slot = &memo.slots[memo.next];
    memo.next ^= 1;
    auto& e = *slot;
    e.stamp = m_stamp;
    e.bx = bx;
    e.by = by;
    e.q = Vec2::Zero();  // the search leaves q as it is when no wall cell is in the block (callers then ignore it)
    e.found = searchNearestWall(x, y, e.d2, e.q);
  }
  d2 = slot->d2;
  q = slot->q;
  return slot->found;
}

bool GriddedFlow::searchNearestWall(double x, double y, double& d2, Vec2& q, double bound2) const {
  const std::size_t k = static_cast<std::size_t>(nearestNode((y - m_y0) / m_dy, m_ny)) * m_nx + nearestNode((x - m_x0) / m_dx, m_nx);
  const double hx = 0.5 * m_dx, hy = 0.5 * m_dy;
  // Every comparison below is strict (a wall is taken only nearer than the best so far, and what is
  // passed over is no nearer than it), so starting from any value above the least distance finds
  // the same wall point as starting from infinity: the first in the list at that distance.
  d2 = bound2;
  const bool bounded = bound2 < std::numeric_limits<double>::infinity();
  // None under the bound (it was not above the least distance, or that wall lies outside this block).
  const auto unbounded = [&] { return bounded && d2 == bound2 && searchNearestWall(x, y, d2, q); };
  if (m_smooth) {
    // The wall squares and contour segments of the listed cells (a segment lies within its cell).
    for (std::size_t e = m_wall_start[k]; e < m_wall_start[k + 1]; ++e) nearestOfNode(m_wall_cells[2 * e], m_wall_cells[2 * e + 1], x, y, d2, q);
    if (unbounded()) return true;
    const double reach = m_reach * std::min(m_dx, m_dy);
    return d2 <= reach * reach;
  }
  // The wall cells (solid with a fluid neighbour) within m_reach cells of the point's node, listed
  // row by row (j), i ascending in a row. Skipped without changing the answer: a row whose y part
  // of the squared distance alone is no nearer than the best so far (the x part only adds), and the
  // rest of a row after a cell right of x that is no nearer (the x part grows along the row).
  int row = std::numeric_limits<int>::min(), skip_row = row;
  double py = 0, ey2 = 0;
  for (std::size_t e = m_wall_start[k]; e < m_wall_start[k + 1]; ++e) {
    const int i = m_wall_cells[2 * e], j = m_wall_cells[2 * e + 1];
    if (j == skip_row) continue;
    if (j != row) {
      row = j;
      const double cy = m_y0 + j * m_dy;
      py = std::clamp(y, cy - hy, cy + hy);
      ey2 = (y - py) * (y - py);
      if (!(ey2 < d2)) {
        skip_row = j;
        continue;
      }
    }
    // Nearest point of the solid cell [xi - hx, xi + hx] x [yj - hy, yj + hy].
    const double cx = m_x0 + i * m_dx;
    const double px = std::clamp(x, cx - hx, cx + hx);
    const double e2 = (x - px) * (x - px) + ey2;
    if (e2 < d2) {
      d2 = e2;
      q = Vec2(px, py);
    } else if (x < cx - hx) {
      skip_row = j;
    }
  }
  if (unbounded()) return true;
  // Any solid cell beyond the searched block is at least m_reach cells away.
  const double reach = m_reach * std::min(m_dx, m_dy);
  return d2 <= reach * reach;
}

bool GriddedFlow::nearestWallIsAt(const Vec2& p, double s, std::pair<int, int>& hint, const Vec2& n, double facing_cos) const {
  // nearestWallPoint(p) && sqrt(d2) >= s (1 - 1e-9), as a test over the cells: sqrt is monotone, so
  // the minimum's root is the roots' minimum, and the first cell nearer than that settles it.
  const double x = p.x(), y = p.y();
  // isSolid(x, y), sharing its node with the search below (square walls: the node's cell decides).
  const double fx = (x - m_x0) / m_dx, fy = (y - m_y0) / m_dy;
  if (fx < -0.5 || fy < -0.5 || fx > m_nx - 0.5 || fy > m_ny - 0.5) return false;
  const std::size_t k = static_cast<std::size_t>(nearestNode(fy, m_ny)) * m_nx + nearestNode(fx, m_nx);
  if (m_smooth ? isSolid(x, y) : m_solid[k] != 0) return false;
  const double hx = 0.5 * m_dx, hy = 0.5 * m_dy;
  const double reach = m_reach * std::min(m_dx, m_dy), t = s * (1 - 1e-9);
  // Above t^2 (1 + 1e-9) the root is above t whatever its rounding: no square root needed.
  const double t2 = t * t * (1 + 1e-9);
  if (m_smooth) {
    // As below, over the listed cells' squares and segments; a cell whose box is not nearer than t
    // is looked into only while no wall within reach has been seen.
    const double reach2 = reach * reach;
    Vec2 qq;
    const auto exact = [&](int i, int j) {
      double e2 = std::numeric_limits<double>::infinity();
      nearestOfNode(i, j, x, y, e2, qq);
      return e2;
    };
    // Nearer than t, and (with the filter) facing the ray: the direction from its point qq to p.
    const auto nearerThanT = [&](double e2) {
      if (!(e2 < t2 && std::sqrt(e2) < t)) return false;
      return facing_cos > 1.0 || !(e2 > 0) || (p - qq).dot(n) < facing_cos * std::sqrt(e2);
    };
    // Node (i, j)'s walls, piece by piece (its square, or each of its contour segments): one nearer
    // than t that faces the ray, though another of the node's pieces may be nearer (two segments
    // at a vertex of the contour: the nearer one turned away, the other facing); e2 its least
    // squared distance.
    const auto nodeNearer = [&](int i, int j, double& e2) {
      const std::size_t kc = static_cast<std::size_t>(j) * m_nx + i;
      if (squareWall(kc)) return nearerThanT(e2 = exact(i, j));
      e2 = std::numeric_limits<double>::infinity();
      bool any = false;
      for (std::uint32_t sg = m_seg_start[kc]; sg < m_seg_start[kc + 1] && !any; ++sg) {
        const double e = segmentNearest(&m_seg[4 * static_cast<std::size_t>(sg)], p, qq);
        e2 = std::min(e2, e);
        any = nearerThanT(e);
      }
      return any;
    };
    double e2 = 0;
    if (hint.first >= 0 && nodeNearer(hint.first, hint.second, e2)) return false;
    bool within = false;
    for (std::size_t e = m_wall_start[k]; e < m_wall_start[k + 1]; ++e) {
      const int i = m_wall_cells[2 * e], j = m_wall_cells[2 * e + 1];
      const double cx = m_x0 + i * m_dx, cy = m_y0 + j * m_dy;
      const double px = std::clamp(x, cx - hx, cx + hx), py = std::clamp(y, cy - hy, cy + hy);
      const double box2 = (x - px) * (x - px) + (y - py) * (y - py);
      if (!(box2 < t2 && std::sqrt(box2) < t)) {
        if (!within && box2 <= reach2) within = exact(i, j) <= reach2;
        continue;
      }
      if (nodeNearer(i, j, e2)) {
        hint = {i, j};
        return false;
      }
      within = within || e2 <= reach2;
    }
    return within;
  }
  const auto nearer = [&](int i, int j, double& e2) {
    const double cx = m_x0 + i * m_dx, cy = m_y0 + j * m_dy;
    const double px = std::clamp(x, cx - hx, cx + hx), py = std::clamp(y, cy - hy, cy + hy);
    e2 = (x - px) * (x - px) + (y - py) * (y - py);
    if (!(e2 < t2 && std::sqrt(e2) < t)) return false;
    return facing_cos > 1.0 || !(e2 > 0) || (x - px) * n.x() + (y - py) * n.y() < facing_cos * std::sqrt(e2);
  };
  // The ray's last wall cell nearer than s usually still is (bisection probes on one ray): tried
  // first, it settles a false answer without the block's scan.
  double e2 = 0;
  if (hint.first >= 0 && nearer(hint.first, hint.second, e2)) return false;
  // The cells as nearer() sees them (e2 = x part + y part, the same sum), skipping what cannot
  // change the answer (a cell is nearer or not by its e2 alone, so the order does not matter): a
  // row whose y part alone is not nearer than t (the x part only adds) once a wall within reach
  // is known, or that is beyond reach; the rest of a row after a cell right of x that is not
  // nearer and, once a wall within reach is known or it is beyond reach (the x part grows along
  // the row: the cells are listed row by row, i ascending).
  const double reach2 = reach * reach;
  bool within = false;
  int row = std::numeric_limits<int>::min(), skip_row = row;
  double ey2 = 0;
  for (std::size_t e = m_wall_start[k]; e < m_wall_start[k + 1]; ++e) {
    const int i = m_wall_cells[2 * e], j = m_wall_cells[2 * e + 1];
    if (j == skip_row) continue;
    if (j != row) {
      row = j;
      const double cy = m_y0 + j * m_dy;
      const double py = std::clamp(y, cy - hy, cy + hy);
      ey2 = (y - py) * (y - py);
      if (!(ey2 < t2) && (within || ey2 > reach2)) {
        skip_row = j;
        continue;
      }
    }
    const double cx = m_x0 + i * m_dx;
    const double px = std::clamp(x, cx - hx, cx + hx);
    e2 = (x - px) * (x - px) + ey2;
    if (e2 < t2 && std::sqrt(e2) < t && (facing_cos > 1.0 || !(e2 > 0) || nearer(i, j, e2))) {
      hint = {i, j};
      return false;
    }
    within = within || e2 <= reach2;
    if (x < cx - hx && (within || e2 > reach2)) skip_row = j;
  }
  return within;
}

double GriddedFlow::slotSwitch(const Vec2& q, const Vec2& n, double s_max, double tol, double facing_cos) const {
  // The first s at which a wall facing the ray is nearer than s, wall piece by wall piece: a cell's
  // square or one contour segment is convex, so along the ray its distance minus s, g(s), is convex
  // and non-increasing (its slope, the cosine of the ray with the direction from the piece to the
  // point, minus 1, is <= 0 and grows with s). So a piece is nearer than s from the one root of g on
  // (0, s_max] on, if g(s_max) < 0, and faces the ray (that slope below facing_cos - 1) up to some s
  // and not after: it makes a switch only at its root, if it faces the ray there. The earliest of
  // those is the answer, found on each piece alone (regula falsi, Illinois, to tol), the pieces
  // pruned by the earliest so far; one search of all walls at the answer confirms it (a point in
  // solid, or no wall within reach, answers false there too: then a bisection of the search, as
  // before). Every piece that can be nearer than s <= s_max lies within s_max of q + s_max n, in the
  // wall list of its node.
  const Vec2 end = q + s_max * n;
  const int ie = std::clamp(nearestNode((end.x() - m_x0) / m_dx, m_nx), 0, m_nx - 1);
  const int je = std::clamp(nearestNode((end.y() - m_y0) / m_dy, m_ny), 0, m_ny - 1);
  const std::size_t k = static_cast<std::size_t>(je) * m_nx + ie;
  const double hx = 0.5 * m_dx, hy = 0.5 * m_dy, keep = 1 - 1e-9;  // nearestWallIsAt's "nearer than s (1 - 1e-9)"
  double first = s_max, answer = s_max;  // the earliest switch's far side (pruning) and near side
  // One piece, by its nearest point to a point: the root of d(s) - s keep on (0, first], if any,
  // facing there. `guess`: the root from the piece's shape (its ends' and lines' quadratics,
  // segmentReach), taken when g brackets it within a thousandth of tol (g(a) >= 0 > g(b)): the
  // roots of the pieces then stand apart as they are, whichever piece comes first; else regula
  // falsi from [0, first] to tol. The earliest root's bracket is kept.
  const auto piece = [&](auto&& nearest, auto&& guess) {
    Vec2 qq;
    const auto g = [&](double s) { return std::sqrt(nearest(q + s * n, qq)) - s * keep; };
    double b = first, gb = g(b);
    if (!(gb < 0)) return;
    double a = 0, ga = 0;
    const double r = guess(first);
    bool bracketed = false;
    if (r >= 0 && r <= first) {
      const double lo = std::max(0.0, r - 1e-3 * tol), hi = std::min(first, r + 1e-3 * tol);
      const double glo = lo > 0 ? g(lo) : 0.0;  // at 0 q is on the piece or nearer than it (as below)
      const double ghi = hi < first ? g(hi) : gb;
      if (glo >= 0 && ghi < 0) {
        a = lo, ga = glo, b = hi, gb = ghi;
        bracketed = true;
      }
    }
    if (!bracketed) {
      ga = g(0);
      if (!(ga >= 0)) ga = 0;  // q itself on the piece (its own wall): a root at 0 at the earliest
    }
    int kept = 0;  // the end kept by the last step: -1 a, +1 b (Illinois halves a twice-kept end's value)
    for (int step = 0; step < 200 && b - a > tol; ++step) {
      double r = ga - gb > 0 ? (a * gb - b * ga) / (gb - ga) : 0.5 * (a + b);
      r = std::clamp(r, a + 0.5 * tol, b - 0.5 * tol);  // at least half the tolerance inside: the bracket closes near the root
      const double gr = g(r);
      if (gr >= 0) {
        a = r, ga = gr;
        if (kept == 1) gb *= 0.5;
        kept = 1;
      } else {
        b = r, gb = gr;
        if (kept == -1) ga *= 0.5;
        kept = -1;
      }
    }
    const Vec2 pb = q + b * n;
    const double len = std::sqrt(nearest(pb, qq));
    if ((!(len > 0) || (pb - qq).dot(n) < facing_cos * len) && a < answer) {
      first = b;
      answer = a;
    }
  };
  for (std::size_t e = m_wall_start[k]; e < m_wall_start[k + 1]; ++e) {
    const int i = m_wall_cells[2 * e], j = m_wall_cells[2 * e + 1];
    const double cx = m_x0 + i * m_dx, cy = m_y0 + j * m_dy;
    const auto box = [&](const Vec2& x, Vec2& qq) {
      qq = Vec2(std::clamp(x.x(), cx - hx, cx + hx), std::clamp(x.y(), cy - hy, cy + hy));
      return (x - qq).squaredNorm();
    };
    const std::size_t kc = static_cast<std::size_t>(j) * m_nx + i;
    if (!m_smooth || squareWall(kc)) {
      // The square's root: its four sides' least (outside the square its distance is theirs), each
      // corner taken once.
      piece(box, [&](double s_max) {
        const double x0 = cx - hx, x1 = cx + hx, y0 = cy - hy, y1 = cy + hy;
        const double sides[4][4] = {{x0, y0, x1, y0}, {x1, y0, x1, y1}, {x1, y1, x0, y1}, {x0, y1, x0, y0}};
        double r = std::numeric_limits<double>::infinity();
        for (const auto& c : sides) r = std::min({r, pointReach(c, q, n, keep, s_max), lineReach(c, q, n, keep, s_max)});
        return r;
      });
      continue;
    }
    Vec2 qq;
    if (!(box(q + first * n, qq) < first * first)) continue;  // the segments lie in the square
    for (std::uint32_t sg = m_seg_start[kc]; sg < m_seg_start[kc + 1]; ++sg) {
      const double* c = &m_seg[4 * static_cast<std::size_t>(sg)];
      piece([c](const Vec2& x, Vec2& qq) { return segmentNearest(c, x, qq); },
            [&](double s_max) { return segmentReach(c, q, n, keep, s_max); });
    }
  }
  std::pair<int, int> hint(-1, -1);
  const auto at = [&](double s) { return nearestWallIsAt(q + s * n, s, hint, n, facing_cos); };
  if (at(answer)) return answer;
  double lo = 0, hi = answer;
  while (hi - lo > tol) {
    const double mid = 0.5 * (lo + hi);
    (at(mid) ? lo : hi) = mid;
  }
  return lo;
}

Vec2 GriddedFlow::faceVelocity(double x, double y) const {
  // Pollock: x-velocity linear between the cell's x-faces, y-velocity between its y-faces.
  const int i = nearestNode((x - m_x0) / m_dx, m_nx), j = nearestNode((y - m_y0) / m_dy, m_ny);
  const std::size_t k = static_cast<std::size_t>(j) * m_nx + i;
  const double s = std::clamp((x - m_x0) / m_dx - i + 0.5, 0.0, 1.0), t = std::clamp((y - m_y0) / m_dy - j + 0.5, 0.0, 1.0);
  const double u_left = i > 0 ? m_ux[k - 1] : m_ux[k], v_bottom = j > 0 ? m_uy[k - m_nx] : m_uy[k];
  return {u_left + s * (m_ux[k] - u_left), v_bottom + t * (m_uy[k] - v_bottom)};
}

Vec2 GriddedFlow::meanVelocity(double x, double y) const {
  if (isSolid(x, y)) return {0, 0};
  if (m_walls == GridWalls::nodes) return {bilinear(m_ux, x, y), bilinear(m_uy, x, y)};
  Vec2 u = faceVelocity(x, y);
  if (m_walls == GridWalls::brinkman) {
    // Quick exit far from walls: the node transform reads up to ~half a spacing too far beside
    // convex corners and its bilinear interpolation up to ~0.7 spacings more.
    const double h = depth(x, y), d_m = matchDistance(h);
    // Smooth walls: the contour can lie up to ~one spacing nearer than the node transform says.
    if (bilinear(m_dist, x, y) > d_m + (m_smooth ? 3 : 2) * std::max(m_dx, m_dy)) return u;
    double d2 = 0;
    Vec2 q;
    if (!nearestWallPoint(x, y, d2, q)) return u;
    const double d = std::sqrt(d2);
    if (!(d > 0)) return {0, 0};
    return d < d_m ? layerVelocity(x, y, d, q, h, d_m) : u;
  }
  const int i = nearestNode((x - m_x0) / m_dx, m_nx), j = nearestNode((y - m_y0) / m_dy, m_ny);
  const std::size_t k = static_cast<std::size_t>(j) * m_nx + i;
  if (!m_near[k]) return u;
  // No slip: within one spacing of a wall the normal part (linear in d there) is scaled by
  // d / (2 l), making it quadratic in d, and within l the tangential part by d / l. Beside a
  // straight wall this is the no-slip expansion u_t ~ d, u_n ~ d^2 matched to the wall cell's
  // face values.
  double d2 = 0;
  Vec2 q;
  const double l = 0.5 * std::min(m_dx, m_dy);
  if (nearestWallPoint(x, y, d2, q) && d2 < 4 * l * l) {
    const double d = std::sqrt(d2);
    if (!(d > 0)) return {0, 0};
    const Vec2 n = (Vec2(x, y) - q) / d;
    const Vec2 un = u.dot(n) * n;
    u = un * (0.5 * d / l) + (u - un) * std::min(1.0, d / l);
  }
  return u;
}

double GriddedFlow::depth(double x, double y) const {
  if (m_walls == GridWalls::nodes) return bilinear(m_h, x, y);
  double h = 0;
  return fluidBilinear(m_h, x, y, h) ? h : bilinear(m_h, x, y);
}

double GriddedFlow::wallDistance(double x, double y) const {
  if (isSolid(x, y)) return 0.0;
  if (m_walls != GridWalls::nodes) {
    double d2 = 0;
    Vec2 q;
    if (nearestWallPoint(x, y, d2, q)) return std::sqrt(d2);
    return std::max(m_reach * std::min(m_dx, m_dy), bilinear(m_dist, x, y));
  }
  return std::max(0.0, bilinear(m_dist, x, y));
}

Vec2 GriddedFlow::wallNormal(double x, double y) const {
  if (m_walls != GridWalls::nodes && !isSolid(x, y)) {
    double d2 = 0;
    Vec2 q;
    if (nearestWallPoint(x, y, d2, q) && d2 > 0) return (Vec2(x, y) - q) / std::sqrt(d2);
  }
  return FlowField::wallNormal(x, y);
}

void GriddedFlow::setDomain(const Bounds2& domain) {
  if (!(domain.x1 > domain.x0) || !(domain.y1 > domain.y0)) throw std::invalid_argument("GriddedFlow::setDomain: an empty domain");
  m_domain = domain;
  m_has_domain = true;
}

Bounds2 GriddedFlow::bounds() const {
  if (m_has_domain) return m_domain;
  return {m_x0, m_x0 + (m_nx - 1) * m_dx, m_y0, m_y0 + (m_ny - 1) * m_dy};
}

}  // namespace mmval::particles
