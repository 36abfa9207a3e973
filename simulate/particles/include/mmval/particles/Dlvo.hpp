// DLVO interaction of a sphere with a plate or with another sphere across a
// symmetric z:z electrolyte: electrostatic double layer (HHF or LSA), retarded
// van der Waals (Gregory 1981), optional Born repulsion (Ruckenstein & Prieve
// 1976); the features of the energy profile; and attachment from the profile
// (barrier-limited rate: Ruckenstein & Prieve 1973; Prieve & Ruckenstein 1974,
// AIChE J. 20:1178; secondary-minimum capture: Shen et al. 2007); and the charge
// regulation of a glass collector (Basic Stern model, Behrens & Grier 2001), whose
// diffuse-layer potential can stand for its zeta potential. SI throughout:
// gaps in m, energies in J, forces in N, potentials in V. The overdamped engine evaluates DlvoInteraction::force at a
// particle's surface gap; the physics-dlvo case kind checks it against theory.
#pragma once
#include <cstdint>
#include <limits>
#include <vector>

namespace mmval::particles {

/// Symmetric z:z electrolyte in a dielectric solvent.
struct Electrolyte {
  double ionic_strength = 10.0;           ///< mol/m3 (= mM); I = c z^2 for a z:z salt of concentration c
  int valence = 1;                        ///< z of both ions (1: NaCl, KCl; 2: MgSO4)
  double temperature = 298.15;            ///< K
  double relative_permittivity = 78.5;    ///< water near 25 C
};

/// Debye length 1/kappa, kappa^2 = 2 e^2 N_A I / (eps_r eps_0 k T) with I in
/// mol/m3 (Israelachvili 2011, Intermolecular and Surface Forces, 3rd ed., Chapter 14:
/// 0.304 nm / sqrt(I / M) for a 1:1 salt at 25 C). The valence enters through I = c z^2
/// (and LSA's tanh(z e psi / 4kT)). m.
/// Throws std::invalid_argument unless I > 0, z >= 1, T > 0, eps_r > 0.
double debyeLength(const Electrolyte& e);

/// A silanol surface (glass, silica) in the Basic Stern model as Behrens & Grier (2001,
/// J. Chem. Phys. 115:6716, Sec. II) use it: SiOH <-> SiO- + H+ with dissociation constant
/// 10^-pK mol/L at the proton concentration next to the surface (bulk 10^-pH mol/L times
/// exp(-e psi_0 / kT)); a charge-free Stern layer of capacitance C between the surface
/// (psi_0, charge sigma_0 = -e Gamma alpha) and the start of the diffuse layer (psi_d); a
/// Gouy-Chapman diffuse layer whose charge is -sigma_0 (Grahame's equation for a z:z salt).
/// Defaults: the paper's silica values (reference-data/dlvo-materials.toml).
struct SternSurface {
  double pK = 7.5;               ///< -log10 of the silanol dissociation constant in mol/L
  double site_density = 8e18;    ///< Gamma, silanol sites per m2 (8 per nm2)
  double capacitance = 2.9;      ///< C, F/m2; infinity: no Stern layer (psi_d = psi_0)
};

/// The regulated state of a SternSurface in a bulk electrolyte.
struct RegulatedCharge {
  double diffuse_potential = 0;     ///< psi_d, V: what DLVO takes as the zeta (surface) potential
  double surface_potential = 0;     ///< psi_0, V, at the plane of the silanol groups
  double surface_charge = 0;        ///< sigma_0, C/m2 (<= 0); the diffuse layer holds -sigma_0
  double dissociated_fraction = 0;  ///< alpha = [SiO-] / Gamma, in [0, 1]
};

/// Solves the Basic Stern model for the diffuse-layer potential at the bulk pH and the
/// electrolyte's ionic strength, valence, temperature and permittivity. The three relations
/// (mass action, Stern layer, Grahame) reduce to one equation in x = ln(alpha / (1 - alpha)),
///   x + ln10 (pK - pH) + (2/z) asinh(g alpha) + s alpha = 0,
///   g = z e^2 Gamma / (2 eps kappa kT),  s = e^2 Gamma / (C kT),  psi_d = -(2 kT / z e) asinh(g alpha),
/// whose left side rises strictly with x and lies in [x + L, x + L + (2/z) asinh(g) + s],
/// L = ln10 (pK - pH): the root is bracketed in closed form and found by bisection to
/// rounding. Never NaN; alpha -> 0 gives psi_d = 0 exactly. Throws std::invalid_argument
/// unless 0 <= pH <= 14, pK is finite, Gamma > 0 and finite, C > 0 and the electrolyte is
/// valid (debyeLength).
RegulatedCharge regulatedCharge(const SternSurface& s, const Electrolyte& e, double pH);
/// regulatedCharge(s, e, pH).diffuse_potential, V.
double regulatedSurfacePotential(const SternSurface& s, const Electrolyte& e, double pH);

enum class DoubleLayerModel {
  /// Hogg, Healy & Fuerstenau 1966 (Trans. Faraday Soc. 62:1638), constant surface
  /// potential, Derjaguin approximation. Linearised Poisson-Boltzmann: holds for
  /// low potentials (|z e psi / k T| <~ 1, i.e. |psi| <~ 25 mV, and in practice used
  /// up to 50-60 mV) and kappa a >> 1, h << a. Unequal potentials attract at short
  /// range (constant-potential image effect).
  hhf,
  /// Linear superposition approximation (Gregory 1975, J. Colloid Interface Sci.
  /// 51:44), Derjaguin approximation: any potential, but only where the double layers
  /// overlap weakly, kappa h >~ 1 (at contact it lies above the constant-potential
  /// HHF value: 4 pi eps R psi^2 against HHF's 4 pi eps R psi^2 ln 2 at low potentials).
  lsa,
};

/// Inputs of one sphere-collector pair.
struct DlvoParameters {
  double particle_radius = 2.5e-6;  ///< m
  /// Collector radius, m; infinity: a plate (sphere-plate), finite: a sphere
  /// (sphere-sphere, Derjaguin with R = a1 a2 / (a1 + a2)).
  double collector_radius = std::numeric_limits<double>::infinity();
  double particle_potential = -0.050;   ///< surface (zeta) potential, V (latex: an assumption, no source)
  double collector_potential = -0.077;  ///< V (glass: middle of -88..-66 mV, reference-data/dlvo-materials.toml)
  /// How collector_potential came about. Fixed: an input. Regulated: the diffuse-layer potential
  /// of the Basic Stern model of `surface` at the electrolyte and `ph` (withRegulatedCollector
  /// sets it). The interaction uses collector_potential only; this says where it came from.
  struct CollectorCharge {
    bool regulated = false;
    SternSurface surface;
    double ph = 7.0;  ///< bulk pH (an assumption: the source paper gives none; neutral water)
  };
  CollectorCharge collector_charge;
  Electrolyte electrolyte;
  double hamaker = 1e-20;                 ///< J, particle-water-collector
  double retardation_wavelength = 100e-9; ///< m, Gregory 1981's lambda
  DoubleLayerModel double_layer = DoubleLayerModel::lsa;  ///< lsa: the default potentials exceed HHF's range
  bool born = true;                       ///< Born repulsion (bounds the primary minimum)
  double born_collision_diameter = 0.5e-9;  ///< m, sigma of the Born term
};

/// p with collector_potential = regulatedSurfacePotential(collector_charge.surface,
/// electrolyte, collector_charge.ph) when the collector charge is regulated; p unchanged when
/// it is fixed.
DlvoParameters withRegulatedCollector(DlvoParameters p);
/// p at another ionic strength (mol/m3): a regulated collector potential follows it, a fixed
/// one stays (what a scan over ionic strength should use).
DlvoParameters atIonicStrength(DlvoParameters p, double ionic_strength);

/// Energy and force of the pair at a surface gap h > 0 (h <= 0 is outside the model:
/// the results are not finite; callers clamp the gap). Force > 0 pushes the surfaces
/// apart (F = -dV/dh). Each evaluation is a few exp/log: cheap enough per particle step.
class DlvoInteraction {
 public:
  /// Throws std::invalid_argument naming the field for non-physical input
  /// (radius <= 0, hamaker < 0, lambda <= 0, sigma <= 0, bad electrolyte).
  explicit DlvoInteraction(const DlvoParameters& p);

