#include "mmval/particles/Physics.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace mmval::particles {

double stokesDragCoefficient(const Fluid& f, double diameter) { return 3.0 * kPi * f.viscosity * diameter; }

double relaxationTime(const Fluid& f, const ParticleMaterial& p) {
  return p.density * p.diameter * p.diameter / (18.0 * f.viscosity);
}

double settlingSpeed(const Fluid& f, const ParticleMaterial& p, double gravity) {
  return (p.density - f.density) * gravity * p.diameter * p.diameter / (18.0 * f.viscosity);
}

double stokesEinstein(const Fluid& f, double diameter) {
  return kBoltzmann * f.temperature / stokesDragCoefficient(f, diameter);
}

double faxenParallel(double radius, double centre_distance) {
  if (!(centre_distance > radius)) return std::numeric_limits<double>::infinity();
  const double x = radius / centre_distance;
  const double x3 = x * x * x;
  const double d = 1.0 - 9.0 / 16.0 * x + x3 / 8.0 - 45.0 / 256.0 * x3 * x - x3 * x * x / 16.0;
  return 1.0 / d;
}

double brennerPerpendicular(double radius, double centre_distance) {
  if (!(centre_distance > radius)) return std::numeric_limits<double>::infinity();
  const double alpha = std::acosh(centre_distance / radius);
  // Far from the wall the series converges quickly; near contact (alpha -> 0) it
  // needs ~1/alpha terms. sinh of large arguments overflows, so stop there: the
  // bracket tends to 0 geometrically long before.
  double sum = 0.0;
  for (int n = 1; n < 100000; ++n) {
    const double k = 2.0 * n + 1.0;
    if (k * alpha > 700.0) break;
    const double num = 2.0 * std::sinh(k * alpha) + k * std::sinh(2.0 * alpha);
    const double s = std::sinh((n + 0.5) * alpha);
    const double den = 4.0 * s * s - k * k * std::sinh(alpha) * std::sinh(alpha);
    const double term = n * (n + 1.0) / ((2.0 * n - 1.0) * (2.0 * n + 3.0)) * (num / den - 1.0);
    sum += term;
    if (std::abs(term) < 1e-13 * std::abs(sum)) break;
  }
  return 4.0 / 3.0 * std::sinh(alpha) * sum;
}

namespace {

// GCB's join (Physics.hpp): lubrication forms below delta/a = 0.01, reflections above 1.
constexpr double kNearGap = 0.01, kFarGap = 1.0;

void checkGeometry(const char* what, double radius, double centre_distance) {
  if (!(radius > 0) || !(centre_distance > radius))
    throw std::invalid_argument(std::string(what) + ": need centre_distance > radius > 0");
}

// Lubrication resistances of a sphere parallel to a wall, GCB I (delta/a -> 0), with
// l = ln(a / delta): translating sphere's force F_t (6 pi mu a U) and torque T_t
// (8 pi mu a^2 U), rotating sphere's torque T_r (8 pi mu a^3 Omega); the rotating
// sphere's force is (4/3) T_t by the symmetry of the resistance matrix.
struct Lubrication {
  double f_t, t_t, t_r;
};
Lubrication lubrication(double gap_ratio) {
  const double l = -std::log(gap_ratio);
  return {8.0 / 15.0 * l + 0.9588, 0.1 * l - 0.1895, 0.4 * l + 0.3817};
}

}  // namespace

double nearContactWeight(double radius, double centre_distance) {
  checkGeometry("nearContactWeight", radius, centre_distance);
  const double gap = (centre_distance - radius) / radius;
  const double t = std::clamp(std::log(gap / kNearGap) / std::log(kFarGap / kNearGap), 0.0, 1.0);
  return 1.0 - t * t * t * (10.0 - 15.0 * t + 6.0 * t * t);  // quintic smoothstep
}

double freeSphereParallel(double radius, double centre_distance) {
  const double far = faxenParallel(radius, centre_distance);
  if (centre_distance - radius >= kFarGap * radius) return far;  // the common case: no logarithm
  const double w = nearContactWeight(radius, centre_distance);
  const auto r = lubrication((centre_distance - radius) / radius);
  const double near = r.f_t - 4.0 / 3.0 * r.t_t * r.t_t / r.t_r;
  return w * near + (1 - w) * far;
}

