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

/// Sphere parallel to one plane wall, all gaps: Goldman, Cox & Brenner (1967, Chem.
/// Eng. Sci. 22:637 "I: motion through a quiescent fluid" and 22:653 "II: Couette
/// flow"; GCB below). Two asymptotes joined in the gap delta = centre_distance - a:
///  - near contact, lubrication theory (GCB I and II, delta/a -> 0): resistances of
///    a translating and of a rotating sphere, logarithmic in delta/a, and the force
///    and torque of a held sphere in shear at their contact values;
///  - far from it, the method of reflections: Faxen's parallel drag and the free
///    sphere's lag in shear 1 - 5/16 (a/z)^3 (GCB II).
/// The weight of the near-contact form is 1 for delta/a <= 0.01, 0 for delta/a >= 1 and
/// a quintic smoothstep in ln(delta/a) in between (C2, monotone). Against GCB's exact
/// (bipolar-coordinate) tables the join is within 1.1 % for the drag and the free
/// velocity and 2.5 % for the rotation (tests/particles/PhysicsTest.cpp, check 6).
double nearContactWeight(double radius, double centre_distance);

/// Drag factor lambda = F / (6 pi mu a U) of a sphere translating parallel to one wall
/// while free to rotate (torque-free, as a suspended particle is): the translational
/// resistance less its coupling to rotation, F_t - (4/3) T_t^2 / T_r in GCB's
/// normalisations (the translational mobility of a sphere free to rotate is the inverse
/// of this Schur complement of the symmetric resistance matrix). Near contact
/// F_t = -(8/15) ln(delta/a) + 0.9588, T_t = -(1/10) ln(delta/a) - 0.1895,
/// T_r = -(2/5) ln(delta/a) + 0.3817 (GCB I, lubrication limit); far away Faxen's
/// series (faxenParallel; the rotation coupling there is O((a/z)^8)). Diverges only
/// logarithmically at contact (0.5 ln(a/delta)), unlike Faxen's series which stays finite.
double freeSphereParallel(double radius, double centre_distance);

/// Motion of a force-free, torque-free sphere in the simple shear u = gamma z e_x
/// above a wall at z = 0 (centre at z = centre_distance).
struct ShearResponse {
  double velocity = 1.0;  ///< U / (gamma z), 1 far from the wall
  double rotation = 0.5;  ///< Omega / gamma (about the vorticity axis), 1/2 far from the wall
};
/// Near contact: the force and torque balance of the lubrication resistances above
/// with the held sphere's shear force 1.7005 x 6 pi mu a^2 gamma and torque
/// 0.9440 x 4 pi mu a^3 gamma (GCB II, contact values); to leading order this is
/// GCB II's U / (gamma a) = 0.7431 / (0.6376 - 0.2 ln(delta/a)). Far: U / (gamma z) =
/// 1 - 5/16 (a/z)^3, Omega / gamma = (1 - 5/16 (a/z)^3) / 2 (Faxen; GCB II).
/// Throws std::invalid_argument unless centre_distance > radius > 0.
ShearResponse freeSphereInShear(double radius, double centre_distance);

/// Lag of a free sphere behind the plane-Poiseuille depth profile of a slit of depth h,
/// in units of the mean speed u_mean (negative: slower than the fluid), from the shear
/// at both plates: 6/h [d_b (f(d_b) - 1) + d_t (f(d_t) - 1)] with d_b = z, d_t = h - z
/// the centre distances and f = freeSphereInShear(radius, d).velocity (each plate's wall
/// shear is 6 u_mean / h). Superposition of the two plates and the linear-shear lag
/// are approximations (HydroModel.hpp). Centre distances below 1.001 a count as 1.001 a.
double slitShearLag(double radius, double z, double h);

/// Mean over z in [a, h - a] (uniform number density) of a free sphere's speed in a slit,
/// in units of u_mean: 6 s (1 - s) (s = z/h), minus Faxen's 2 a^2/h^2 when `curvature`,
/// plus slitShearLag when `shear_lag` (Gauss-Legendre, relative accuracy ~1e-6).
/// Throws std::invalid_argument unless h > 2 radius > 0.
double slitMeanParticleSpeed(double radius, double h, bool curvature, bool shear_lag);

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
