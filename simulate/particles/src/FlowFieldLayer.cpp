// GriddedFlow's near-wall layer (GridWalls::brinkman): the stream function of the face fluxes at
// the cell corners, its interpolations, and the layer velocity as its curl beside walls. The
// grid, its walls and the wall searches the layer asks are in FlowField.cpp.
#include "mmval/particles/FlowField.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace mmval::particles {

void GriddedFlow::integrateStream() {
  // psi of the face fluxes per unit width h_f u_f (h_f the mean depth of the face's two cells,
  // as MicromodelFlow balances them): u h = d psi / dy across an x-face, v h = -d psi / dx across
  // a y-face. The grid's left column and bottom row have no left / bottom faces of their own
  // (faceVelocity copies the opposite face), so those cells do not balance; every corner is
  // reached across real faces only: along corner row 1, then up and down each column from it,
  // the left column's corners from their right neighbours. Where the cells balance (MicromodelFlow:
  // every fluid pixel, to 1e-13) psi does not depend on that path.
  const int cx = m_nx + 1;
  m_psi.assign(static_cast<std::size_t>(cx) * (m_ny + 1), 0.0);
  const auto at = [&](int i, int j) { return static_cast<std::size_t>(j) * m_nx + i; };
  const auto P = [&](int I, int J) -> double& { return m_psi[static_cast<std::size_t>(J) * cx + I]; };
  const auto hx = [&](int i, int j) { return i + 1 < m_nx ? 0.5 * (m_h[at(i, j)] + m_h[at(i + 1, j)]) : m_h[at(i, j)]; };
  const auto hy = [&](int i, int j) { return j + 1 < m_ny ? 0.5 * (m_h[at(i, j)] + m_h[at(i, j + 1)]) : m_h[at(i, j)]; };
  const auto qx = [&](int i, int j) { return m_ux[at(i, j)] == 0.0 ? 0.0 : m_ux[at(i, j)] * hx(i, j) * m_dy; };
  const auto qy = [&](int i, int j) { return m_uy[at(i, j)] == 0.0 ? 0.0 : m_uy[at(i, j)] * hy(i, j) * m_dx; };
  for (int I = 1; I < m_nx; ++I) P(I + 1, 1) = P(I, 1) - qy(I, 0);  // the top faces of row 0
  for (int I = 1; I <= m_nx; ++I) {
    for (int J = 1; J < m_ny; ++J) P(I, J + 1) = P(I, J) + qx(I - 1, J);
    P(I, 0) = P(I, 1) - qx(I - 1, 0);
  }
  for (int J = 1; J <= m_ny; ++J) P(0, J) = P(1, J) + qy(0, J - 1);
  P(0, 0) = P(1, 0) + P(0, 1) - P(1, 1);
}

double GriddedFlow::matchDistance(double h) const { return std::max(h / std::sqrt(12.0), m_resolved) + 0.5 * std::min(m_dx, m_dy); }

namespace {
/// Brinkman slot of half-width D (D = infinity: one wall), layer thickness delta: the velocity
/// profile g(d) = 1 - cosh((D - d) / delta) / cosh(D / delta) and its integral G(d) from the
/// wall, written with exponentials of non-positive arguments so that D >> delta is safe.
struct SlotProfile {
  double delta, D;
  double e(double z) const { return std::isfinite(z) ? std::exp(-z / delta) : 0.0; }
  double g(double d) const { return 1.0 - (e(d) + e(2 * D - d)) / (1.0 + e(2 * D)); }
  double G(double d) const { return d - delta * ((1.0 - e(2 * D)) - (e(d) - e(2 * D - d))) / (1.0 + e(2 * D)); }
};
}  // namespace

