// The theory the slit checks (SlitChecks.cpp) are judged against, apart from
// their scenes: the trajectory integral of settling in plane Poiseuille flow
// (closed form and quadrature of a given drift), the entering particle flux and
// its quantiles, the Graetz series for diffusion to absorbing plates and its
// Leveque limit, and the quadrature and root finding they need. Internal to
// mmval::particles (tests include it).
#pragma once
#include <cmath>
#include <cstddef>
#include <functional>
#include <vector>

#include "mmval/particles/FlowField.hpp"

namespace mmval::particles::checks {

/// Velocity (m/s) of a particle centred at height z (m) in the slit; uniform along the slit.
using DriftAt = std::function<Vec3(double)>;

/// Adaptive Simpson quadrature of f over [lo, hi] to absolute tolerance `eps`
/// (Lyness 1969, with Richardson's correction); recursion depth capped at 50. 0 when hi <= lo.
double integrate(const std::function<double(double)>& f, double lo, double hi, double eps);

/// Root of an increasing function g on [lo, hi] with g(lo) <= 0 <= g(hi), by bisection to `tol`.
double bisect(const std::function<double(double)>& g, double lo, double hi, double tol);

/// Cumulative entering particle flux W(z) = int_a^z v_x(z') dz' on a uniform grid over
/// [a, h - a] (trapezoid; the profile is a smooth polynomial, 20000 intervals), and its
/// quantiles: a uniform suspension enters with a flux proportional to the particles'
/// own x-velocity (the fluid's, less Faxen's term when it is on).
class EntryFlux {
 public:
  /// `drift`: the particle's velocity at height z; a, h: radius and slit depth, m.
  EntryFlux(const DriftAt& drift, double a, double h);
  double total() const { return m_w.back(); }
  /// W(z) / W(h - a).
  double fractionBelow(double z) const;
  /// Height below which the fraction q of the flux enters.
  double quantile(double q) const;