  double energy(double gap) const;  ///< J
  double force(double gap) const;   ///< N
  double doubleLayerEnergy(double gap) const;
  double doubleLayerForce(double gap) const;
  /// Gregory 1981 (J. Colloid Interface Sci. 83:138): -A R / (6 h) (1 + 14 h / lambda)^-1.
  double vanDerWaalsEnergy(double gap) const;
  double vanDerWaalsForce(double gap) const;
  double bornEnergy(double gap) const;  ///< 0 when born is off
  double bornForce(double gap) const;
  /// Energy without the double layer (van der Waals + Born): the favourable
  /// profile the attachment efficiency is measured against.
  double favourableEnergy(double gap) const { return vanDerWaalsEnergy(gap) + bornEnergy(gap); }

  double kT() const { return m_kT; }
  double kappa() const { return m_kappa; }
  /// Derjaguin radius: a for a plate, a1 a2 / (a1 + a2) for two spheres.
  double effectiveRadius() const { return m_reff; }
  bool plate() const { return m_plate; }
  const DlvoParameters& parameters() const { return m_p; }

 private:
  DlvoParameters m_p;
  double m_kT = 0, m_kappa = 0, m_reff = 0, m_eps = 0;
  bool m_plate = true;
};

/// Extrema of the energy profile, energies in units of kT, gaps in m.
struct DlvoProfileFeatures {
  /// Primary maximum (energy barrier): the highest interior maximum.
  bool has_barrier = false;
  double barrier_kT = 0, barrier_gap = 0;
  /// Secondary minimum: the deepest interior minimum beyond the barrier.
  bool has_secondary_minimum = false;
  double secondary_minimum_kT = 0, secondary_minimum_gap = 0;
  /// Primary minimum: the deepest interior minimum inside the barrier (needs Born
  /// repulsion; without it the energy falls without bound at contact).
  bool has_primary_minimum = false;
  double primary_minimum_kT = 0, primary_minimum_gap = 0;
};

/// Finds the extrema by sampling V on a log-spaced grid of gaps [gap_min, gap_max]
/// and refining each bracket by golden-section search. Never NaN: absent features
/// say so through their flags. When V has no interior maximum but a well, the profile
/// without the Born term decides: if it has a maximum inside the well, that is the
/// barrier (merged with the Born wall, energy taken with Born) and the well is a
/// secondary minimum with no primary minimum; otherwise the well is the primary minimum. Throws std::invalid_argument unless 0 < gap_min < gap_max.
DlvoProfileFeatures profileFeatures(const DlvoInteraction& v, double gap_min = 0.01e-9, double gap_max = 5e-6);

/// Hydrodynamic resistance factor beta = D_inf / D_perp(h) for the gap h:
/// sphere-plate: Brenner 1961 (exact series) for h / a >= 0.01, and its near-contact
/// limit (a/h)(1 + (h/a)/5 ln(a/h) + 0.971 h/a) (Cox & Brenner 1967, Chem. Eng. Sci.
/// 22:1753) below; two equal spheres: (6u^2 + 13u + 2) / (6u^2 + 4u), u = h / a
/// (Honig, Roebersen & Wiersema 1971, J. Colloid Interface Sci. 36:97).
double normalResistanceFactor(const DlvoInteraction& v, double gap);

/// Attachment over the barrier, interaction-force-boundary-layer theory.
struct DlvoAttachment {
  /// ln of the attachment efficiency alpha = k(with double layer) / k(favourable),
  /// k = D_inf / Int_{h0}^{h1} w beta exp(Phi / kT) dh (Spielman & Friedlander 1974,
  /// J. Colloid Interface Sci. 46:22; Ruckenstein & Prieve 1973, J. Chem. Soc. Faraday
  /// Trans. 2 69:1522), w = 1 for a plate and (R1 + R2)^2 / (R1 + R2 + h)^2 for two
  /// spheres (Fuchs' geometric factor). ln because alpha underflows double for large
  /// barriers (5 um spheres: thousands of kT).
  double ln_alpha = 0;
  double alpha() const;  ///< exp(ln_alpha), 0 when it underflows
  /// Laplace (saddle-point) estimate of the same ratio around the barrier,
  /// Int ~ w beta exp(Phi_max/kT) sqrt(2 pi kT / |Phi''|) (the barrier-limited rate of
  /// Ruckenstein & Prieve 1973; Kramers 1940, Physica 7:284): accurate when the barrier >> kT.
  /// NaN-free: equals ln_alpha when there is no barrier above zero (Phi_max <= 0).
  double ln_alpha_laplace = 0;
  /// False when Born repulsion is on and no well lies inside the barrier (the double
  /// layer outweighs van der Waals down to the Born wall): alpha = 0 (ln_alpha = -inf),
  /// only secondary-minimum capture remains.
  bool primary_minimum_reachable = true;
  double inner_gap = 0, outer_gap = 0;  ///< m, integration range
  double ln_resistance = 0, ln_resistance_favourable = 0;  ///< ln of the integrals (ln m)
};

/// Integrates from the primary minimum (or gap_min when there is none) to the outer
/// edge of the interaction layer: the larger of 20 Debye lengths and the gap where
/// the van der Waals energy falls to 0.01 kT (independent of ionic strength through
/// the vdW term, so that alpha(I) compares like with like). Adaptive Simpson in ln h,
/// split at the profile's extrema. alpha depends on that outer edge only through the
/// favourable integral (logarithmically for a plate). Costs ~20 ms: evaluate once per
/// pair type and chemistry, not per particle step.
DlvoAttachment attachmentEfficiency(const DlvoInteraction& v, double gap_min = 0.01e-9);

/// d (Phi_max / kT) / d ln I at fixed surface potentials: the barrier's fall with
/// ionic strength, -h_m F_EDL(h_m) / (2 kT), from the envelope theorem at the barrier
/// gap h_m (V_EDL depends on kappa h only, kappa^2 ~ I). With alpha ~ exp(-Phi_max / kT)
/// (Kramers; Ruckenstein & Prieve 1973) it is minus the slope d ln alpha / d ln I -
/// the sphere-plate analogue of Reerink & Overbeek's (1954, Discuss. Faraday Soc.
/// 18:74) log W against log c. 0 when there is no barrier.
double barrierSlopeWithIonicStrength(const DlvoInteraction& v, const DlvoProfileFeatures& f);

/// Fraction of a Maxwell-Boltzmann population whose kinetic energy is below a
/// secondary minimum of depth `depth_kT` (in kT): the regularised incomplete gamma
/// P(3/2, x) = erf(sqrt x) - 2 sqrt(x / pi) exp(-x) (Maxwell model of secondary-minimum
/// capture: Hahn & O'Melia 2004, Environ. Sci. Technol. 38:210; Shen, Li, Huang & Jin
/// 2007, Environ. Sci. Technol. 41). 0 for depth <= 0.
double secondaryMinimumCaptureProbability(double depth_kT);

/// Attachment efficiency of a surface with patchwise charge heterogeneity (Song, Johnson &
/// Elimelech 1994, Environ. Sci. Technol. 28:1164): a fraction `favourable_fraction` (lambda) of
/// its area is favourable (no barrier: every arrival there attaches, alpha = 1), the rest follows
/// the unfavourable profile with `alpha_unfavourable`; patches larger than the particle's
/// interaction zone add as areas: lambda + (1 - lambda) alpha_unfavourable. Throws
/// std::invalid_argument unless both lie in [0, 1].
double patchwiseEfficiency(double favourable_fraction, double alpha_unfavourable);

/// splitmix64's finaliser (Steele, Lea & Flood 2014): a full 64-bit mix, the hash behind the
/// engine's per-arrival draws and the patch map, so both are deterministic in their inputs.
std::uint64_t splitmix64(std::uint64_t z);

/// Favourable patches placed in space (the patchwise model with a patch size): the glass is cut
/// into cells of side `size`, squares on a plate's (x, y) and cubes of (x, y, z) for the grain
/// walls (the cells the wall's surface crosses), and each cell is favourable with probability
/// `fraction` (lambda), decided by a hash of the run's seed, the surface and the cell's index
/// alone: the map is the same for every particle, every step and a resumed run, and the map at a
/// smaller lambda (same seed and size) is a subset of the map at a larger one. Distinct surfaces
/// (bottom plate, top plate, grain walls) carry independent maps.
struct FavourablePatchMap {
  enum class Sheet : std::uint8_t { bottom = 0, top = 1, walls = 2 };
  double fraction = 0;     ///< lambda, in [0, 1]
  double size = 0;         ///< m, side of a cell (> 0)
  std::uint64_t seed = 1;  ///< the run's seed
  /// Uniform [0, 1) value of cell (i, j, k) of `sheet`; the cell is favourable when it is < fraction.
  double cellValue(Sheet sheet, std::int64_t i, std::int64_t j, std::int64_t k) const;
  /// The cell holding the point (x, y, z) is favourable. Plates: cell (floor(x / size),
  /// floor(y / size), 0), z ignored. Walls: cell floor(v / size + kWallShift) on each axis v.
  bool favourableAt(Sheet sheet, double x, double y, double z) const;
  /// Fraction of a cell by which the walls' cells are shifted (2 - golden ratio: no round multiple).
  static constexpr double kWallShift = 0.3819660112501051;
};

}  // namespace mmval::particles