namespace {
/// The facing-wall filter of the slot search: another wall makes a slot only if it faces the ray,
/// its direction to the ray point more than 96 degrees from the ray (cos 96 deg). Two discs'
/// converging gap meets the axis at ~98 degrees (StrainingTest's two discs 1.5 px apart); a
/// pixel step (90 degrees) or a kink of the smooth contour (2-21 degrees) of the same wall does not.
constexpr double kFacingCos = -0.10452846326765347;
/// The step of the stream function's difference along the wall, in spacings: large against the
/// slot search's resolution (1e-3 of it) and round-off, small because along a concave corner's
/// bisector (where q jumps) the difference and the normal derivative are taken in different
/// frames over a band of twice the step: a disc's loop fluxes were 5-12 % at 0.025, 0.5-1.2 % at 0.002.
constexpr double kCurlStep = 0.002;
/// The jump test of the difference along the wall (layerVelocity): the two one-sided differences
/// differ by more than this share of their sizes, plus this share of the flux along the wall.
constexpr double kJumpShare = 0.5;
constexpr double kJumpFloor = 0.1;
/// Slots narrower than this many spacings (half-width) have their amplitude tapered (layerStream).
constexpr double kThinSlot = 0.25;

/// The derivative at the middle of three values e apart: the central difference, unless the two
/// one-sided ones differ by more than kJumpShare of their sizes plus `floor` (a jump between two
/// of the points: each takes its own nearest wall, slot and amplitude). Then the smallest of the
/// three differences: the one-sided one on the side without the jump, or the central one when the
/// middle value is the odd one out (both one-sided differences large and opposite).
double jumpFreeDerivative(double minus, double mid, double plus, double e, double floor) {
  const double fwd = (plus - mid) / e, bwd = (mid - minus) / e, central = (plus - minus) / (2 * e);
  if (std::abs(fwd - bwd) <= kJumpShare * (std::abs(fwd) + std::abs(bwd)) + floor) return central;
  const double one_sided = std::abs(fwd) < std::abs(bwd) ? fwd : bwd;
  return std::abs(central) < std::abs(one_sided) ? central : one_sided;
}

/// Catmull-Rom weights of the four nodes around fraction u in [0, 1] of an interval, and with `dw`
/// their derivatives in u.
void catmullRomWeights(double u, double w[4], double dw[4] = nullptr) {
  const double u2 = u * u, u3 = u2 * u;
  w[0] = 0.5 * (-u3 + 2 * u2 - u);
  w[1] = 0.5 * (3 * u3 - 5 * u2 + 2);
  w[2] = 0.5 * (-3 * u3 + 4 * u2 + u);
  w[3] = 0.5 * (u3 - u2);
  if (dw == nullptr) return;
  dw[0] = 0.5 * (-3 * u2 + 4 * u - 1);
  dw[1] = 0.5 * (9 * u2 - 10 * u);
  dw[2] = 0.5 * (-9 * u2 + 8 * u + 1);
  dw[3] = 0.5 * (3 * u2 - 2 * u);
}
}  // namespace

double GriddedFlow::psiCubic(const Vec2& p) const {
  // Catmull-Rom in each direction over the 4 x 4 corners around p (indices clamped at the grid's edge).
  const double fx = std::clamp((p.x() - m_x0) / m_dx + 0.5, 0.0, static_cast<double>(m_nx));
  const double fy = std::clamp((p.y() - m_y0) / m_dy + 0.5, 0.0, static_cast<double>(m_ny));
  const int I = std::min(static_cast<int>(fx), m_nx - 1), J = std::min(static_cast<int>(fy), m_ny - 1);
  const double s = fx - I, t = fy - J;
  double wx[4], wy[4];
  catmullRomWeights(s, wx);
  catmullRomWeights(t, wy);
  const int cx = m_nx + 1;
  double sum = 0;
  for (int b = 0; b < 4; ++b) {
    const int jj = std::clamp(J - 1 + b, 0, m_ny);
    double row = 0;
    for (int c = 0; c < 4; ++c) row += wx[c] * m_psi[static_cast<std::size_t>(jj) * cx + std::clamp(I - 1 + c, 0, m_nx)];
    sum += wy[b] * row;
  }
  return sum;
}

