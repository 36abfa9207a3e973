// Checks of the overdamped engine near the plates, against theory that owes
// nothing to the engine's own functions:
//   physics-sedimentation      height distribution of non-sticky Brownian
//                              particles between two plates against Boltzmann's
//                              exp(-(z - a) / l_s), l_s = k_B T / (Delta rho V g)
//                              (Perrin 1909): any spurious drift from the
//                              height-dependent mobility (a missing or wrong Ito
//                              term k_B T dM/dz) moves it.
//   physics-hindered-diffusion short-time diffusivity parallel and normal to a
//                              plate at fixed heights, D / D0 = 1 / lambda, against
//                              Faxen's series (parallel) and Brenner 1961 (normal),
//                              tabulated in reference-data/wall-hydrodynamics.toml.
//   physics-blocking           sedimenting spheres on a sticky plate whose deposits
//                              are not sticky: saturation coverage and deposition
//                              probability against ballistic deposition (jamming
//                              ~0.61) rather than RSA (0.547), reference-data/rsa-blocking.toml.
// The sedimentation run cannot switch the engine's Ito drift off; instead it reports
// the mean height the Fokker-Planck equation predicts without it (the check's power).
#include "PhysicsChecks.hpp"
#include "WallTheory.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <optional>
#include <random>
#include <sstream>

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

