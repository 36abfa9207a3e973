// A post (fibre) in its Kuwabara cell, and the single-collector efficiencies
// fibre-filtration theory gives for it: the flow and the references of the
// collector checks (CollectorCheck.cpp), and the same collector in a solved square
// array. Header only: two FlowFields and a few closed forms.
//
// Notation (fibre-filtration texts, e.g. Brown 1993, Air Filtration, ch. 4-5):
//   a_f  post radius, phi = a_f^2 / b^2 its solid fraction (b the cell radius),
//   U    face (superficial) velocity: the velocity far upstream of the array,
//   R    interception parameter = capture radius / a_f, the capture radius being
//        the particle radius plus the capture distance (the gap at which it sticks),
//   Pe   = 2 a_f U / D (Peclet number on the post diameter and the face velocity),
//   eta  single-collector efficiency: particles captured per unit length of post
//        over those the face velocity carries through its projected width 2 a_f.
#pragma once
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <utility>

#include <Eigen/Core>

#include "mmval/particles/FlowField.hpp"

namespace mmval::particles::checks {

/// Kuwabara's hydrodynamic factor Ku = -ln(phi)/2 - 3/4 + phi - phi^2/4
/// (Kuwabara 1959, J. Phys. Soc. Japan 14:527).
inline double kuwabaraFactor(double phi) { return -0.5 * std::log(phi) - 0.75 + phi - 0.25 * phi * phi; }

/// Kuwabara's stream function over U a_f sin(theta), at rho = r / a_f:
///   f(rho) = [ (1 - phi/2) / rho - (1 - phi) rho + 2 rho ln rho - (phi/2) rho^3 ] / (2 Ku),
/// the Stokes solution with no slip on the post (f = f' = 0 at rho = 1), uniform normal
/// flow through the cell boundary (psi = U r sin(theta) at rho = 1/sqrt(phi)) and zero
/// vorticity there (Kuwabara 1959; the form fibre-filtration texts give, e.g. Brown 1993,
/// Air Filtration, ch. 4).
inline double kuwabaraStream(double phi, double rho) {
  return ((1 - 0.5 * phi) / rho - (1 - phi) * rho + 2 * rho * std::log(rho) - 0.5 * phi * rho * rho * rho) / (2 * kuwabaraFactor(phi));
}
/// d f / d rho of the above.
inline double kuwabaraStreamSlope(double phi, double rho) {
  return (-(1 - 0.5 * phi) / (rho * rho) - (1 - phi) + 2 * std::log(rho) + 2 - 1.5 * phi * rho * rho) / (2 * kuwabaraFactor(phi));
}

/// Interception efficiency in the Kuwabara field, exact for particles that follow
/// the streamlines: the flux between the front stagnation streamline and the one
/// that grazes the post at capture radius (1 + R) a_f (at theta = 90 deg, where
/// streamlines come closest), over U a_f: eta_R = f(1 + R) (Stechkina, Kirsch &
/// Fuchs 1969, Ann. Occup. Hyg. 12:1, with the full Kuwabara stream function).
inline double interceptionKuwabara(double phi, double r) { return kuwabaraStream(phi, 1 + r); }

/// Lee & Liu's small-R form eta_R = (1 - phi) / Ku * R^2 / (1 + R)
/// (Lee & Liu 1982, Aerosol Sci. Technol. 1:147; its leading term for R << 1).
inline double interceptionLeeLiu(double phi, double r) { return (1 - phi) / kuwabaraFactor(phi) * r * r / (1 + r); }

/// Diffusion efficiency of Stechkina & Fuchs for Kuwabara flow, boundary-layer term and
/// first finite-Pe correction: eta_D = 2.9 Ku^(-1/3) Pe^(-2/3) + 0.624 / Pe
/// (Stechkina & Fuchs 1966, Ann. Occup. Hyg. 9:59; Stechkina, Kirsch & Fuchs 1969).
inline double diffusionStechkina(double phi, double pe) { return 2.9 * std::cbrt(1 / kuwabaraFactor(phi)) * std::pow(pe, -2.0 / 3.0) + 0.624 / pe; }

/// Interception-diffusion interaction term eta_DR = 1.24 Ku^(-1/2) Pe^(-1/2) R^(2/3)
/// (Stechkina, Kirsch & Fuchs 1969): diffusion with a finite capture radius.
inline double interactionStechkina(double phi, double pe, double r) {
  return 1.24 / std::sqrt(kuwabaraFactor(phi)) / std::sqrt(pe) * std::pow(r, 2.0 / 3.0);
}

/// Lee & Liu's diffusion efficiency eta_D = 2.6 ((1 - phi) / Ku)^(1/3) Pe^(-2/3)
/// (Lee & Liu 1982, Aerosol Sci. Technol. 1:147; boundary-layer theory with an approximate
/// stream function, 2.6 where the exact boundary-layer constant is ~2.9).
inline double diffusionLeeLiu(double phi, double pe) { return 2.6 * std::cbrt((1 - phi) / kuwabaraFactor(phi)) * std::pow(pe, -2.0 / 3.0); }

/// One post of radius a_f at the origin in its Kuwabara cell of radius b = a_f / sqrt(phi),
/// flow along +x at face velocity U; outside the cell the flow is uniform (U, 0). The
/// stream function is continuous across the cell boundary (psi = U y on both sides), so a
/// particle that follows the flow enters the cell on the streamline it came on; only the
/// tangential velocity jumps there. Plane flow: no depth profile (SceneConfig::depth_profile
/// = false); `depth` only gives the particles room across the slab. The wall is the post.
class KuwabaraCell final : public FlowField {
 public:
  KuwabaraCell(double post_radius, double solid_fraction, double face_velocity, double depth, Bounds2 bounds)
      : m_a(post_radius), m_phi(solid_fraction), m_u(face_velocity), m_h(depth), m_bounds(bounds) {
    if (!(post_radius > 0) || !(solid_fraction > 0) || !(solid_fraction < 1) || !(depth > 0) || !std::isfinite(face_velocity))
      throw std::invalid_argument("KuwabaraCell: need a post radius > 0, 0 < solid fraction < 1, depth > 0 and a finite velocity");
    m_b = m_a / std::sqrt(m_phi);
  }
  double cellRadius() const { return m_b; }