double GriddedFlow::psiBilinear(const Vec2& p, Vec2* grad) const {
  const double fx = std::clamp((p.x() - m_x0) / m_dx + 0.5, 0.0, static_cast<double>(m_nx));
  const double fy = std::clamp((p.y() - m_y0) / m_dy + 0.5, 0.0, static_cast<double>(m_ny));
  const int I = std::min(static_cast<int>(fx), m_nx - 1), J = std::min(static_cast<int>(fy), m_ny - 1);
  const double s = fx - I, t = fy - J;
  const std::size_t k = static_cast<std::size_t>(J) * (m_nx + 1) + I;
  const double p00 = m_psi[k], p10 = m_psi[k + 1], p01 = m_psi[k + m_nx + 1], p11 = m_psi[k + m_nx + 2];
  if (grad) *grad = Vec2(((1 - t) * (p10 - p00) + t * (p11 - p01)) / m_dx, ((1 - s) * (p01 - p00) + s * (p11 - p10)) / m_dy);
  return (1 - s) * (1 - t) * p00 + s * (1 - t) * p10 + (1 - s) * t * p01 + s * t * p11;
}

double GriddedFlow::wallPsi(const Vec2& q, const Vec2& n) const {
  // A solid cell's faces carry nothing, so its four corners share the wall's value: the solid cell
  // nearest q among the 3 x 3 around the node just inside the wall.
  const Vec2 in = q - 1e-3 * std::min(m_dx, m_dy) * n;
  const int i0 = nearestNode((in.x() - m_x0) / m_dx, m_nx), j0 = nearestNode((in.y() - m_y0) / m_dy, m_ny);
  double best = std::numeric_limits<double>::infinity();
  std::size_t corner = 0;
  for (int j = std::max(0, j0 - 1); j <= std::min(m_ny - 1, j0 + 1); ++j)
    for (int i = std::max(0, i0 - 1); i <= std::min(m_nx - 1, i0 + 1); ++i) {
      if (!m_solid[static_cast<std::size_t>(j) * m_nx + i]) continue;
      const double cx = m_x0 + i * m_dx, cy = m_y0 + j * m_dy;
      const double px = std::clamp(in.x(), cx - 0.5 * m_dx, cx + 0.5 * m_dx), py = std::clamp(in.y(), cy - 0.5 * m_dy, cy + 0.5 * m_dy);
      const double e2 = (in.x() - px) * (in.x() - px) + (in.y() - py) * (in.y() - py);
      if (e2 < best) {
        best = e2;
        corner = static_cast<std::size_t>(j) * (m_nx + 1) + i;
      }
    }
  return std::isfinite(best) ? m_psi[corner] : psiBilinear(q, nullptr);
}

Vec2 GriddedFlow::smoothNormal(const Vec2& p, const Vec2& fallback) const {
  // The gradient of the Catmull-Rom interpolation of the nodes' distance transform (C1 in p).
  const double fx = std::clamp((p.x() - m_x0) / m_dx, 0.0, m_nx - 1.0), fy = std::clamp((p.y() - m_y0) / m_dy, 0.0, m_ny - 1.0);
  const int i = std::min(static_cast<int>(fx), m_nx - 2), j = std::min(static_cast<int>(fy), m_ny - 2);
  const double s = fx - i, t = fy - j;
  double wx[4], wy[4], dwx[4], dwy[4];
  catmullRomWeights(s, wx, dwx);
  catmullRomWeights(t, wy, dwy);
  const double cap = 1e3 * std::max(m_dx, m_dy);  // no wall at all: 1e300
  double gx = 0, gy = 0;
  for (int b = 0; b < 4; ++b) {
    const int jj = std::clamp(j - 1 + b, 0, m_ny - 1);
    for (int c = 0; c < 4; ++c) {
      const double v = std::min(cap, m_dist[static_cast<std::size_t>(jj) * m_nx + std::clamp(i - 1 + c, 0, m_nx - 1)]);
      gx += dwx[c] * wy[b] * v;
      gy += wx[c] * dwy[b] * v;
    }
  }
  const Vec2 g(gx / m_dx, gy / m_dy);
  const double len = g.norm();
  return len > 1e-3 ? Vec2(g / len) : fallback;
}