double secondsSince(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// ---------------------------------------------------------------- shared keys

void declareFluidAndParticle(Schema& s, const char* diameter, const char* density) {
  const Fluid fluid;
  declareFluid(s, {.viscosity = fluid.viscosity, .density = fluid.density, .temperature = fluid.temperature, .with_temperature = true});
  s.quantity("particles.diameter", "um", "Particle diameter").def(diameter).positive();
  s.quantity("particles.density", "g/cm3", "Particle density").def(density).positive();
  s.integer("run.seed", "Random seed (start positions, Brownian motion)").def(1).min(0);
  s.real("numerics.max_step_fraction", "Largest displacement per engine step, in radii").def(0.1).min(1e-3).max(1);
}

/// A scene with nothing sticky: plates only reflect (the engine's hard contact).
SceneConfig nonStickyScene(const Case& c) {
  SceneConfig s;
  s.fluid.viscosity = c.quantity("fluid.viscosity");
  s.fluid.density = c.quantity("fluid.density");
  s.fluid.temperature = c.quantity("fluid.temperature");
  s.particle.diameter = c.quantity("particles.diameter");
  s.particle.density = c.quantity("particles.density");
  s.brownian = true;
  s.wall_hindrance = true;
  s.faxen_curvature = false;  // no flow
  s.depth_profile = false;
  s.attachment.capture_distance = 0.0;
  s.attachment.bottom = s.attachment.top = s.attachment.grains = s.attachment.deposited = false;
  s.attachment.hamaker = 0.0;
  s.seed = static_cast<std::uint64_t>(c.integer("run.seed"));
  s.max_step_fraction = c.real("numerics.max_step_fraction");
  return s;
}

void requireParticleFits(const Case& c, double gap, double diameter, double factor) {
  if (!(gap > factor * diameter))
    throw InputError(c.where("plates.gap"), "the plates are too close for this check", fmt::format("{:.4g} um", gap * 1e6),
                     fmt::format("> {:g} particle diameters ({:.4g} um)", factor, factor * diameter * 1e6));
}

/// Particles on a square grid of pitch `pitch` at height z, centred on the origin.
std::vector<Vec3> gridAtHeight(int n, double pitch, double z, const std::function<double()>& height = {}) {
  const int side = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
  std::vector<Vec3> pos;
  pos.reserve(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const double x = (k % side - 0.5 * (side - 1)) * pitch, y = (k / side - 0.5 * (side - 1)) * pitch;
    pos.emplace_back(x, y, height ? height() : z);
  }
  return pos;
}

Bounds2 boundsFor(int n, double pitch) {
  // Room for in-plane wandering: particles that reach the bounds would count as gone.
  const double half = (0.5 * std::ceil(std::sqrt(static_cast<double>(n))) + 50.0) * pitch;
  return {-half, half, -half, half};
}

// ------------------------------------------------- 1. sedimentation equilibrium

void declareSedimentation(Schema& s) {
  declareFluidAndParticle(s, "1 um", "2.0 g/cm3");
  s.quantity("plates.gap", "um", "Distance h between the bottom (z = 0) and top (z = h) plates").def("5 um").positive();
  s.quantity("physics.gravity", "m/s2", "Gravity along -z").def("9.81 m/s2").positive();
  s.boolean("physics.wall_hindrance", "Faxen / Brenner mobilities near the plates (off: constant mobility; Boltzmann either way)").def(true);
  s.boolean("physics.ito_drift", "The Ito drift k_B T dM/dz (for checks only: false shows the wrong equilibrium the engine would reach without it)").def(true);
  s.integer("particles.count", "Non-interacting (dilute) particles, started evenly across the accessible depth").def(200).min(10).max(100000);
  s.quantity("particles.pitch", "um", "In-plane spacing of the particles (dilute: contacts must not matter)").def("50 um").positive();
  s.quantity("run.equilibration", "s", "Time discarded before sampling (several settling times across the gap)").def("30 s").nonNegative();
  s.quantity("run.duration", "s", "Physical time simulated").def("130 s").positive();
  s.quantity("run.sample_interval", "s", "Time between height snapshots (longer than the height's correlation time)").def("5 s").positive();
  s.integer("analysis.bins", "Histogram bins (equal width in the CSV; equiprobable for the chi-square test)").def(20).min(2).max(1000);
}

RunOutput runSedimentation(const Case& c, const RunContext& ctx) {
  const auto t0 = Clock::now();
  SceneConfig scene = nonStickyScene(c);
  scene.gravity = c.quantity("physics.gravity");
  scene.wall_hindrance = c.flag("physics.wall_hindrance");
  scene.ito_drift = c.flag("physics.ito_drift");
  const double h = c.quantity("plates.gap"), a = scene.particle.radius();
  requireParticleFits(c, h, scene.particle.diameter, 1.5);
  const double t_eq = c.quantity("run.equilibration"), duration = c.quantity("run.duration"), dt_s = c.quantity("run.sample_interval");
  if (!(duration > t_eq))
    throw InputError(c.where("run.duration"), "no time left to sample after the equilibration", fmt::format("{:g} s", duration),
                     fmt::format("> run.equilibration ({:g} s)", t_eq));
  const auto snapshots = static_cast<std::int64_t>(std::floor((duration - t_eq) / dt_s + 1e-9)) + 1;
  if (snapshots < 2)
    throw InputError(c.where("run.sample_interval"), "fewer than two snapshots", fmt::format("{:g} s", dt_s),
                     fmt::format("<= (run.duration - run.equilibration) = {:g} s", duration - t_eq));
  const double drho = scene.particle.density - scene.fluid.density;
  if (!(drho > 0))
    throw InputError(c.where("particles.density"), "particles must be denser than the fluid to sediment",
                     fmt::format("{:g} kg/m3", scene.particle.density), fmt::format("> fluid.density ({:g} kg/m3)", scene.fluid.density));
  const double kT = kBoltzmann * scene.fluid.temperature;
  const Barometric ref{a, h - 2 * a, kT / (drho * scene.particle.volume() * scene.gravity)};  // Perrin's sedimentation length

  const int n = static_cast<int>(c.integer("particles.count"));
  const double pitch = c.quantity("particles.pitch");
  if (!(pitch > 2 * a)) throw InputError(c.where("particles.pitch"), "particles would overlap", fmt::format("{:.4g} um", pitch * 1e6), "> one diameter");
  auto flow = std::make_shared<UniformFlow>(Vec2::Zero(), h, boundsFor(n, pitch));
  OverdampedEngine engine(flow, scene);
  // Start evenly across the accessible depth (not from the answer): the run must relax to it.
  std::mt19937_64 rng(scene.seed * 7919ULL + 17ULL);
  std::uniform_real_distribution<double> start(a, h - a);
  engine.insert(gridAtHeight(n, pitch, 0.0, [&] { return start(rng); }));

  std::vector<std::vector<double>> z;
  for (std::int64_t k = 0; k < snapshots; ++k) {
    engine.advance(t_eq + k * dt_s);
    std::vector<double> snap;
    for (const auto& p : engine.particles()) {
      if (p.status != ParticleStatus::mobile)
        throw std::logic_error(fmt::format("sedimentation check: particle {} is {} on non-sticky plates", p.id, statusName(p.status)));
      snap.push_back(p.x.z());
    }
    z.push_back(std::move(snap));
  }
  const int bins = static_cast<int>(c.integer("analysis.bins"));
  const SedimentationStats st = sedimentationStats(z, ref, bins);
  writeFileAtomic(ctx.out_dir / "height_histogram.csv", st.histogram_csv);
  const double ref_mean = ref.mean(), no_ito = scene.wall_hindrance ? meanHeightWithoutItoDrift(ref, h) : ref_mean;

  RunOutput out;
  out.files = {"height_histogram.csv"};
  out.metrics["mean_height"] = st.mean;
  out.metrics["mean_height_reference"] = ref_mean;
  out.metrics["mean_height_se"] = st.se;
  out.metrics["mean_height_ratio"] = st.mean / ref_mean;
  out.metrics["mean_height_zscore"] = (st.mean - ref_mean) / st.se;
  out.metrics["mean_height_without_ito"] = no_ito;
  out.metrics["without_ito_zscore"] = (no_ito - ref_mean) / st.se;
  out.metrics["sedimentation_length"] = ref.ls;
  out.metrics["ks_statistic"] = st.ks_d;
  out.metrics["ks_p_value"] = st.ks_p;
  out.metrics["chi2"] = st.chi2;
  out.metrics["chi2_p_value"] = st.chi2_p;
  out.metrics["snapshot_correlation"] = st.lag1;
  out.metrics["samples"] = static_cast<double>(st.samples);
  out.metrics["effective_samples"] = st.n_eff;
  out.metrics["wall_time"] = secondsSince(t0);
  for (const char* k : {"mean_height", "mean_height_reference", "mean_height_se", "mean_height_without_ito", "sedimentation_length"}) out.units[k] = "um";
  out.units["wall_time"] = "s";
  const EngineStats es = engine.stats();
  out.details["engine_settings"] = engine.describe();
  out.details["steps"] = es.steps;
  out.details["dt_min_s"] = es.min_dt;
  out.details["dt_max_s"] = es.max_dt;
  out.details["snapshots"] = snapshots;
  setDetail(out.details, DetailField::reference, {
      {"description", "p(z) = exp(-(z - a)/l_s) / (l_s (1 - exp(-(h - 2a)/l_s))) on [a, h - a] (Boltzmann; Perrin 1909)"},
      {"l_s_um", ref.ls * 1e6},
      {"mean_height_um", ref_mean * 1e6},
      {"area_fraction", n * kPi * a * a / std::pow(2 * (flow->bounds().x1), 2)},
      {"without_ito", "mean height of p ~ lambda_perp(z) exp(-(z - a)/l_s), the Ito stationary density with the drift k_B T dM/dz left out"}});
  return out;
}

void sedimentationMetrics(Schema& s) {
  s.metric("mean_height", "um", "Mean centre height of the particles over the sampled snapshots");
  s.metric("mean_height_reference", "um", "Mean centre height of Boltzmann's truncated exponential on [a, h - a]");
  s.metric("mean_height_se", "um", "Standard error of mean_height (spread of the independent particles' time averages)");
  s.metric("mean_height_ratio", "1", "mean_height / mean_height_reference");
  s.metric("mean_height_zscore", "1", "(mean_height - mean_height_reference) / mean_height_se");
  s.metric("mean_height_without_ito", "um", "Mean height the engine would reach without the Ito drift k_B T dM/dz (Fokker-Planck, quadrature)");
  s.metric("without_ito_zscore", "1", "(mean_height_without_ito - mean_height_reference) / mean_height_se: how many standard errors the check would miss by without the drift");
  s.metric("sedimentation_length", "um", "l_s = k_B T / (Delta rho V g)");
  s.metric("ks_statistic", "1", "Kolmogorov-Smirnov distance of the pooled heights to the Boltzmann CDF");
  s.metric("ks_p_value", "1", "p-value of ks_statistic with effective_samples (Kolmogorov's distribution, Stephens' finite-n form)");
  s.metric("chi2", "1", "Chi-square of the pooled heights over analysis.bins equiprobable bins, scaled by effective_samples / samples");
  s.metric("chi2_p_value", "1", "p-value of chi2 with bins - 1 degrees of freedom");
  s.metric("snapshot_correlation", "1", "Correlation of a particle's height between consecutive snapshots (~0: the pooled samples are independent)");
  s.metric("samples", "1", "Pooled height samples (particles x snapshots)");
  s.metric("effective_samples", "1", "Independent samples they are worth, samples (1 - r) / (1 + r) with r = snapshot_correlation");
  s.metric("wall_time", "s", "Wall-clock time of the run");
}

// ------------------------------------------------- 2. hindered diffusion near a wall

void declareHinderedDiffusion(Schema& s) {
  declareFluidAndParticle(s, "1 um", "1.05 g/cm3");
  s.quantity("plates.gap", "um", "Distance h between the plates (wide: the top plate's correction stays below 0.1 %)").def("1000 um").positive();
  s.realList("release.heights", "Centre heights z / a above the bottom plate at which particles are released")
      .def(std::vector<double>{1.1276, 1.5431, 2.3524, 3.7622, 10.0677});
  s.integer("release.particles", "Particles released at each height (in batches of 2000; each gives one displacement)").def(40000).min(100).max(10000000);
  s.real("release.rms_fraction",
         "Lag time per height: the unhindered rms displacement sqrt(2 D0 tau) is this fraction of the gap z - a (short: the particle stays near its height)")
      .def(0.1)
      .min(1e-3)
      .max(1);
  s.integer("release.steps", "Engine steps per lag at least (the step is also capped by the engine's own rules)").def(10).min(1).max(10000);
}

struct Displacements {
  double var_par = 0, var_perp = 0, se_par = 0, se_perp = 0, mean_perp = 0;  ///< m2, m
  std::int64_t n = 0;
};

Displacements releaseAt(const SceneConfig& base, double h, double z, double tau, int steps, std::int64_t count) {
  constexpr int kBatch = 2000;
  const double pitch = 10 * base.particle.diameter;
  Moments par, perp;
  int batch = 0;
  for (std::int64_t done = 0; done < count; done += kBatch, ++batch) {
    const int n = static_cast<int>(std::min<std::int64_t>(kBatch, count - done));
    SceneConfig s = base;
    s.seed = base.seed * 1000003ULL + static_cast<std::uint64_t>(batch) * 7919ULL + static_cast<std::uint64_t>(std::llround(z * 1e9));
    s.max_dt = tau / steps;
    OverdampedEngine engine(std::make_shared<UniformFlow>(Vec2::Zero(), h, boundsFor(n, pitch)), s);
    const auto start = gridAtHeight(n, pitch, z);
    engine.insert(start);
    engine.advance(tau);
    const auto ps = engine.particles();
    for (int i = 0; i < n; ++i) {
      const Vec3 d = ps[i].x - start[i];
      par.add(d.x());
      par.add(d.y());
      perp.add(d.z());
    }
  }
  return {par.var(), perp.var(), par.varSe(), perp.varSe(), perp.mean(), static_cast<std::int64_t>(perp.n)};
}

std::string heightLabel(double z_over_a) { return fmt::format("{:.4g}", z_over_a); }

RunOutput runHinderedDiffusion(const Case& c, const RunContext& ctx) {
  const auto t0 = Clock::now();
  SceneConfig scene = nonStickyScene(c);
  scene.gravity = 0.0;  // pure diffusion: no settling drift across the lag
  const double h = c.quantity("plates.gap"), a = scene.particle.radius();
  requireParticleFits(c, h, scene.particle.diameter, 20);
  const auto& heights = c.reals("release.heights");
  if (heights.empty()) throw InputError(c.where("release.heights"), "no heights given", "[]", "one or more heights z / a");
  for (double r : heights)
    if (!(r > 1.0) || !(r * a < 0.5 * h))
      throw InputError(c.where("release.heights"), "a release height is outside the lower half of the gap", fmt::format("{:g}", r),
                       fmt::format("1 < z / a < {:.4g} (half the gap)", 0.5 * h / a));
  const double d0 = kBoltzmann * scene.fluid.temperature / (6 * kPi * scene.fluid.viscosity * a);  // Stokes-Einstein
  const double eps = c.real("release.rms_fraction");
  const int steps = static_cast<int>(c.integer("release.steps"));
  const auto count = c.integer("release.particles");

  RunOutput out;
  std::ostringstream csv;
  csv << "z_over_a,gap_over_a,lag_s,samples,lambda_par,lambda_par_se,lambda_perp,lambda_perp_se,mean_dz_um\n";
  nlohmann::json rows = nlohmann::json::array();
  for (double r : heights) {
    const double z = r * a, gap = z - a;
    // Lag: the unhindered rms displacement is eps times the gap. Along the path the mobility
    // changes, so Var(dz) = 2 D tau [1 + tau (D'^2 + 3 D D'') / (2 D) + ...] (Ito generator to
    // second order, with the drift D'); near the wall D ~ D0 gap / a makes the bias ~eps^2 gap / (4 a),
    // far away (D'' ~ 9 D0 a / (4 z^3)) below 0.2 % for eps = 0.1.
    const double tau = (eps * gap) * (eps * gap) / (2 * d0);
    const Displacements d = releaseAt(scene, h, z, tau, steps, count);
    // lambda = D0 / D with D = Var(dx) / (2 tau); its error from the variance's by the delta method.
    const double lp = 2 * d0 * tau / d.var_par, ln = 2 * d0 * tau / d.var_perp;
    const double lp_se = lp * d.se_par / d.var_par, ln_se = ln * d.se_perp / d.var_perp;
    const std::string label = heightLabel(r);
    out.metrics[fmt::format("lambda_par_{}", label)] = lp;
    out.metrics[fmt::format("lambda_perp_{}", label)] = ln;
    out.metrics[fmt::format("lambda_par_se_{}", label)] = lp_se;
    out.metrics[fmt::format("lambda_perp_se_{}", label)] = ln_se;
    csv << fmt::format("{:.6g},{:.6g},{:.6g},{},{:.6g},{:.3g},{:.6g},{:.3g},{:.4g}\n", r, r - 1, tau, d.n, lp, lp_se, ln, ln_se, d.mean_perp * 1e6);
    rows.push_back({{"z_over_a", r}, {"lag_s", tau}, {"samples", d.n}, {"lambda_par", lp}, {"lambda_par_se", lp_se}, {"lambda_perp", ln}, {"lambda_perp_se", ln_se}});
  }
  writeFileAtomic(ctx.out_dir / "hindered_diffusion.csv", csv.str());
  out.files = {"hindered_diffusion.csv"};
  out.metrics["wall_time"] = secondsSince(t0);
  out.units["wall_time"] = "s";
  out.details["heights"] = rows;
  out.details["d0_m2_s"] = d0;
  out.details["method"] = "lambda = 2 D0 tau / Var(displacement) over a lag tau = (rms_fraction (z - a))^2 / (2 D0); the variance removes the Ito drift's mean displacement";
  return out;
}

void hinderedDiffusionMetrics(Schema& s) {
  s.metric("lambda_par_*", "1", "Measured parallel drag factor D0 / D_par at centre height z / a = the suffix");
  s.metric("lambda_perp_*", "1", "Measured normal drag factor D0 / D_perp at centre height z / a = the suffix");
  s.metric("lambda_par_se_*", "1", "Standard error of lambda_par at that height");
  s.metric("lambda_perp_se_*", "1", "Standard error of lambda_perp at that height");
  s.metric("wall_time", "s", "Wall-clock time of the run");
}

// ------------------------------------------------- 8. blocking by non-sticky deposits

// Ballistic deposition (BD; Jullien & Meakin 1987, J. Phys. A 20:L1145; Talbot & Ricci
// 1992, Phys. Rev. Lett. 68:958): spheres fall one at a time at random positions onto a
// plane; one that lands on a deposited sphere rolls down it (steepest descent) to the
// plane or into a pocket of three deposits, and is then discarded. That is the
// Pe = v_s a / D -> infinity limit of sedimenting particles on a sticky plate whose
// deposits are not sticky (deposition.deposited = false): the engine's hard contacts
// make them roll. Here each batch of well-separated particles (a small increment of
// attempted coverage) falls in a fresh engine holding the deposits so far; particles
// left resting on deposits are discarded, as in BD. Coverage is counted in a window
// `analysis.margin` inside the domain's edges (no periodic boundaries in the plane).

void declareBlocking(Schema& s) {
  declareFluidAndParticle(s, "5 um", "1.05 g/cm3");
  s.quantity("plates.gap", "um", "Distance between the plates (the particles start 3.2 radii above the bottom)").def("50 um").positive();
  s.quantity("physics.gravity", "m/s2", "Gravity along -z (transport to the plate)").def("9.81 m/s2").positive();
  s.boolean("physics.brownian", "Brownian motion (off: the ballistic limit Pe -> infinity)").def(false);
  s.quantity("domain.size", "um", "Side of the square deposition area (particles that roll out of it are lost)").def("250 um").positive();
  s.quantity("analysis.margin", "um", "Coverage is counted this far inside the domain's edges").def("15 um").nonNegative();
  s.quantity("deposition.capture_distance", "um", "Gap to the bottom plate at which a particle attaches").def("0.05 um").positive();
  s.real("run.batch_coverage", "Attempted coverage per batch, pi a^2 x dropped particles / area (small: arrivals nearly sequential)").def(0.01).min(1e-4).max(0.1);
  s.real("run.attempted_coverage", "Attempted coverage at the end, tau = pi a^2 x all dropped particles / area").def(4.0).min(0.01).max(100);
}

/// A new deposit at x (at contact with the plate, z = a) moved apart in the plane from
/// the deposits it overlaps (the engine's hard contacts leave overlaps of ~1e-4 a; the
/// next batch's engine refuses overlapping particles). `max_overlap` records the largest
/// one. Empty when no overlap-free position is found nearby (then the deposit is dropped).
std::optional<Vec3> separated(Vec3 x, const std::vector<Vec3>& deposits, double a, double& max_overlap) {
  const auto overlaps = [&](const Vec3& p, const Vec3& o) { return (p - o).norm() < 2 * a; };
  // All overlaps at once (a particle wedged between two deposits moves out sideways).
  for (int pass = 0; pass < 200; ++pass) {
    Vec3 push = Vec3::Zero();
    bool any = false;
    for (const auto& o : deposits) {
      Vec3 r = x - o;
      r.z() = 0;
      const double d = r.norm(), overlap = 2 * a - d;
      if (overlap <= 0 || !(d > 0)) continue;
      if (pass == 0) max_overlap = std::max(max_overlap, overlap);
      push += r / d * (overlap + 1e-9 * a);  // just clear of contact, beyond round-off
      any = true;
    }
    if (!any) break;
    x += push;
  }
  // Wedged in a pocket of fixed deposits that has no room for it: not placed.
  if (std::any_of(deposits.begin(), deposits.end(), [&](const Vec3& o) { return overlaps(x, o); })) return std::nullopt;
  return x;
}

struct BlockingBatch {
  double tau = 0, coverage = 0, probability = 0;  ///< before the batch: attempted and actual coverage; deposited / dropped in the window
  std::int64_t dropped = 0, deposited = 0, rejected = 0;
};

/// The geometry of a blocking run and its stages: drop points, one batch's fall, bookkeeping.
struct BlockingRun {
  SceneConfig scene;
  std::shared_ptr<UniformFlow> flow;
  double a = 0, L = 0, margin = 0, window = 0, disk = 0, v_s = 0;
  std::vector<Vec3> deposits;
  double max_overlap = 0;  ///< largest overlap the engine's contacts left between deposits, m
  std::int64_t unplaced = 0;

  bool inWindow(const Vec3& x) const { return x.x() >= margin && x.x() < L - margin && x.y() >= margin && x.y() < L - margin; }
  double coverage() const {
    std::int64_t n = 0;
    for (const auto& x : deposits) n += inWindow(x);
    return n * disk / window;
  }
  /// Well-separated drop points 3.2 radii up: above every deposit (tops at 2a).
  std::vector<Vec3> dropPoints(int n, std::mt19937_64& rng) const {
    std::uniform_real_distribution<double> U(0.0, 1.0);
    std::vector<Vec3> drops;
    while (static_cast<int>(drops.size()) < n) {
      const Vec3 x(a + U(rng) * (L - 2 * a), a + U(rng) * (L - 2 * a), 3.2 * a);
      if (std::all_of(drops.begin(), drops.end(), [&](const Vec3& o) { return (o - x).norm() >= 4 * a; })) drops.push_back(x);
    }
    return drops;
  }
  /// A fresh engine holding the deposits lets `drops` fall until each is on the plate, gone,
  /// or at rest on deposits; returns their final states.
  std::vector<ParticleState> fall(const std::vector<Vec3>& drops, std::uint64_t seed) const {
    SceneConfig sc = scene;
    sc.seed = seed;
    OverdampedEngine engine(flow, sc);
    engine.insert(deposits);
    const auto first = static_cast<std::ptrdiff_t>(deposits.size());
    engine.insert(drops);
    std::vector<Vec3> last(drops);
    for (int k = 0; k < 200; ++k) {
      engine.advance(engine.time() + 2 * a / v_s);
      const auto ps = engine.particles();
      bool moving = false;
      for (std::size_t i = 0; i < drops.size(); ++i) {
        const auto& p = ps[first + i];
        moving = moving || (p.status == ParticleStatus::mobile && (p.x - last[i]).norm() > 1e-3 * a);
        last[i] = p.x;
      }
      if (!moving) break;
    }
    const auto ps = engine.particles();
    return {ps.begin() + first, ps.end()};
  }
  /// Keeps the attached ones (at contact with the plate, z = a), discards the ones resting on deposits (BD).
  void record(const std::vector<Vec3>& drops, const std::vector<ParticleState>& final_states, BlockingBatch& rec) {
    for (std::size_t i = 0; i < drops.size(); ++i) {
      const auto& p = final_states[i];
      const bool counted = inWindow(drops[i]);
      rec.dropped += counted;
      if (p.status == ParticleStatus::deposited) {
        if (const auto x = separated(Vec3(p.x.x(), p.x.y(), a), deposits, a, max_overlap)) {
          deposits.push_back(*x);
          rec.deposited += counted;
        } else {
          ++unplaced;
        }
      } else if (p.status == ParticleStatus::mobile) {
        rec.rejected += counted;
      }
    }
    rec.probability = rec.dropped ? static_cast<double>(rec.deposited) / rec.dropped : std::nan("");
  }
};

RunOutput runBlocking(const Case& c, const RunContext& ctx) {
  const auto t0 = Clock::now();
  BlockingRun run;
  SceneConfig& scene = run.scene;
  scene = nonStickyScene(c);
  scene.gravity = c.quantity("physics.gravity");
  scene.brownian = c.flag("physics.brownian");
  scene.attachment.capture_distance = c.quantity("deposition.capture_distance");
  scene.attachment.bottom = true;
  scene.attachment.deposited = false;
  const double a = scene.particle.radius(), h = c.quantity("plates.gap"), L = c.quantity("domain.size"), margin = c.quantity("analysis.margin");
  requireParticleFits(c, h, scene.particle.diameter, 2.5);
  if (!(L - 2 * margin > 10 * scene.particle.diameter))
    throw InputError(c.where("analysis.margin"), "the counting window is too small", fmt::format("{:.4g} um", margin * 1e6),
                     fmt::format("domain.size - 2 margin > 10 diameters ({:.4g} um)", 10 * scene.particle.diameter * 1e6));
  run.a = a;
  run.L = L;
  run.margin = margin;
  run.window = (L - 2 * margin) * (L - 2 * margin);
  run.disk = kPi * a * a;
  run.v_s = settlingSpeed(scene.fluid, scene.particle, scene.gravity);
  run.flow = std::make_shared<UniformFlow>(Vec2::Zero(), h, Bounds2{0, L, 0, L});
  const double disk = run.disk, window = run.window;
  const int per_batch = std::max(1, static_cast<int>(std::lround(c.real("run.batch_coverage") * L * L / disk)));
  const double tau_end = c.real("run.attempted_coverage");
  std::mt19937_64 rng(scene.seed * 6364136223846793005ULL + 1442695040888963407ULL);

  std::vector<BlockingBatch> batches;
  std::int64_t dropped_window = 0;
  double tau = 0;
  for (int b = 0; tau < tau_end; ++b) {
    BlockingBatch rec;
    rec.tau = tau;
    rec.coverage = run.coverage();
    const auto drops = run.dropPoints(per_batch, rng);
    run.record(drops, run.fall(drops, scene.seed * 1000003ULL + static_cast<std::uint64_t>(b)), rec);
    dropped_window += rec.dropped;
    tau = dropped_window * disk / window;
    batches.push_back(rec);
  }
  const auto& deposits = run.deposits;
  const double max_overlap = run.max_overlap;
  const std::int64_t unplaced = run.unplaced;
  const double coverage = run.coverage();

  std::ostringstream csv;
  csv << "attempted_coverage,coverage,dropped,deposited,rejected,deposition_probability\n";
  for (const auto& r : batches)
    csv << fmt::format("{:.6g},{:.6g},{},{},{},{:.6g}\n", r.tau, r.coverage, r.dropped, r.deposited, r.rejected, r.probability);
  csv << fmt::format("{:.6g},{:.6g},,,,\n", tau, coverage);
  writeFileAtomic(ctx.out_dir / "coverage.csv", csv.str());
  std::ostringstream dep;
  dep << "x_um,y_um,z_um\n";
  for (const auto& x : deposits) dep << fmt::format("{:.6g},{:.6g},{:.6g}\n", x.x() * 1e6, x.y() * 1e6, x.z() * 1e6);
  writeFileAtomic(ctx.out_dir / "deposits.csv", dep.str());

  // Deposition probability over coverage bands (pooled batches): the blocking function.
  RunOutput out;
  const auto band = [&](double lo, double hi) {
    std::int64_t n = 0, d = 0;
    for (const auto& r : batches)
      if (r.coverage >= lo && r.coverage < hi) n += r.dropped, d += r.deposited;
    return std::pair<double, std::int64_t>(n ? static_cast<double>(d) / n : std::nan(""), n);
  };
  nlohmann::json bands = nlohmann::json::array();
  for (int k = 0; k < 6; ++k) {
    const double lo = 0.1 * k, hi = lo + 0.1;
    const auto [p, n] = band(lo, hi);
    if (n == 0) continue;
    out.metrics[fmt::format("blocking_{:02d}_{:02d}", 10 * k, 10 * k + 10)] = p;
    bands.push_back({{"coverage_from", lo}, {"coverage_to", hi}, {"probability", p}, {"dropped", n}});
  }
  out.metrics["coverage"] = coverage;
  out.metrics["attempted_coverage"] = tau;
  out.metrics["max_contact_overlap"] = max_overlap / a;
  out.metrics["unplaced_deposits"] = static_cast<double>(unplaced);
  out.metrics["deposits"] = static_cast<double>(deposits.size());
  out.metrics["wall_time"] = secondsSince(t0);
  out.units["wall_time"] = "s";
  out.files = {"coverage.csv", "deposits.csv"};
  out.details["batches"] = batches.size();
  out.details["particles_per_batch"] = per_batch;
  out.details["blocking_bands"] = bands;
  out.details["peclet"] = run.v_s * a / (kBoltzmann * scene.fluid.temperature / (6 * kPi * scene.fluid.viscosity * a));
  return out;
}

void blockingMetrics(Schema& s) {
  s.metric("coverage", "1", "Final coverage pi a^2 N / area of the deposits in the counting window");
  s.metric("attempted_coverage", "1", "pi a^2 x particles dropped over the window / its area (dimensionless time)");
  s.metric("blocking_*", "1", "Deposition probability of particles dropped while the coverage was in the band (blocking_10_20: 0.1-0.2)");
  s.metric("deposits", "1", "Deposits kept over the whole domain at the end");
  s.metric("unplaced_deposits", "1", "Deposits the engine left wedged with overlaps no in-plane move removes; not kept (0 expected, a few tolerable)");
  s.metric("max_contact_overlap", "1", "Largest overlap between deposits the engine's contact resolution left, in radii (removed before the next batch)");
  s.metric("wall_time", "s", "Wall-clock time of the run");
}

}  // namespace