ShearResponse freeSphereInShear(double radius, double centre_distance) {
  checkGeometry("freeSphereInShear", radius, centre_distance);
  const double s = centre_distance / radius, x3 = 1.0 / (s * s * s);
  ShearResponse far{1.0 - 5.0 / 16.0 * x3, 0.5 * (1.0 - 5.0 / 16.0 * x3)};
  if (s - 1.0 >= kFarGap) return far;
  const double w = nearContactWeight(radius, centre_distance);
  // Force-free, torque-free balance in units mu = a = gamma = 1 (x-force, y-torque):
  //   -6 pi F_t U + 8 pi T_t Omega + 6 pi F_s = 0,   8 pi T_t U - 8 pi T_r Omega + 4 pi T_s = 0,
  // F_s = 1.7005, T_s = 0.9440 the held sphere's contact values (GCB II, Table 1 at h/a = 1).
  const auto r = lubrication(s - 1.0);
  constexpr double f_s = 1.7005, t_s = 0.9440;
  const double u = (f_s + 2.0 / 3.0 * r.t_t * t_s / r.t_r) / (r.f_t - 4.0 / 3.0 * r.t_t * r.t_t / r.t_r);  // U / (gamma a)
  const double omega = (r.t_t * u + 0.5 * t_s) / r.t_r;
  return {w * u / s + (1 - w) * far.velocity, w * omega + (1 - w) * far.rotation};
}

double slitShearLag(double radius, double z, double h) {
  const double d_min = 1.001 * radius;
  const auto lag = [&](double d) {
    d = std::max(d, d_min);
    return d * (freeSphereInShear(radius, d).velocity - 1.0);
  };
  return 6.0 / h * (lag(z) + lag(h - z));
}

double slitMeanParticleSpeed(double radius, double h, bool curvature, bool shear_lag) {
  if (!(radius > 0) || !(h > 2 * radius)) throw std::invalid_argument("slitMeanParticleSpeed: need h > 2 radius > 0");
  const double z0 = radius, z1 = h - radius;
  const double s0 = z0 / h, s1 = z1 / h;
  const auto F = [](double s) { return 3 * s * s - 2 * s * s * s; };  // integral of 6 s (1 - s)
  double mean = (F(s1) - F(s0)) / (s1 - s0) - (curvature ? 2 * s0 * s0 : 0.0);
  if (shear_lag) {
    // The lag varies like ln(gap) at the ends: Gauss-Legendre (8 points) on panels graded
    // geometrically towards each plate resolves it without evaluating at the plates.
    static constexpr double kX[8] = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290, -0.1834346424956498,
                                     0.1834346424956498,  0.5255324099163290,  0.7966664774136267,  0.9602898564975363};
    static constexpr double kW[8] = {0.1012285362903763, 0.2223810344533745, 0.3137066378224683, 0.3626837833783620,
                                     0.3626837833783620, 0.3137066378224683, 0.2223810344533745, 0.1012285362903763};
    const double half = 0.5 * (z1 - z0);
    double sum = 0;
    // Panels of the half depth [z0, z0 + half] (the lag is symmetric about the mid-plane).
    double lo = 0;
    for (int k = 30; k >= 0; --k) {
      const double hi = k == 0 ? half : half * std::pow(0.5, k);
      for (int q = 0; q < 8; ++q) {
        const double t = 0.5 * (lo + hi) + 0.5 * (hi - lo) * kX[q];
        sum += 0.5 * (hi - lo) * kW[q] * slitShearLag(radius, z0 + t, h);
      }
      lo = hi;
    }
    mean += sum / half;
  }
  return mean;
}

double twoWallParallel(double radius, double z, double h) {
  return 1.0 + (faxenParallel(radius, z) - 1.0) + (faxenParallel(radius, h - z) - 1.0);
}

double twoWallPerpendicular(double radius, double z, double h) {
  return 1.0 + (brennerPerpendicular(radius, z) - 1.0) + (brennerPerpendicular(radius, h - z) - 1.0);
}

double hertzContactTime(double m_eff, double r_eff, double e_eff, double impact_speed) {
  if (!(m_eff > 0) || !(r_eff > 0) || !(e_eff > 0) || !(impact_speed > 0))
    throw std::invalid_argument("hertzContactTime: every argument must be > 0");
  return 2.868 * std::pow(m_eff * m_eff / (r_eff * e_eff * e_eff * impact_speed), 0.2);
}

double hertzContactTimeEqual(const ParticleMaterial& p, double impact_speed) {
  const double e_eff = p.youngs_modulus / (2.0 * (1.0 - p.poisson_ratio * p.poisson_ratio));
  return hertzContactTime(0.5 * p.mass(), 0.5 * p.radius(), e_eff, impact_speed);
}

double rayleighTime(const ParticleMaterial& p) {
  const double shear = p.youngs_modulus / (2.0 * (1.0 + p.poisson_ratio));
  return kPi * p.radius() * std::sqrt(p.density / shear) / (0.1631 * p.poisson_ratio + 0.8766);
}

}  // namespace mmval::particles