double GriddedFlow::layerStream(const Vec2& p, double d, const Vec2& q, double h, double d_m, double* dpsi_dn) const {
  const Vec2 n = (p - q) / d;
  const double spacing = std::min(m_dx, m_dy), half = 0.5 * spacing;
  // The slot's half-width: the largest s <= d_m with q still the nearest facing wall point of
  // q + s n, searched in [0, d_m] (a bracket that depends on the ray only, so that D is a function
  // of q and n) to 1e-3 of the curl's step (slotSwitch).
  double D = std::numeric_limits<double>::infinity();
  std::pair<int, int> hint(-1, -1);
  if (!nearestWallIsAt(q + d_m * n, d_m, hint, n, kFacingCos)) {
    const double lo = slotSwitch(q, n, d_m, 1e-3 * kCurlStep * spacing, kFacingCos);
    // The switch below the point itself (beyond the search's accuracy) is not a slot the point
    // is in: at a concave corner of one grain (or a smooth contour's kink) q's ray meets the other
    // side at once, and a slot of half-width d made B g(d) = 2 (psi - psi_w) / d, unbounded at
    // the wall. An open wall there.
    if (lo >= d - 2e-3 * kCurlStep * spacing) D = std::max(lo, d);
  }
  const SlotProfile slot{h / std::sqrt(12.0), D};
  const double psi_w = wallPsi(q, n);
  double B = 0;
  if (std::isfinite(D)) {
    // Slot: the half-slot's flux, wall to medial axis.
    B = (psiCubic(q + D * n) - psi_w) / slot.G(D);
    // A slot much narrower than a spacing (a concave corner's wedge, two contours all but
    // touching) carries the interpolation's error of psi over G(D) ~ D^2 / (2 delta): tapered as
    // (D / D0)^2 below D0 = kThinSlot spacings, B stays bounded and goes to zero with the slot.
    const double D0 = kThinSlot * spacing;
    if (D < D0) B *= (D / D0) * (D / D0);
  }
  double dB_dn = 0;
  if (!std::isfinite(D)) {
    // Open wall: the flux between the wall and half a spacing beyond the match distance, the blend
    // band's outer end (d_m + spacing / 2, where psi's interpolation runs between corners off the
    // wall, past the kink of psi at the wall), so that the layer's psi meets the bilinear one at the band's
    // outer end up to that interpolation's error. (The slope of psi over the strip around d_m gave
    // the bulk's speed without the solve's error in the flux beside the wall, but left that flux to
    // the blend band: a ribbon of jumps, LayerSpikeTest. The value carries it into the layer:
    // +7 % / +2.4 % / +0.7 % at 10 / 5 / 2.5 um cells beside a straight wall, SubCellWallTest.)
    // Taken along the smoothed normal at the point (not q's normal, which jumps at a concave corner
    // or kink of the wall: the amplitude, and psi with it, stays continuous where the nearest wall
    // point jumps; beside a straight wall the two are the same).
    const double b = d_m + half, Gb = slot.G(b);
    const auto amplitude = [&](const Vec2& x, double dx_) {
      // (Inside a solid node's cell, where a smooth contour can pass, the interpolation bends
      // towards the wall: q's normal there.)
      Vec2 ns = smoothNormal(x, n);
      if (ns.dot(n) < 0.5) ns = n;
      return (psiCubic(x + (b - dx_) * ns) - psi_w) / Gb;
    };
    B = amplitude(p, d);
    if (dpsi_dn) {
      const double e = kCurlStep * spacing;
      // The smoothed normal can turn to q's own (the 0.5 test above) between the two points: the
      // same jump test as along the wall, on the scale of B's change over a spacing.
      dB_dn = jumpFreeDerivative(amplitude(p - e * n, d - e), B, amplitude(p + e * n, d + e), e, kJumpFloor * std::abs(B) / spacing);
    }
  }
  const double psi_l = psi_w + B * slot.G(d);
  if (!std::isfinite(D) && d > d_m - half) {
    // Into the corners' bilinear psi over the outer half spacing (smoothstep: C1 in d).
    const double r = (d_m - d) / half, w = r * r * (3 - 2 * r), dw = -6 * r * (1 - r) / half;
    Vec2 grad_b;
    const double psi_b = psiBilinear(p, &grad_b);
    if (dpsi_dn) *dpsi_dn = w * (B * slot.g(d) + slot.G(d) * dB_dn) + (1 - w) * grad_b.dot(n) + dw * (psi_l - psi_b);
    return w * psi_l + (1 - w) * psi_b;
  }
  if (dpsi_dn) *dpsi_dn = B * slot.g(d) + slot.G(d) * dB_dn;
  return psi_l;
}