void registerWallChecks(CaseKindRegistry& registry) {
  CaseKind sed;
  sed.name = "physics-sedimentation";
  sed.summary = "Non-sticky Brownian particles settling between two plates: stationary height distribution against Boltzmann "
                "with the sedimentation length k_B T / (Delta rho V g)";
  sed.declare = declareSedimentation;
  sed.run = runSedimentation;
  registry.add(sed);
  registry.declareMetrics(sed.name, sedimentationMetrics);

  CaseKind hd;
  hd.name = "physics-hindered-diffusion";
  hd.summary = "Short-time diffusion of particles released at fixed heights above a plate: D_par / D0 and D_perp / D0 against "
               "Faxen and Brenner (1961)";
  hd.declare = declareHinderedDiffusion;
  hd.run = runHinderedDiffusion;
  registry.add(hd);
  registry.declareMetrics(hd.name, hinderedDiffusionMetrics);

  CaseKind bl;
  bl.name = "physics-blocking";
  bl.summary = "Sedimenting spheres on a sticky plate whose deposits are not sticky: coverage and deposition probability against "
               "ballistic deposition (jamming 0.61) and random sequential adsorption (0.547)";
  bl.declare = declareBlocking;
  bl.run = runBlocking;
  registry.add(bl);
  registry.declareMetrics(bl.name, blockingMetrics);
}

}  // namespace mmval::particles::checks