 private:
  static constexpr int kCells = 20000;
  double m_a, m_dz;
  std::vector<double> m_w;
};

// Settling of a non-Brownian particle in plane Poiseuille flow. Its centre moves
// with dx/dt = v_x(z), dz/dt = v_z(z) < 0 (both independent of x), so along a
// trajectory dx/dz = v_x / v_z and a particle entering at height z0 is caught
// (gap to the bottom plate = capture distance, centre height z_c = a + c) after
//   X(z0) = int_{z_c}^{z0} v_x(z) / |v_z(z)| dz.                              (1)
// Point particles (a, c -> 0), u = 6 U s (1 - s) with s = z / h, v_z = -v_s:
//   X(z0) = (U h / v_s) F(s0),  F(s) = int_0^s 6 t (1 - t) dt = 3 s^2 - 2 s^3,
// and the entering flux below s0 is the same F(s0) (flux-weighted entry), so the
// fraction caught within L is the flux fraction with F(s0) <= L v_s / (U h):
//   f(L) = min(1, L v_s / (h U))                                              (2)
// (Fuchs, The Mechanics of Aerosols, 1964, sedimentation in a flat channel). For
// the engine's centres in [a, h - a] with hindrance and Faxen off, (1) gives
// X = (U h / v_s) (F(s0) - F(s_c)), the flux is still u(z) but only over
// [s_a, 1 - s_a] (s_a = a / h), so
//   f(L) = [F(min(s*, 1 - s_a)) - F(s_a)] / [F(1 - s_a) - F(s_a)],
//   F(s*) = F(s_c) + L v_s / (U h)                                             (3)
// (the flux entering between a and z_c is caught at once: f(0) > 0),
// which tends to (2) as a, c -> 0: the closed form the point run is checked
// against. With the full model (Faxen's term, hindered settling) (1) is evaluated
// by quadrature of the engine's own driftVelocity: that reference follows whatever
// the model is, so it checks the time stepping and the capture, not the model.

/// F(s) = 3 s^2 - 2 s^3: the flux of plane Poiseuille flow below s = z / h over the total.
double cubicF(double s);

/// Closed form (3): fraction deposited within L for hindrance and Faxen off
/// (L, h, a, c in m, U and vs in m/s).
double pointFraction(double L, double h, double U, double vs, double a, double c);

/// (1) by quadrature of the velocity `drift`, in w = ln(gap) so that the near-wall
/// slowing of hindered settling (|v_z| ~ gap) is resolved; `scale` sets the tolerance.
double trajectoryDistance(const DriftAt& drift, double z0, double a, double c, double scale);

/// Reference fraction within L from (1): the entry height z* with X(z*) = L (X
/// increases with z0) and the flux fraction below it.
double trajectoryFraction(const DriftAt& drift, const EntryFlux& flux, double L, double a, double c, double h, double scale);

// Graetz problem for plane Poiseuille flow between two absorbing plates, axial
// diffusion neglected (Pe = U h / D >> 1). With eta = 2 z / h - 1 in [-1, 1],
// u = (3/2) U (1 - eta^2) and c = sum A_n phi_n(eta) exp(-lambda_n^2 mu),
//   mu = 8 D L / (3 U h^2),
// the eigenfunctions solve phi'' + lambda^2 (1 - eta^2) phi = 0, phi'(0) = 0,
// phi(1) = 0 (symmetric modes; a uniform inlet excites no others). The
// flux-weighted (bulk) concentration, i.e. the penetration, is
//   P(mu) = sum G_n exp(-lambda_n^2 mu),
//   G_n = (3/2) [int_0^1 (1 - eta^2) phi_n]^2 / int_0^1 (1 - eta^2) phi_n^2,
// from the orthogonality of the phi_n with weight (1 - eta^2) (Sturm-Liouville).
// Far downstream P ~ G_1 exp(-lambda_1^2 mu), i.e. the Sherwood number on the
// hydraulic diameter 2 h tends to (8/3) lambda_1^2 = 7.541 (Shah & London 1978);
// lambda_1 = 1.6816. Written with mu' = D L / (U h^2) = (3/8) mu below.
//
// The engine's particles are not points: a centre stays in [a, h - a] and is
// caught at z_c = a + c (c the capture distance), where the flow is not zero.
// The same eigenproblem on the centres' domain eta in [0, eta_c], eta_c =
// 1 - 2 z_c / h, with phi(eta_c) = 0 and the parabola unchanged, is exact for
// that: G_n = [int_0^eta_c w phi_n]^2 / (int_0^eta_c w phi_n^2 int_0^eta_c w),
// w = 1 - eta^2, and the flux entering between z_c and a (caught at once) is
// taken off: P = P_c (eta_c - eta_c^3/3) / (eta_a - eta_a^3/3), eta_a = 1 - 2a/h.
// eta_c = eta_a = 1 gives the point-particle series above.
struct GraetzSeries {
  std::vector<double> lambda, weight;
  double entry_fraction = 1.0;  ///< share of the entering flux not caught at once
  /// Penetration at mu' = D L / (U h^2).
  double penetration(double mu_prime) const {
    double p = 0;
    for (std::size_t n = 0; n < lambda.size(); ++n) p += weight[n] * std::exp(-lambda[n] * lambda[n] * 8.0 / 3.0 * mu_prime);
    return entry_fraction * p;
  }
};

/// The first `modes` eigenvalues and weights: sign changes of phi(1; lambda) scanned
/// in steps of 0.05 (eigenvalues are ~4 apart), refined by bisection. eta_c: the centres' absorbing height
/// as above (1 for point particles), eta_a: the same at contact (entry_fraction).
GraetzSeries graetzSeries(int modes, double eta_c, double eta_a);

// Leveque limit: near each plate the profile is the linear shear u = gamma y,
// gamma = 6 U / h, and the deposition flux per unit width over a length L is
// (D c0 / Gamma(4/3)) (gamma / (9 D))^(1/3) (3/2) L^(2/3) (Leveque 1928; e.g.
// Deen, Analysis of Transport Phenomena, 1998, Sec. 3.5). Two plates against
// the entering U h c0:  1 - P = 3 (2/3)^(1/3) / Gamma(4/3) mu'^(2/3) = 2.9348 mu'^(2/3).
double levequePenetration(double mu_prime);

}  // namespace mmval::particles::checks
