// Checks of the overdamped engine's deposition on the plates of a slit (plane
// Poiseuille flow between two parallel plates, no side walls), against theory:
//   physics-settling-slit    non-Brownian particles settling at the Stokes speed
//                            onto the bottom plate: deposited fraction against
//                            channel length, (a) with wall hindrance and Faxen's
//                            term off against the closed-form trajectory result
//                            (the point-particle L v_s / (h U)), (b) with the
//                            engine's full model against a quadrature of the
//                            engine's own deterministic velocity (a check of the
//                            stepping and of the capture, not of the model).
//   physics-diffusion-slit   Brownian particles, no gravity, both plates perfect
//                            sinks: penetration against channel length against
//                            the Graetz series for plane Poiseuille flow between
//                            absorbing plates (computed here from its
//                            eigenproblem) and its Leveque limit.
// Particles enter at x = 0, flux-weighted across the depth; they are placed at
// the quantiles (i + 1/2) / N of the entering particle flux (stratified), each
// in its own lane across the (unbounded) width, so that they never touch. The
// deposition position of every particle is recorded along one long slit, and
// the curve at several lengths is read off those positions.
#include "PhysicsChecks.hpp"
#include "SlitTheory.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <sstream>
#include <vector>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles::checks {

namespace {

using Clock = std::chrono::steady_clock;
constexpr double kInf = std::numeric_limits<double>::infinity();

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// The engine's deterministic velocity of a particle centred at height z (the references' input).
DriftAt driftOf(const OverdampedEngine& e) {
  return [&e](double z) { return e.driftVelocity(Vec3(0, 0, z)); };
}

// ------------------------------------------------------------------ the slit

/// Plane Poiseuille flow of depth h and mean speed U along +x, plates sticky as
/// asked, nothing else: the engine's UniformFlow with its parabolic depth profile.
/// The slit starts `upstream` before the inlet x = 0 (Brownian particles may step
/// back) and ends at the outlet x = length.
struct Slit {
  double h = 0, U = 0, length = 0, upstream = 0;
  std::shared_ptr<const FlowField> flow;
};

Slit makeSlit(double h, double U, double length, double upstream) {
  Slit s{h, U, length, upstream, nullptr};
  s.flow = std::make_shared<UniformFlow>(Vec2(U, 0.0), h, Bounds2{-upstream, length, -1.0, 1.0});
  return s;
}

void declareSlitAndParticles(Schema& s, const char* depth, const char* speed, const char* diameter, std::int64_t count, const char* capture) {
  const Fluid fluid;
  s.quantity("slit.depth", "um", "Gap h between the plates (bottom z = 0, top z = h)").def(depth).positive();
  s.quantity("slit.mean_velocity", "mm/s", "Depth-averaged flow speed U (plane Poiseuille profile 6 U z (h - z) / h^2)").def(speed).positive();
  declareFluid(s, {.viscosity = fluid.viscosity, .density = fluid.density, .temperature = fluid.temperature, .with_temperature = true});
  s.quantity("particles.diameter", "um", "Particle diameter").def(diameter).positive();
  s.integer("particles.count", "Particles entering the slit, one per flux quantile").def(count).min(10).max(100000);
  s.quantity("deposition.capture_distance", "um", "Surface gap at which a particle attaches to a sticky plate").def(capture).positive();
}

SceneConfig slitScene(const Case& c) {
  SceneConfig s;
  s.fluid.viscosity = c.quantity("fluid.viscosity");
  s.fluid.density = c.quantity("fluid.density");
  s.fluid.temperature = c.quantity("fluid.temperature");
  s.particle.diameter = c.quantity("particles.diameter");
  s.depth_profile = true;
  s.attachment.capture_distance = c.quantity("deposition.capture_distance");
  s.attachment.grains = false;     // there are no grains or side walls
  s.attachment.deposited = false;  // particles travel in lanes ten diameters apart or more: no ripening
  s.attachment.hamaker = 0.0;
  s.max_step_fraction = c.real("numerics.max_step_fraction");
  return s;
}

void requireFits(const Case& c, double h, double d, double cd) {
  if (!(h > 2 * d + 2 * cd))
    throw InputError(c.where("particles.diameter"), "particles do not fit in the slit with room to settle",
                     fmt::format("{:.4g} um (depth {:.4g} um, capture distance {:.4g} um)", d * 1e6, h * 1e6, cd * 1e6),
                     "a diameter below half the depth minus the capture distance");
}

/// Stratified flux-weighted entry: particle i at the flux quantile (i + 1/2) / N,
/// at x = 0, in lane y = (i - N/2) * lane.
std::vector<Vec3> entryPositions(const EntryFlux& flux, int n, double lane) {
  std::vector<Vec3> out;
  out.reserve(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) out.emplace_back(0.0, (i - 0.5 * n) * lane, flux.quantile((i + 0.5) / n));
  return out;
}

struct Outcome {
  std::vector<double> x_dep;  ///< deposition x per particle (+inf: left through the outlet, NaN: still moving)
  std::int64_t deposited = 0, left = 0, undecided = 0;
  double engine_seconds = 0;
  EngineStats stats;
};

/// Advances in chunks of `chunk` until no particle moves or `t_max` is reached.
Outcome runToEnd(OverdampedEngine& e, double chunk, double t_max) {
  double t = 0;
  while (e.counts().inside > 0 && t < t_max) {
    t = std::min(t + chunk, t_max);
    e.advance(t);
  }
  Outcome o;
  for (const auto& p : e.particles()) {
    if (p.status == ParticleStatus::deposited) {
      o.x_dep.push_back(p.x.x());
      ++o.deposited;
    } else if (p.status == ParticleStatus::left) {
      o.x_dep.push_back(kInf);
      ++o.left;
    } else {
      o.x_dep.push_back(std::numeric_limits<double>::quiet_NaN());
      ++o.undecided;
    }
  }
  o.stats = e.stats();
  o.engine_seconds = o.stats.wall_seconds;
  return o;
}

/// Fraction of particles deposited at x <= L.
double depositedWithin(const Outcome& o, double L) {
  const auto n = std::count_if(o.x_dep.begin(), o.x_dep.end(), [&](double x) { return x <= L; });
  return static_cast<double>(n) / static_cast<double>(o.x_dep.size());
}

// ====================================================== check 3: settling

// Settling of a non-Brownian particle: the deposited fraction against the closed
// form (3) of the trajectory integral (1) and its quadrature (SlitTheory.hpp).

/// The closed form's assumptions: the centre follows the undisturbed flow and
/// settles at the free Stokes speed everywhere (no wall hindrance, no Faxen term,
/// no Goldman-Cox-Brenner lag or near-contact drag). The switches of the last two
/// are optional members of SceneConfig, tested the way HydroModel tests them.
template <class Config>
void pointParticleHydrodynamics(Config& c) {
  c.wall_hindrance = false;
  c.faxen_curvature = false;
  c.near_wall_shear = false;
  c.near_contact_drag = false;
}

void declareSettling(Schema& s) {
  declareSlitAndParticles(s, "20 um", "0.72 mm/s", "5 um", 100, "0.1 um");
  s.quantity("slit.length", "mm", "Slit length (outlet); the curve is read at analysis.points lengths in (0, length]").def("45 mm").positive();
  s.quantity("particles.density", "g/cm3", "Particle density (polystyrene 1.05)").def("1.05 g/cm3").positive();
  s.quantity("physics.gravity", "m/s2", "Gravity along -z").def("9.81 m/s2").positive();
  s.integer("analysis.points", "Lengths at which the deposited fraction is compared").def(50).min(2).max(10000);
  s.real("numerics.max_step_fraction", "Largest displacement per engine step, in radii").def(0.5).min(1e-4).max(1);
}

void settlingMetrics(Schema& s) {
  s.metric("point_fraction_max_error", "1", "Hindrance and Faxen off: max over lengths of |deposited fraction - closed form (3)|");
  s.metric("point_position_max_error", "1", "Hindrance and Faxen off: max |deposition x - closed-form X(z0)| over deposited particles, over h U / v_s");
  s.metric("full_fraction_max_error", "1", "Full model: max over lengths of |deposited fraction - quadrature of the engine's drift|");
  s.metric("full_position_max_error", "1", "Full model: max |deposition x - quadrature X(z0)| over deposited particles, over h U / v_s");
  s.metric("quadrature_closed_form_difference", "1", "Max over lengths of |quadrature reference - closed form (3)| for the point run (self-check of the quadrature)");
  s.metric("finite_size_shift", "1", "Max over lengths of |closed form (3) - min(1, L v_s / (h U))|: what finite size and capture distance change");
  s.metric("full_model_shift", "1", "Max over lengths of |full-model reference - closed form (3)|: what Faxen's term and hindered settling change");
  s.metric("point_deposited", "1", "Hindrance and Faxen off: particles deposited within the slit");
  s.metric("full_deposited", "1", "Full model: particles deposited within the slit");
  s.metric("undecided", "1", "Particles still moving when the runs stopped (both runs)");
  s.metric("settling_speed", "um/s", "Stokes settling speed v_s");
  s.metric("wall_time", "s", "Wall-clock time of the run");
}

struct SettlingRun {
  Outcome outcome;
  std::vector<double> z0, x_ref;  ///< entry height and reference deposition distance per particle
  double position_error = 0;      ///< max |x - x_ref| over deposited particles, m
};

SettlingRun runSettlingModel(const SceneConfig& scene, const Slit& slit, int n, bool closed_form) {
  auto engine = std::make_unique<OverdampedEngine>(slit.flow, scene);
  const double a = scene.particle.radius(), cd = scene.attachment.capture_distance;
  const double vs = settlingSpeed(scene.fluid, scene.particle, scene.gravity);
  const EntryFlux flux(driftOf(*engine), a, slit.h);
  SettlingRun r;
  const auto pos = entryPositions(flux, n, 10 * scene.particle.diameter);
  engine->insert(pos);
  const double scale = slit.h * slit.U / vs;
  for (const auto& p : pos) {
    r.z0.push_back(p.z());
    r.x_ref.push_back(closed_form ? scale * std::max(0.0, cubicF(p.z() / slit.h) - cubicF((a + cd) / slit.h))
                                  : trajectoryDistance(driftOf(*engine), p.z(), a, cd, scale));
  }
  // Slowest particle: from the top to the capture height, hindered near both plates;
  // 20 free-settling times across the depth is a generous cap.
  const double t_settle = slit.h / vs;
  r.outcome = runToEnd(*engine, t_settle, 20 * t_settle);
  for (std::size_t i = 0; i < r.x_ref.size(); ++i)
    if (std::isfinite(r.outcome.x_dep[i])) r.position_error = std::max(r.position_error, std::abs(r.outcome.x_dep[i] - r.x_ref[i]));
  return r;
}

/// The base scene of both settling runs, from the case: no Brownian motion, only the
/// bottom plate sticky; InputError when particles do not fit or would not settle.
SceneConfig settlingScene(const Case& c, double h) {
  SceneConfig base = slitScene(c);
  base.particle.density = c.quantity("particles.density");
  base.gravity = c.quantity("physics.gravity");
  base.brownian = false;
  base.attachment.bottom = true;
  base.attachment.top = false;  // only the bottom plate collects settling particles
  requireFits(c, h, base.particle.diameter, base.attachment.capture_distance);
  if (!(base.particle.density > base.fluid.density))
    throw InputError(c.where("particles.density"), "particles must be heavier than the fluid to settle",
                     fmt::format("{:g} kg/m3", base.particle.density), fmt::format("> fluid density {:g} kg/m3", base.fluid.density));
  return base;
}

/// Measured and reference curves at `points` lengths in (0, slit length], their largest
/// differences, and the curve as CSV.
struct SettlingCurves {
  double e_point = 0, e_full = 0, e_quad = 0, shift_size = 0, shift_model = 0;
  std::string csv;
};

SettlingCurves compareSettlingCurves(const SettlingRun& rp, const SettlingRun& rf, const SceneConfig& point, const SceneConfig& full,
                                     const Slit& slit, int points) {
  const double h = slit.h, U = slit.U, a = point.particle.radius(), cd = point.attachment.capture_distance;
  const double vs = settlingSpeed(point.fluid, point.particle, point.gravity), scale = h * U / vs;
  // The references need engines only for their drift.
  const OverdampedEngine point_drift(slit.flow, point), full_drift(slit.flow, full);
  const EntryFlux point_flux(driftOf(point_drift), a, h), full_flux(driftOf(full_drift), a, h);
  SettlingCurves r;
  std::ostringstream csv;
  csv << "length_mm,fraction_point,fraction_point_reference,fraction_point_quadrature,fraction_point_limit,fraction_full,"
         "fraction_full_reference\n";
  for (int k = 1; k <= points; ++k) {
    const double L = slit.length * k / points;
    const double fp = depositedWithin(rp.outcome, L), ff = depositedWithin(rf.outcome, L);
    const double fp_ref = pointFraction(L, h, U, vs, a, cd);
    const double fp_quad = trajectoryFraction(driftOf(point_drift), point_flux, L, a, cd, h, scale);
    const double f_limit = std::min(1.0, L / scale);  // (2), point particles
    const double ff_ref = trajectoryFraction(driftOf(full_drift), full_flux, L, a, cd, h, scale);
    r.e_point = std::max(r.e_point, std::abs(fp - fp_ref));
    r.e_full = std::max(r.e_full, std::abs(ff - ff_ref));
    r.e_quad = std::max(r.e_quad, std::abs(fp_quad - fp_ref));
    r.shift_size = std::max(r.shift_size, std::abs(fp_ref - f_limit));
    r.shift_model = std::max(r.shift_model, std::abs(ff_ref - fp_ref));
    csv << fmt::format("{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g}\n", L * 1e3, fp, fp_ref, fp_quad, f_limit, ff, ff_ref);
  }
  r.csv = csv.str();
  return r;
}

/// One row per particle: entry height, deposition x and reference x of both runs.
std::string settlingParticlesCsv(const SettlingRun& rp, const SettlingRun& rf) {
  std::ostringstream per;
  per << "particle,entry_z_um,x_point_um,x_point_reference_um,x_full_um,x_full_reference_um\n";
  const auto um = [](double x) { return std::isfinite(x) ? fmt::format("{:.6g}", x * 1e6) : std::string(std::isnan(x) ? "moving" : "left"); };
  for (std::size_t i = 0; i < rp.z0.size(); ++i)
    per << fmt::format("{},{:.6g},{},{},{},{}\n", i + 1, rp.z0[i] * 1e6, um(rp.outcome.x_dep[i]), um(rp.x_ref[i]), um(rf.outcome.x_dep[i]),
                       um(rf.x_ref[i]));
  return per.str();
}

RunOutput runSettling(const Case& c, const RunContext& ctx) {
  const auto t0 = Clock::now();
  const double h = c.quantity("slit.depth"), U = c.quantity("slit.mean_velocity");
  const SceneConfig base = settlingScene(c, h);
  const int n = static_cast<int>(c.integer("particles.count"));
  const Slit slit = makeSlit(h, U, c.quantity("slit.length"), 2 * base.particle.diameter);
  SceneConfig point = base;
  pointParticleHydrodynamics(point);
  SceneConfig full = base;
  full.wall_hindrance = true;
  full.faxen_curvature = true;

  const SettlingRun rp = runSettlingModel(point, slit, n, true);
  const SettlingRun rf = runSettlingModel(full, slit, n, false);
  const SettlingCurves curves = compareSettlingCurves(rp, rf, point, full, slit, static_cast<int>(c.integer("analysis.points")));
  writeFileAtomic(ctx.out_dir / "settling-deposition.csv", curves.csv);
  writeFileAtomic(ctx.out_dir / "settling-particles.csv", settlingParticlesCsv(rp, rf));

  const double vs = settlingSpeed(base.fluid, base.particle, base.gravity);
  const double scale = h * U / vs;  // length over which point particles all deposit
  RunOutput out;
  out.files = {"settling-deposition.csv", "settling-particles.csv"};
  out.metrics["point_fraction_max_error"] = curves.e_point;
  out.metrics["point_position_max_error"] = rp.position_error / scale;
  out.metrics["full_fraction_max_error"] = curves.e_full;
  out.metrics["full_position_max_error"] = rf.position_error / scale;
  out.metrics["quadrature_closed_form_difference"] = curves.e_quad;
  out.metrics["finite_size_shift"] = curves.shift_size;
  out.metrics["full_model_shift"] = curves.shift_model;
  out.metrics["point_deposited"] = static_cast<double>(rp.outcome.deposited);
  out.metrics["full_deposited"] = static_cast<double>(rf.outcome.deposited);
  out.metrics["undecided"] = static_cast<double>(rp.outcome.undecided + rf.outcome.undecided);
  out.metrics["settling_speed"] = vs;
  out.units["settling_speed"] = "um/s";
  out.metrics["wall_time"] = secondsSince(t0);
  out.units["wall_time"] = "s";
  out.details["full_deposition_length_point_mm"] = scale * 1e3;
  out.details["particles"] = n;
  out.details["entry"] = "stratified: particle i at the (i + 1/2) / N quantile of the entering particle flux, x = 0, own lane";
  out.details["engine_seconds"] = {{"point", rp.outcome.engine_seconds}, {"full", rf.outcome.engine_seconds}};
  out.details["engine_steps"] = {{"point", rp.outcome.stats.steps}, {"full", rf.outcome.stats.steps}};
  out.details["engine_settings"] = {{"point", OverdampedEngine(slit.flow, point).describe()}, {"full", OverdampedEngine(slit.flow, full).describe()}};
  setDetail(out.details, DetailField::reference,
            {{"description", "point run: closed form f(L) = [F(min(s*, 1 - a/h)) - F(a/h)] / [F(1 - a/h) - F(a/h)], F(s) = 3 s^2 - 2 s^3, "
                             "F(s*) = F((a + c)/h) + L v_s / (U h) (-> L v_s / (h U) for point particles); full run: quadrature of "
                             "dx/dz = v_x / v_z of the engine's own drift (checks stepping and capture, not the model)"}});
  return out;
}

// ====================================================== check 4: diffusion

// Brownian deposition on both plates: the penetration against the Graetz series and
// its Leveque limit (SlitTheory.hpp).

void declareDiffusion(Schema& s) {
  declareSlitAndParticles(s, "20 um", "0.0125 mm/s", "0.8 um", 3000, "0.02 um");
  s.realList("analysis.mu", "Dimensionless lengths mu' = D L / (U h^2) at which the penetration is compared (ascending, > 0)")
      .def(std::vector<double>{0.005, 0.01, 0.02, 0.05, 0.1})
      .min(1e-5)
      .max(10);
  s.boolean("physics.wall_hindrance", "Brenner / Faxen hindered diffusion near the plates (off: constant D, the theory's assumption)").def(false);
  s.boolean("physics.faxen_curvature", "Faxen's a^2/6 lap(u) term (off: the theory's assumption)").def(false);
  s.real("numerics.max_step_fraction", "Largest displacement per engine step (flow or Brownian rms), in radii").def(0.5).min(1e-3).max(1);
  s.real("numerics.step_check_factor",
         "A second run with max_step_fraction times this factor (coarser) shows the time-step error; 0: no second run")
      .def(2.0)
      .min(0)
      .max(10);
  s.integer("run.seed", "Random seed (Brownian motion)").def(1).min(0);
}

void diffusionMetrics(Schema& s) {
  s.metric("penetration_max_abs_z", "1",
           "Max over the lengths of |P - P_Graetz| / standard error of P; P_Graetz for the engine's absorbing planes (centres caught at a + c)");
  s.metric("penetration_max_error", "1", "Max over the lengths of |P - P_Graetz|");
  s.metric("penetration_point_max_abs_z", "1", "Max over the lengths of |P - P_Graetz,point| / standard error: against the point-particle series");
  s.metric("finite_size_shift", "1", "Max over the lengths of |P_Graetz - P_Graetz,point|: what the centre's excluded layer and capture distance change");
  s.metric("graetz_weight_*", "1", "G_n (n = 1, 2, 3) of the point-particle Graetz penetration series, as computed here");
  s.metric("sherwood_mean", "1", "Mean Sherwood number on the hydraulic diameter 2 h over the longest length, -ln(P) / mu'");
  s.metric("sherwood_mean_reference", "1", "The same from the Graetz series");
  s.metric("sherwood_mean_z", "1", "(Sh - Sh_Graetz) / standard error of Sh at the longest length");
  s.metric("graetz_eigenvalue_*", "1", "lambda_n (n = 1, 2, 3) of the Graetz eigenproblem for plane Poiseuille flow, as computed here");
  s.metric("graetz_limiting_sherwood", "1", "(8/3) lambda_1^2: the fully developed Sherwood number on 2 h, as computed here");
  s.metric("graetz_leveque_difference", "1", "|P_Graetz - P_Leveque| at the shortest length (series against its short-length limit)");
  s.metric("step_check_max_abs_z", "1", "Max over the lengths of |P - P_coarse| / combined standard error, coarse: max_step_fraction x step_check_factor");
  s.metric("step_check_max_difference", "1", "Max over the lengths of |P - P_coarse|");
  s.metric("upstream_deposited", "1", "Particles that deposited upstream of the inlet (x < 0: axial diffusion against the flow)");
  s.metric("undecided", "1", "Particles still moving when the run stopped");
  s.metric("peclet", "1", "U h / D");
  s.metric("wall_time", "s", "Wall-clock time of the run");
}

Outcome runDiffusionOnce(const SceneConfig& scene, const Slit& slit, int n) {
  OverdampedEngine engine(slit.flow, scene);
  const EntryFlux flux(driftOf(engine), scene.particle.radius(), slit.h);
  engine.insert(entryPositions(flux, n, 10 * scene.particle.diameter));
  const double transit = slit.length / slit.U;
  return runToEnd(engine, transit, 20 * transit);
}

struct PenetrationCurve {
  std::vector<double> p, se;
};

PenetrationCurve penetrationAt(const Outcome& o, const std::vector<double>& lengths) {
  PenetrationCurve c;
  const double n = static_cast<double>(o.x_dep.size());
  for (const double L : lengths) {
    const double p = 1.0 - depositedWithin(o, L);
    c.p.push_back(p);
    // Binomial standard error; the stratified entry only lowers the true spread.
    c.se.push_back(std::sqrt(std::max(p * (1 - p), 1.0 / n) / n));
  }
  return c;
}

/// The diffusion scene from the case: Brownian, no gravity, both plates sinks;
/// InputError when particles do not fit.
SceneConfig diffusionScene(const Case& c, double h) {
  SceneConfig scene = slitScene(c);
  scene.gravity = 0.0;  // the particles' density plays no part
  scene.brownian = true;
  scene.wall_hindrance = c.flag("physics.wall_hindrance");
  scene.faxen_curvature = c.flag("physics.faxen_curvature");
  scene.attachment.bottom = scene.attachment.top = true;
  scene.seed = static_cast<std::uint64_t>(c.integer("run.seed"));
  requireFits(c, h, scene.particle.diameter, scene.attachment.capture_distance);
  return scene;
}

/// analysis.mu, checked: not empty, strictly ascending.
const std::vector<double>& dimensionlessLengths(const Case& c) {
  const std::vector<double>& mus = c.reals("analysis.mu");
  if (mus.empty()) throw InputError(c.where("analysis.mu"), "no lengths given", "[]", "at least one mu' value");
  for (std::size_t k = 1; k < mus.size(); ++k)
    if (!(mus[k] > mus[k - 1]))
      throw InputError(c.where("analysis.mu"), "lengths must be strictly ascending", fmt::format("{:g} after {:g}", mus[k], mus[k - 1]),
                       "an ascending list of mu' values");
  return mus;
}

/// The measured penetration against both series (and the coarse run when there is one)
/// at every length: the largest differences, and the curve as CSV.
struct DiffusionComparison {
  double max_z = 0, max_err = 0, point_z = 0, size_shift = 0, step_z = 0, step_diff = 0;
  std::string csv;
};

DiffusionComparison compareDiffusion(const std::vector<double>& mus, const std::vector<double>& lengths, const PenetrationCurve& pb,
                                     const PenetrationCurve* pc, const GraetzSeries& graetz, const GraetzSeries& graetz_point) {
  DiffusionComparison r;
  std::ostringstream csv;
  csv << "mu,length_um,penetration,penetration_se,penetration_graetz,penetration_graetz_point,penetration_leveque,sherwood,sherwood_se,"
         "sherwood_graetz,penetration_coarse,penetration_coarse_se\n";
  for (std::size_t k = 0; k < mus.size(); ++k) {
    const double ref = graetz.penetration(mus[k]), ref_point = graetz_point.penetration(mus[k]);
    // Mean Sherwood number on 2 h over the length: P = exp(-Sh mu') (log-mean driving force).
    const double sh = -std::log(pb.p[k]) / mus[k], sh_se = pb.se[k] / (pb.p[k] * mus[k]), sh_ref = -std::log(ref) / mus[k];
    r.max_z = std::max(r.max_z, std::abs(pb.p[k] - ref) / pb.se[k]);
    r.max_err = std::max(r.max_err, std::abs(pb.p[k] - ref));
    r.point_z = std::max(r.point_z, std::abs(pb.p[k] - ref_point) / pb.se[k]);
    r.size_shift = std::max(r.size_shift, std::abs(ref - ref_point));
    std::string coarse_cols = ",";
    if (pc != nullptr) {
      r.step_z = std::max(r.step_z, std::abs(pb.p[k] - pc->p[k]) / std::hypot(pb.se[k], pc->se[k]));
      r.step_diff = std::max(r.step_diff, std::abs(pb.p[k] - pc->p[k]));
      coarse_cols = fmt::format("{:.6g},{:.6g}", pc->p[k], pc->se[k]);
    }
    csv << fmt::format("{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{}\n", mus[k], lengths[k] * 1e6, pb.p[k], pb.se[k],
                       ref, ref_point, levequePenetration(mus[k]), sh, sh_se, sh_ref, coarse_cols);
  }
  r.csv = csv.str();
  return r;
}

RunOutput runDiffusion(const Case& c, const RunContext& ctx) {
  const auto t0 = Clock::now();
  const double h = c.quantity("slit.depth"), U = c.quantity("slit.mean_velocity");
  const SceneConfig scene = diffusionScene(c, h);
  const std::vector<double>& mus = dimensionlessLengths(c);
  const double factor = c.real("numerics.step_check_factor");
  if (factor > 0 && scene.max_step_fraction * factor > 1)
    throw InputError(c.where("numerics.step_check_factor"), "the coarse run's step would exceed the engine's limit of one radius",
                     fmt::format("{:g} x max_step_fraction {:g}", factor, scene.max_step_fraction), "max_step_fraction x factor <= 1");
  const int n = static_cast<int>(c.integer("particles.count"));
  const double d = scene.particle.diameter, a = 0.5 * d, cd = scene.attachment.capture_distance;
  const double D = stokesEinstein(scene.fluid, d);
  std::vector<double> lengths;
  for (const double m : mus) lengths.push_back(m * U * h * h / D);
  // The slit ends just past the longest length; it starts 20 depths upstream so that
  // no particle leaves against the flow (sticky plates there too: a particle that
  // diffuses back and deposits counts as deposited, and is reported).
  const Slit slit = makeSlit(h, U, lengths.back() * 1.001, 20 * h);

  const Outcome base = runDiffusionOnce(scene, slit, n);
  Outcome coarse;
  if (factor > 0) {
    SceneConfig cs = scene;
    cs.max_step_fraction *= factor;
    cs.seed = scene.seed + 7919;  // independent noise: the difference is judged against both runs' errors
    coarse = runDiffusionOnce(cs, slit, n);
  }
  // The reference for the engine's absorbing planes (centres caught at a + c), and
  // the classic point-particle series; their difference is the finite-size shift.
  const GraetzSeries graetz = graetzSeries(40, 1 - 2 * (a + cd) / h, 1 - 2 * a / h);
  const GraetzSeries graetz_point = graetzSeries(40, 1.0, 1.0);
  const PenetrationCurve pb = penetrationAt(base, lengths);
  const PenetrationCurve pc = factor > 0 ? penetrationAt(coarse, lengths) : PenetrationCurve{};
  const DiffusionComparison cmp = compareDiffusion(mus, lengths, pb, factor > 0 ? &pc : nullptr, graetz, graetz_point);
  writeFileAtomic(ctx.out_dir / "diffusion-penetration.csv", cmp.csv);

  const std::size_t last = mus.size() - 1;
  const double sh = -std::log(pb.p[last]) / mus[last], sh_ref = -std::log(graetz.penetration(mus[last])) / mus[last];
  const double sh_se = pb.se[last] / (pb.p[last] * mus[last]);
  RunOutput out;
  out.files = {"diffusion-penetration.csv"};
  out.metrics["penetration_max_abs_z"] = cmp.max_z;
  out.metrics["penetration_max_error"] = cmp.max_err;
  out.metrics["sherwood_mean"] = sh;
  out.metrics["sherwood_mean_reference"] = sh_ref;
  out.metrics["sherwood_mean_z"] = (sh - sh_ref) / sh_se;
  out.metrics["penetration_point_max_abs_z"] = cmp.point_z;
  out.metrics["finite_size_shift"] = cmp.size_shift;
  for (int m = 0; m < 3; ++m) {
    out.metrics[fmt::format("graetz_eigenvalue_{}", m + 1)] = graetz_point.lambda[m];
    out.metrics[fmt::format("graetz_weight_{}", m + 1)] = graetz_point.weight[m];
  }
  out.metrics["graetz_limiting_sherwood"] = 8.0 / 3.0 * graetz_point.lambda[0] * graetz_point.lambda[0];
  out.metrics["graetz_leveque_difference"] = std::abs(graetz_point.penetration(mus[0]) - levequePenetration(mus[0]));
  if (factor > 0) {
    out.metrics["step_check_max_abs_z"] = cmp.step_z;
    out.metrics["step_check_max_difference"] = cmp.step_diff;
  }
  const auto upstream = std::count_if(base.x_dep.begin(), base.x_dep.end(), [](double x) { return x < 0; });
  out.metrics["upstream_deposited"] = static_cast<double>(upstream);
  out.metrics["undecided"] = static_cast<double>(base.undecided + coarse.undecided);
  out.metrics["peclet"] = U * h / D;
  out.metrics["wall_time"] = secondsSince(t0);
  out.units["wall_time"] = "s";
  out.details["diffusivity_m2_s"] = D;
  out.details["radius_over_depth"] = a / h;
  out.details["particles"] = n;
  out.details["counts"] = {{"deposited", base.deposited}, {"left", base.left}, {"undecided", base.undecided}};
  out.details["engine_seconds"] = {{"base", base.engine_seconds}, {"coarse", coarse.engine_seconds}};
  out.details["engine_steps"] = {{"base", base.stats.steps}, {"coarse", coarse.stats.steps}};
  out.details["engine_settings"] = OverdampedEngine(slit.flow, scene).describe();
  out.details["graetz_modes"] = {{"lambda", graetz.lambda}, {"weight", graetz.weight}, {"entry_fraction", graetz.entry_fraction}};
  out.details["graetz_point_modes"] = {{"lambda", graetz_point.lambda}, {"weight", graetz_point.weight}};
  setDetail(out.details, DetailField::reference,
            {{"description", "Graetz series for plane Poiseuille flow between absorbing plates, P = sum G_n exp(-lambda_n^2 (8/3) mu'), "
                             "mu' = D L / (U h^2), 40 modes computed from the eigenproblem on the centres' domain (caught at a + c); "
                             "penetration_graetz_point: the same for point particles"}});
  return out;
}

}  // namespace

void registerSlitChecks(CaseKindRegistry& registry) {
  CaseKind settle;
  settle.name = "physics-settling-slit";
  settle.summary = "Settling deposition on the bottom plate of a slit in plane Poiseuille flow: deposited fraction vs length against the "
                   "closed-form trajectory result (hindrance and Faxen off) and against a quadrature of the engine's own drift (full model)";
  settle.declare = declareSettling;
  settle.run = runSettling;
  registry.add(settle);
  registry.declareMetrics(settle.name, settlingMetrics);

  CaseKind diff;
  diff.name = "physics-diffusion-slit";
  diff.summary = "Brownian deposition on both plates of a slit in plane Poiseuille flow: penetration vs dimensionless length against the "
                 "Graetz series (and its Leveque limit), with a coarser-step run for the time-step error";
  diff.declare = declareDiffusion;
  diff.run = runDiffusion;
  registry.add(diff);
  registry.declareMetrics(diff.name, diffusionMetrics);
}

}  // namespace mmval::particles::checks
