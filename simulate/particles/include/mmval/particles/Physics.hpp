// Single-particle hydrodynamics and contact formulas shared by both engines.
// SI throughout; each formula names its source. The tests in tests/particles
// check them against the closed forms they come from.
#pragma once

namespace mmval::particles {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr double kBoltzmann = 1.380649e-23;  ///< J/K (SI 2019, exact)

struct Fluid {
  double viscosity = 1.0e-3;     ///< Pa s (water near 20 C)
  double density = 998.2;        ///< kg/m3 (water at 20 C)
  double temperature = 293.15;   ///< K
};

struct ParticleMaterial {
  double diameter = 5e-6;        ///< m
  double density = 1050.0;       ///< kg/m3 (polystyrene)
  double youngs_modulus = 1e6;   ///< Pa (softened; the paper softens E for a larger DEM step)
  double poisson_ratio = 0.3;
  double restitution = 0.5;
  double friction = 0.5;
  double radius() const { return 0.5 * diameter; }
  double volume() const { return kPi * diameter * diameter * diameter / 6.0; }
  double mass() const { return density * volume(); }
};

/// Stokes drag coefficient 3 pi mu d, N s/m (Stokes 1851).
double stokesDragCoefficient(const Fluid& f, double diameter);
/// Particle relaxation time tau_p = rho_p d^2 / (18 mu), s.
double relaxationTime(const Fluid& f, const ParticleMaterial& p);
/// Stokes terminal settling speed (rho_p - rho_f) g d^2 / (18 mu), m/s (positive: downward).
double settlingSpeed(const Fluid& f, const ParticleMaterial& p, double gravity = 9.81);
/// Stokes-Einstein diffusivity k_B T / (3 pi mu d), m2/s (Einstein 1905).
double stokesEinstein(const Fluid& f, double diameter);

/// Faxen's correction for motion parallel to one plane wall, lambda = F / (6 pi mu a U)
/// at centre distance `centre_distance` (> radius): 1 / (1 - 9/16 x + 1/8 x^3 - 45/256 x^4 - 1/16 x^5),
/// x = a / h (Happel & Brenner 1965, Eq. 7-4.28). Accurate to ~1 % for h/a >~ 1.5;
/// it is a far-field series, so near contact the drag is underestimated.
double faxenParallel(double radius, double centre_distance);
/// Brenner's exact correction for motion perpendicular to a plane wall (Brenner 1961,
/// Chem. Eng. Sci. 16:242, Eq. 2.19), series summed to 1e-12 relative. Diverges at contact.
double brennerPerpendicular(double radius, double centre_distance);

/// Two plane walls (the chip's bottom and top, gap h): corrections added as drag
/// increments of each wall alone, lambda = 1 + (lambda_bottom - 1) + (lambda_top - 1)
/// (linear superposition; Faucheux & Libchaber 1994, PRE 49:5158 find it within a
/// few % of experiment between two plates). `z` is the centre height.
double twoWallParallel(double radius, double z, double h);
double twoWallPerpendicular(double radius, double z, double h);

/// Hertz contact duration of a head-on impact at speed `impact_speed`,
/// t_c = 2.868 (m*^2 / (R* E*^2 v))^(1/5) with m*, R*, E* the effective mass,
/// radius and modulus (Johnson 1985, Eq. 11.24; the paper's Eq. 14 DEM criterion).
double hertzContactTime(double m_eff, double r_eff, double e_eff, double impact_speed);
/// Same for two equal spheres of `p` (m* = m/2, R* = R/2, E* = E / (2 (1 - nu^2))).
double hertzContactTimeEqual(const ParticleMaterial& p, double impact_speed);
/// Rayleigh time pi R sqrt(rho / G) / (0.1631 nu + 0.8766) (Ning & Thornton), s.
double rayleighTime(const ParticleMaterial& p);

}  // namespace mmval::particles
