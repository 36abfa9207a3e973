// What both particle engines share: the scene description (fluid, particles,
// forces, sticky surfaces), the particle state and counts, and the engine
// interface. An engine is told where particles are inserted and advanced to a
// time; it moves them with the flow given by a FlowField (FlowField.hpp).
#pragma once
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Error.hpp"
#include "mmval/particles/Dlvo.hpp"
#include "mmval/particles/FlowField.hpp"
#include "mmval/particles/Physics.hpp"

namespace mmval::particles {

/// How particles stick. A particle attaches (and stays) when its surface gap
/// to a sticky surface falls below `capture_distance` - a colloid-filtration
/// capture rule (Yao, Habibian & O'Melia 1971) standing in for the secondary
/// minimum / cohesion the experiment's sticky particles show. Optionally a
/// sphere-plate van der Waals attraction F = A a / (6 gap^2) (Hamaker 1937;
/// Israelachvili, Intermolecular and Surface Forces, 3rd ed., Table 13.1) pulls
/// them in from a distance; it is evaluated at gap >= capture_distance only.
struct AttachmentModel {
  /// What decides attachment of a particle that arrives within the capture distance of a
  /// sticky surface. capture: it attaches (with plate_efficiency and torque_balance on the
  /// plates). dlvo: the DLVO profile of that surface type (glass plates and grains: sphere-plate
  /// against the collector potential; deposits: sphere-sphere against the particle's own
  /// potential) decides, one draw per arrival: primary-minimum attachment with the
  /// interaction-force-boundary-layer efficiency alpha, else secondary-minimum capture with the
  /// Maxwell probability when that well is deeper than 1 kT (on a plate only if the
  /// secondary-minimum adhesion holds against the shear's torque), else it stays mobile.
  enum class Rule : std::uint8_t { capture, dlvo };
  Rule rule = Rule::capture;
  /// Chemistry of the dlvo rule: electrolyte, Hamaker constant, double-layer model, Born term;
  /// particle_potential is the particle's zeta potential and collector_potential the chip's
  /// (plates and grains). The radii are set by the engine.
  DlvoParameters chemistry;
  /// dlvo rule, glass only (plates and grains; deposits are latex and keep their own chemistry):
  /// lambda, the area fraction of favourable (barrier-free, attractive) patches on the glass, the
  /// patchwise heterogeneity model of Song, Johnson & Elimelech (1994, Environ. Sci. Technol.
  /// 28:1164). An arrival lands on a favourable patch with probability lambda and attaches in the
  /// primary minimum; otherwise the unfavourable rule above decides, so the efficiency per arrival
  /// is lambda + (1 - lambda) alpha_unfavourable (patchwiseEfficiency, Dlvo.hpp). Same draw per
  /// arrival as that rule: 0 leaves every result as without the model. An assumption: nothing in
  /// the experiment constrains it (reference-data/dlvo-materials.toml).
  double favourable_fraction = 0.0;
  /// m; dlvo rule with favourable_fraction > 0: 0 draws the patch per arrival as above; > 0 places
  /// the patches in space (FavourablePatchMap, Dlvo.hpp: cells of this side on the plates' (x, y)
  /// and in (x, y, z) at the grain walls, each favourable with probability lambda, from the seed).
  /// A particle within the capture distance of the glass (resting, rolling or translating in the
  /// secondary minimum) attaches in the primary minimum as soon as its contact point lies on a
  /// favourable cell, checked every step; an arrival on an unfavourable cell goes through the
  /// unfavourable rule with its draw unscaled.
  double patch_size = 0.0;
  double capture_distance = 0.1e-6;  ///< m; <= 0 switches attachment off
  /// m; dlvo rule: after an arrival that did not attach, the next arrival at the same surface
  /// counts only once the particle's gap to it has exceeded this distance (deposits: its centre
  /// farther than two radii plus this from every deposit). < 0: one particle radius, beyond the
  /// range of the DLVO force and the near-wall hindrance, so each arrival comes from the bulk as in
  /// the efficiency's definition (interaction-force-boundary-layer theory). <= capture_distance:
  /// leaving the capture distance is enough, the former rule, whose arrivals multiply as the step
  /// shrinks (a discretised Brownian path crosses one level ~dt^-1/2 times).
  double release_distance = -1.0;
  bool bottom = true;                ///< the chip's bottom plate (z = 0) is sticky
  bool top = false;                  ///< the top plate (z = h)
  bool grains = true;                ///< grain and side walls
  bool deposited = true;             ///< already deposited particles (ripening, bridging)
  double hamaker = 0.0;              ///< J (1e-20 typical polystyrene-water-glass); 0: no attraction
  double attraction_range = 1e-6;    ///< m; vdW is cut off beyond this gap
  /// Plates only: a particle that reaches a sticky plate attaches only if the
  /// adhesive torque about its contact's edge holds against the shear's torque
  /// (HydroModel::plateAdhesionHolds); otherwise it stays mobile and rolls on
  /// (checked again every step). Off: the capture rule above alone.
  bool torque_balance = false;
  /// Grain walls, side walls and deposits: the same torque balance for a particle held against
  /// them by its DMT contact adhesion (sphere-wall A a / (6 z0^2); sphere-sphere on a deposit
  /// A (a/2) / (6 z0^2), Derjaguin for two equal spheres), against the local shear of the fluid
  /// speed at its centre over its radius (HydroModel::surfaceAdhesionHolds); a particle the shear
  /// would roll off stays mobile and is checked again every step, so it is held where the flow is
  /// slow. Off: every contact within the capture distance holds (the capture rule).
  bool surface_torque_balance = false;
  /// Plates only: the probability that a particle arriving on a sticky plate attaches (colloid
  /// filtration theory's attachment efficiency alpha; 1: every arrival sticks). Drawn once per
  /// arrival (deterministic from the seed and the particle); a rejected particle stays mobile on
  /// the plate until it leaves the capture distance and arrives again. A calibration parameter:
  /// the experiment gives no surface chemistry to compute it from.
  double plate_efficiency = 1.0;
  /// m; contact separation z0 of the DMT adhesion F_A = A a / (6 z0^2); 0.4 nm is
  /// the convention of colloid-detachment studies (e.g. Bergendahl & Grasso 2000,
  /// Chem. Eng. Sci. 55:1523), not a measured value for this chip.
  double adhesion_separation = 0.4e-9;
  /// Pa; composite modulus K = (4/3) / ((1 - nu1^2)/E1 + (1 - nu2^2)/E2) of the
  /// contact. Default: polystyrene (E = 3.4 GPa, nu = 0.33) on glass (E = 70 GPa,
  /// nu = 0.22), handbook values: 4.84 GPa.
  double contact_modulus = 4.84e9;
};

/// Straining (overdamped engine): a particle the flow holds in a passage narrower than itself is
/// retained there. It is pinned in a step when the grain walls refuse its move (no admissible
/// position within the wall passes: walls closer than a radius on both sides) or when the walls it
/// was pushed off hold it against its drift (the in-plane drift points into the cone of two wall
/// normals: it touches two walls that close in ahead of it), and the drift beats diffusion over a
/// radius (u a / D >= 1). Pinned again and again within `anchor_fraction` radii of where it was
/// first pinned for `time`, it becomes deposited with Surface::strained: held in place, an
/// obstacle and a deposit like an attached particle (Sen & Khilar 2006, Adv. Colloid Interface Sci.
/// 119:71: straining, retention in throats smaller than the particle, next to attachment).
struct StrainingModel {
  bool enabled = true;
  /// s the particle must stay pinned before it counts as strained. 1 s: ~300 times the time to
  /// advect one radius at the chip's mean pore velocity (2.5 um at 0.74 mm/s: 3.4 ms), so a particle
  /// only delayed at a throat entrance (turned aside by the flow within a few advective times) is
  /// not counted, and < 0.1 % of a 20-minute run, so it does not change when retention happens.
  double time = 1.0;
  /// Radii the particle may wander (Brownian, contact pushes) from where it was first pinned and
  /// still count as held there; beyond it the clock starts again. 0.25 radius: the drift presses a
  /// held particle into the throat, so its Brownian excursions against it are ~D / u (0.1 nm for a
  /// 5 um sphere at 1 mm/s); a particle that moves on along a path leaves it within a step or two.
  /// The overdamped engine allows at least one step's travel (max_step_fraction radii; the contact
  /// pushes move a held particle by up to that) and reports the radius it uses as anchor_radii.
  double anchor_fraction = 0.25;
};

struct SceneConfig {
  Fluid fluid;
  ParticleMaterial particle;
  double gravity = 9.81;            ///< m/s2 along -z (the depth); 0: no settling
  bool brownian = true;             ///< overdamped engine: Brownian displacements (Stokes-Einstein)
  bool wall_hindrance = true;       ///< Faxen / Brenner corrections from the two plates
  /// Overdamped engine: the Ito drift k_B T dM/dz of the position-dependent mobility. Off only for
  /// checks that show what leaving it out does (sedimentation equilibrium is then wrong).
  bool ito_drift = true;
  bool faxen_curvature = true;      ///< Faxen's a^2/6 lap(u) term of the depth profile
  /// Overdamped engine: a free sphere near a plate lags the wall shear of the depth profile
  /// (Goldman, Cox & Brenner 1967; HydroModel::shearLag). false: it moves with the fluid at its centre.
  bool near_wall_shear = true;
  /// Parallel drag near the plates of a sphere free to rotate: Goldman-Cox-Brenner lubrication
  /// joined to Faxen's series (Physics.hpp, freeSphereParallel). false: Faxen's series alone.
  bool near_contact_drag = true;
  /// The in-plane velocity follows the parabolic Hele-Shaw profile across the depth (a chip).
  /// false: plane flow, the same velocity at every height (checks against plane-flow theory,
  /// e.g. collectors in Stokes flow); Faxen's curvature term is then zero.
  bool depth_profile = true;
  AttachmentModel attachment;
  StrainingModel straining;
  double outlet_x = std::numeric_limits<double>::quiet_NaN();  ///< m; NaN: the field's x1
  /// Overdamped engine: the field's bounds y0 and y1 are mirror planes (MicromodelFlow with slip
  /// sides, whose field holds the mirrored pore space beyond them): a particle whose centre crosses
  /// one is reflected back across it (y -> 2 y0 - y), never deposited or counted left there.
  /// Particles do not see the mirror images of other particles.
  bool mirror_sides = false;
  std::uint64_t seed = 1;
  /// Overdamped engine: largest displacement per step, as a fraction of the radius.
  double max_step_fraction = 0.1;
  /// Overdamped engine: threads of the per-particle loops of a step (numerics.threads); 0: auto
  /// (the hardware's cores, 2 to 8). The results are bit for bit those of one thread.
  int threads = 1;
  double max_dt = std::numeric_limits<double>::infinity();  ///< s
  /// Overdamped engine: the most steps of its own a particle takes within one engine step
  /// (numerics.substeps, a power of 2). 1: every particle takes the engine's step, set by the
  /// fastest; K > 1: the engine's step is up to K times that, and a particle whose own limit is
  /// shorter takes up to K steps of its own within it (OverdampedEngine, "Substeps").
  int substeps = 1;
  /// Overdamped engine: the drift's part of a step (numerics.drift_integrator). false: Euler, v(x) dt;
  /// true: Heun's predictor-corrector, (v(x) + v(x + v(x) dt)) dt / 2, second order along curved
  /// streamlines; the Brownian displacement is the same draw at x either way.
  bool heun_drift = false;
  /// LIGGGHTS engine: DEM step as a fraction of the Rayleigh time (<= 0.2 usual).
  double rayleigh_fraction = 0.1;
  /// LIGGGHTS engine: sjkr cohesion energy density, J/m3 (0: off).
  double cohesion_energy_density = 0.0;
  /// LIGGGHTS engine: log and screen files go here (created).
  std::filesystem::path work_dir = std::filesystem::temp_directory_path() / "mmval-liggghts";
};

/// An InputLocation naming only a key (engine-level errors have no file).
inline InputLocation keyLocation(std::string key) {
  InputLocation l;
  l.key = std::move(key);
  return l;
}

enum class ParticleStatus : std::uint8_t { mobile = 0, deposited = 1, left = 2 };
/// The surface a deposited particle is held by (none while mobile or gone; solid: swallowed by a
/// cell that deposits closed; strained: held by the flow in a passage narrower than itself,
/// StrainingModel).
enum class Surface : std::uint8_t { none = 0, bottom = 1, top = 2, grain = 3, deposit = 4, solid = 5, strained = 6 };
inline const char* surfaceName(Surface s) {
  switch (s) {
    case Surface::bottom: return "bottom plate";
    case Surface::top: return "top plate";
    case Surface::grain: return "grains";
    case Surface::deposit: return "deposits";
    case Surface::solid: return "closed cells";
    case Surface::strained: return "strained";
    default: return "none";
  }
}
const char* statusName(ParticleStatus s);

struct ParticleState {
  std::int64_t id = 0;  ///< 1-based, in insertion order
  Vec3 x = Vec3::Zero();  ///< m
  Vec3 v = Vec3::Zero();  ///< m/s (last step's mean velocity for the overdamped engine)
  ParticleStatus status = ParticleStatus::mobile;
  double t_event = std::numeric_limits<double>::quiet_NaN();  ///< s: time it deposited or left
  std::uint32_t plate_arrivals = 0;  ///< arrivals on a sticky plate drawn against plate_efficiency
  bool plate_rejected = false;       ///< its last plate arrival did not attach; cleared when it leaves the plate
  /// dlvo rule: arrivals drawn (all surfaces) and a bit per Surface whose last arrival did not
  /// attach (cleared when the particle's gap to that surface exceeds AttachmentModel::release_distance).
  std::uint32_t arrivals = 0;
  std::uint8_t rejected = 0;
  Surface held_by = Surface::none;   ///< set when it deposits; dlvo rule: also the surface a mobile particle translates along in its secondary minimum
  bool secondary = false;            ///< dlvo rule: in the secondary minimum (deposited: held there; mobile: translating along held_by in the well)
  /// Straining: time (s) the particle was first pinned near `pin_anchor` (NaN: not pinned).
  double pinned_since = std::numeric_limits<double>::quiet_NaN();
  Vec3 pin_anchor = Vec3::Zero();    ///< m, where it was first pinned (x, y used)
};

/// Particle bookkeeping; injected == inside + deposited + left always holds. deposited counts
/// every retained particle: attached (to plates, grains, deposits, closed cells) and strained;
/// strained is the part of it held by Surface::strained.
struct Counts {
  std::int64_t injected = 0, inside = 0, deposited = 0, left = 0;
  std::int64_t strained = 0;
  std::int64_t attached() const { return deposited - strained; }
  bool balanced() const { return injected == inside + deposited + left; }
};

struct EngineStats {
  std::int64_t steps = 0;
  std::int64_t particle_steps = 0;
  double last_dt = 0.0;   ///< s
  double min_dt = std::numeric_limits<double>::infinity(), max_dt = 0.0;
  double wall_seconds = 0.0;
};

class ParticleEngine {
 public:
  virtual ~ParticleEngine() = default;
  virtual std::string name() const = 0;
  /// Adds particles at rest at `positions` (m). Throws InputError (key
  /// "particles.insert") if one is in solid, outside the depth, or overlaps a
  /// wall or another particle; nothing is inserted then.
  virtual void insert(const std::vector<Vec3>& positions) = 0;
  /// Advances to time `t_end` (s) >= time().
  virtual void advance(double t_end) = 0;
  virtual double time() const = 0;
  /// Every particle ever inserted, in id order.
  virtual std::vector<ParticleState> particles() const = 0;
  virtual Counts counts() const = 0;
  virtual EngineStats stats() const = 0;
  /// Scene and numerical settings (for result.json).
  virtual nlohmann::json describe() const = 0;
  /// The version of the third-party engine behind this one, as the engine
  /// itself reports it (for the run's provenance); "" for mmval's own engines.
  virtual std::string engineVersion() const { return ""; }
};

/// Counts of a particle list.
Counts countParticles(const std::vector<ParticleState>& ps);

/// Why a position cannot take a particle ("" when it can): solid, outside
/// [a, h - a], closer than a radius to a wall, overlapping one of `others`.
std::string insertionProblem(const FlowField& flow, double radius, const Vec3& x, const std::vector<ParticleState>& others);

/// Samples `n` insertion positions as if carried in through x = x_in during the
/// last interval: z weighted by the flux profile, y uniform over the fluid, and
/// x in [x_in + a, x_in + a + strip u(z) / u_max] (strip: the centre-line travel
/// of one interval), so the number density is uniform across the depth.
/// Overlaps are rejected. Deterministic for a given seed.
/// Throws InputError (key "particles") when the strip cannot take them.
std::vector<Vec3> sampleInlet(const FlowField& flow, double radius, double x_in, double strip, int n, std::uint64_t seed,
                              const std::vector<ParticleState>& others);

}  // namespace mmval::particles