bool GriddedFlow::streamAt(const Vec2& p, double h, double d_m, double& psi, double bound2) const {
  if (isSolid(p.x(), p.y())) return false;
  double d2 = 0;
  Vec2 q;
  if (!searchNearestWall(p.x(), p.y(), d2, q, bound2) || d2 >= d_m * d_m) {
    psi = psiBilinear(p, nullptr);
    return true;
  }
  const double d = std::sqrt(d2);
  if (!(d > 0)) return false;
  psi = layerStream(p, d, q, h, d_m, nullptr);
  return true;
}

Vec2 GriddedFlow::layerVelocity(double x, double y, double d, const Vec2& q, double h, double d_m) const {
  // u h = curl psi: along the normal line psi's derivative is analytic (q, n and D stay; the open
  // wall's amplitude by its own difference), along the wall a central difference of psi at points
  // with their own nearest wall, slot width and amplitude (the terms of a turning frame, a changing
  // slot and amplitude).
  const Vec2 p(x, y), n = (p - q) / d, t(n.y(), -n.x());
  double dpsi_dn = 0;
  const double psi0 = layerStream(p, d, q, h, d_m, &dpsi_dn);
  const double e = kCurlStep * std::min(m_dx, m_dy);
  double plus = 0, minus = 0;
  // The stencil's points are no farther than sqrt(d^2 + e^2) from q: their searches pass over the
  // walls beyond that on their boxes (the same answer, searchNearestWall).
  const double bound2 = (d * d + e * e) * (1 + 1e-6);
  const bool has_plus = streamAt(p + e * t, h, d_m, plus, bound2), has_minus = streamAt(p - e * t, h, d_m, minus, bound2);
  double dpsi_dt = 0;
  if (has_plus && has_minus) {
    // Each point takes its own nearest wall: where two points of the stencil take walls of two
    // grains (walls that do not face each other, a wall and another grain's corner), psi can jump
    // between them, and the central difference across the jump is (jump / 2e), up to ~100x the
    // fastest flow on the paper's strip (LayerSpikeTest). A smooth psi's one-sided differences
    // differ by e psi_tt, a small part of either; a jump makes them differ by jump / e. Then the
    // side without the jump, the smaller difference, is the flow on this side of it.
    dpsi_dt = jumpFreeDerivative(minus, psi0, plus, e, kJumpFloor * std::abs(dpsi_dn));
  } else if (has_plus) dpsi_dt = (plus - psi0) / e;
  else if (has_minus) dpsi_dt = (psi0 - minus) / e;
  return (dpsi_dn * t - dpsi_dt * n) / h;
}

}  // namespace mmval::particles