  /// u_r = f(rho) U cos(theta) / rho, u_theta = -f'(rho) U sin(theta) (psi = U a_f f(rho) sin(theta)),
  /// written in x, y: u_x = U (f/rho cos^2 + f' sin^2), u_y = U (f/rho - f') sin cos.
  Vec2 meanVelocity(double x, double y) const override {
    const double r2 = x * x + y * y;
    if (r2 >= m_b * m_b) return {m_u, 0.0};
    if (r2 <= m_a * m_a) return {0.0, 0.0};
    const double r = std::sqrt(r2), rho = r / m_a, c = x / r, s = y / r;
    const double f_rho = kuwabaraStream(m_phi, rho) / rho, fp = kuwabaraStreamSlope(m_phi, rho);
    return {m_u * (f_rho * c * c + fp * s * s), m_u * (f_rho - fp) * s * c};
  }
  double depth(double, double) const override { return m_h; }
  bool isSolid(double x, double y) const override { return x * x + y * y <= m_a * m_a; }
  double wallDistance(double x, double y) const override { return std::max(0.0, std::hypot(x, y) - m_a); }
  Vec2 wallNormal(double x, double y) const override {
    const double r = std::hypot(x, y);
    return r > 0 ? Vec2(x / r, y / r) : Vec2(1, 0);
  }
  std::uint64_t version() const override { return 1; }
  Bounds2 bounds() const override { return m_bounds; }

 private:
  double m_a, m_phi, m_u, m_h, m_b;
  Bounds2 m_bounds;
};

/// One period [-L/2, L/2]^2 of a square array of posts (post at the origin) whose plane Stokes
/// flow mmval's fluid solver computed (periodic on all sides; CollectorCheck.cpp solves it): its
/// MAC face velocities interpolated bilinearly on their own staggered grids, wrapped
/// periodically; the post itself is the exact circle (no staircase), so only the velocity carries
/// the grid's error. Scaled to face (superficial) velocity U.
class SquareArrayCell final : public FlowField {
 public:
  SquareArrayCell(Eigen::ArrayXXd u, Eigen::ArrayXXd v, int n, double period, double post_radius, double depth, Bounds2 bounds)
      : m_u(std::move(u)), m_v(std::move(v)), m_n(n), m_L(period), m_a(post_radius), m_h(depth), m_bounds(bounds) {}
  double period() const { return m_L; }
  double postRadius() const { return m_a; }
  Vec2 meanVelocity(double x, double y) const override {
    if (isSolid(x, y)) return {0.0, 0.0};
    // Solver frame: the post at the period's centre; u at (i h, (j + 1/2) h), v at ((i + 1/2) h, j h).
    const double h = m_L / m_n, X = x + 0.5 * m_L, Y = y + 0.5 * m_L;
    return {bilinear(m_u, X / h, Y / h - 0.5), bilinear(m_v, X / h - 0.5, Y / h)};
  }
  double depth(double, double) const override { return m_h; }
  bool isSolid(double x, double y) const override { return local(x, y).norm() <= m_a; }
  double wallDistance(double x, double y) const override { return std::max(0.0, local(x, y).norm() - m_a); }
  Vec2 wallNormal(double x, double y) const override {
    const Vec2 l = local(x, y);
    const double r = l.norm();
    return r > 0 ? Vec2(l / r) : Vec2(1, 0);
  }
  std::uint64_t version() const override { return 1; }
  Bounds2 bounds() const override { return m_bounds; }

 private:
  /// Position relative to the nearest post of the array.
  Vec2 local(double x, double y) const { return {x - m_L * std::round(x / m_L), y - m_L * std::round(y / m_L)}; }
  /// Bilinear interpolation at fractional index (fi, fj) with period n in both indices (the
  /// solver's extra face column or row repeats the first).
  double bilinear(const Eigen::ArrayXXd& a, double fi, double fj) const {
    const double i0 = std::floor(fi), j0 = std::floor(fj), s = fi - i0, t = fj - j0;
    const auto at = [&](double i, double j) {
      const auto ii = static_cast<Eigen::Index>(((static_cast<long>(i) % m_n) + m_n) % m_n);
      const auto jj = static_cast<Eigen::Index>(((static_cast<long>(j) % m_n) + m_n) % m_n);
      return a(jj, ii);
    };
    return (1 - s) * (1 - t) * at(i0, j0) + s * (1 - t) * at(i0 + 1, j0) + (1 - s) * t * at(i0, j0 + 1) + s * t * at(i0 + 1, j0 + 1);
  }
  Eigen::ArrayXXd m_u, m_v;
  long m_n;
  double m_L, m_a, m_h;
  Bounds2 m_bounds;
};

}  // namespace mmval::particles::checks
