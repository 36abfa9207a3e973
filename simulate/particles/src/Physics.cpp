#include "mmval/particles/Physics.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

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
