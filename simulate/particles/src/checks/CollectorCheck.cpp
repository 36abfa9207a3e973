// Single-collector efficiency of a post array against fibre-filtration theory
// (issue 24, check 5). The overdamped engine moves particles through one post in
// its Kuwabara cell (CollectorFlow.hpp: the analytic plane Stokes flow the theory
// is written for) and the post is the only sticky surface:
//   physics-collector-interception  Brownian motion off: particles follow the
//       streamlines, and the efficiency is the upstream offset of the grazing
//       trajectory over a_f, found by a multi-section search over starting
//       offsets; against the exact Kuwabara interception f(1 + R).
//   physics-collector-diffusion     Brownian motion on: particles released
//       uniformly over a band upstream; eta = captured fraction x band width /
//       (2 a_f); against Stechkina, Kirsch & Fuchs (1969) and the Pe^(-2/3) law.
// The scene: plane flow (no Hele-Shaw depth profile), gravity off, no plate
// hindrance and plates not sticky, so the slab's depth plays no part: the z
// coordinate only keeps particles apart. Hindrance by the post itself is left
// out, as in the theory (particles move with the fluid at their centre).
#include "PhysicsChecks.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <sstream>
#include <unordered_map>

#include <fmt/format.h>

#include "CollectorFlow.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
#include "mmval/simulate/FlowSolver.hpp"

namespace mmval::particles::checks {

namespace {

constexpr const char* kInterceptionKind = "physics-collector-interception";
constexpr const char* kDiffusionKind = "physics-collector-diffusion";

/// Band half-width margin in standard deviations of the lateral diffusion upstream:
/// particles starting further out than this reach the post with probability < 1e-4.
constexpr double kBandSigmas = 4.0;
/// Released particles are this far apart on average (in radii), so that contacts between
/// them are rare and the dilute-suspension theory applies.
constexpr double kSpacingRadii = 20.0;
/// Depth of the release region along the flow, in cell radii (the longer, the more lateral spread).
constexpr double kReleaseDepth = 0.3;
/// The diffusion runs' outlet, in post radii downstream of the post's centre.
constexpr double kOutletRadii = 2.0;
/// Particles per engine in the diffusion runs (contacts cost per particle grows with the batch).
constexpr std::int64_t kBatchParticles = 1000;

struct CollectorSetup {
  double post_radius = 0, phi = 0, viscosity = 0, temperature = 0, capture_distance = 0, max_step_fraction = 0;
  std::uint64_t seed = 1;
  double cellRadius() const { return post_radius / std::sqrt(phi); }
};

void declareCollectorKeys(Schema& s) {
  s.quantity("collector.radius", "um", "Post radius a_f").def("50 um").positive();
  s.real("collector.solid_fraction", "Solid fraction phi of the post array; the Kuwabara cell radius is a_f / sqrt(phi)").def(0.1).min(0.01).max(0.5);
  s.quantity("fluid.viscosity", "Pa s", "Dynamic viscosity").def("1e-3 Pa s").positive();
  s.quantity("fluid.temperature", "K", "Temperature (Brownian motion)").def("293.15 K").positive();
  s.quantity("deposition.capture_distance", "um",
             "Gap to the post at which a particle sticks; the capture radius is the particle radius plus this gap (R = capture radius / a_f)")
      .def("0.01 um")
      .positive();
  s.integer("run.seed", "Random seed (release positions, Brownian motion)").def(1).min(0);
}

CollectorSetup setupFromCase(const Case& c) {
  CollectorSetup s;
  s.post_radius = c.quantity("collector.radius");
  s.phi = c.real("collector.solid_fraction");
  s.viscosity = c.quantity("fluid.viscosity");
  s.temperature = c.quantity("fluid.temperature");
  s.capture_distance = c.quantity("deposition.capture_distance");
  s.max_step_fraction = c.real("numerics.max_step_fraction");
  s.seed = static_cast<std::uint64_t>(c.integer("run.seed"));
  return s;
}

/// The scene every collector run uses: plane flow, no gravity, no plate hindrance,
/// only the post sticky (deposited particles are not: no ripening).
SceneConfig collectorScene(const CollectorSetup& s, double particle_radius, bool brownian, double outlet_x, std::uint64_t seed) {
  SceneConfig cfg;
  cfg.fluid.viscosity = s.viscosity;
  cfg.fluid.temperature = s.temperature;
  cfg.particle.diameter = 2 * particle_radius;
  cfg.particle.density = cfg.fluid.density;  // neutrally buoyant (gravity is off anyway)
  cfg.gravity = 0.0;
  cfg.brownian = brownian;
  cfg.wall_hindrance = false;
  cfg.faxen_curvature = false;
  cfg.depth_profile = false;
  cfg.attachment.capture_distance = s.capture_distance;
  cfg.attachment.bottom = false;
  cfg.attachment.top = false;
  cfg.attachment.grains = true;
  cfg.attachment.deposited = false;
  cfg.attachment.hamaker = 0.0;
  cfg.outlet_x = outlet_x;
  cfg.seed = seed;
  cfg.max_step_fraction = s.max_step_fraction;
  return cfg;
}

/// Flux through the line x = 0 from the post to the cell boundary over U b: 1 by the
/// stream function's boundary values (psi = 0 on the post, U b at the cell boundary).
/// Simpson's rule on the implemented velocity; its deviation from 1 checks the field.
double cellFluxRatio(const KuwabaraCell& flow, double a_f, double u) {
  // The upper end stops a hair inside the cell: the tangential velocity jumps at its boundary.
  const double b = flow.cellRadius(), top = b * (1 - 1e-12);
  const int n = 2000;
  const double h = (top - a_f) / n;
  double sum = 0;
  for (int i = 0; i <= n; ++i) {
    const double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
    sum += w * flow.meanVelocity(0.0, a_f + i * h).x();
  }
  return sum * h / 3.0 / (u * b);
}

/// Advances until no particle is mobile or `t_max` passes, in `chunk` steps. Returns the mobile count left.
std::int64_t runUntilDone(OverdampedEngine& engine, double chunk, double t_max) {
  while (engine.time() < t_max) {
    engine.advance(std::min(engine.time() + chunk, t_max));
    if (engine.counts().inside == 0) return 0;
  }
  return engine.counts().inside;
}

void checkCaptureRadius(const Case& c, const char* key, const CollectorSetup& s, double capture_radius) {
  if (capture_radius >= 0.5 * s.cellRadius() - s.post_radius)
    throw InputError(c.where(key), "the capture radius reaches half-way to the Kuwabara cell boundary, where the cell model no longer describes the flow",
                     fmt::format("capture radius {:.4g} um", capture_radius * 1e6),
                     fmt::format("< {:.4g} um for a_f = {:.4g} um and phi = {:g}", (0.5 * s.cellRadius() - s.post_radius) * 1e6, s.post_radius * 1e6, s.phi));
}

/// Solves plane Stokes flow through the square array of posts at the case's solid fraction on an
/// n x n grid and scales it to face velocity u. `info` receives the solve's numbers.
std::shared_ptr<const SquareArrayCell> solveSquareArray(const CollectorSetup& s, int n, double u, double depth, nlohmann::json& info) {
  const double L = s.post_radius * std::sqrt(kPi / s.phi);
  const auto t0 = std::chrono::steady_clock::now();
  simulate::SteadyFlowSolver solver(simulate::squareArrayProblem(L, n, s.phi, s.viscosity, 1.0));
  try {
    solver.solve();
  } catch (const simulate::FlowFailure& e) {
    throw e.withKey("numerics.array_cells");
  }
  const double us = solver.superficialVelocity();
  info = {{"period_um", L * 1e6},
          {"cells", n},
          {"cells_per_post_diameter", 2 * s.post_radius / (L / n)},
          {"max_relative_divergence", solver.maxRelativeDivergence()},
          {"solve_seconds", std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()},
          {"permeability_over_L2", us * s.viscosity / 1.0 / (L * L)}};
  const Bounds2 box{-1.5 * L, 1.5 * L, -0.5 * L, 0.5 * L};
  return std::make_shared<SquareArrayCell>(solver.u() * (u / us), solver.v() * (u / us), n, L, s.post_radius, depth, box);
}

// ---- interception ------------------------------------------------------------------------------

void declareInterception(Schema& s) {
  declareCollectorKeys(s);
  s.realList("sweep.interception", "Particle radius over post radius a_p / a_f, one search per value").def(std::vector<double>{0.02, 0.05, 0.1, 0.2}).min(1e-3).max(0.5);
  s.quantity("collector.face_velocity", "mm/s", "Face (superficial) velocity U; without Brownian motion the efficiency does not depend on it").def("0.1 mm/s").positive();
  s.integer("search.particles", "Particles per round of the search for the grazing streamline (spread evenly over the bracket)").def(16).min(2).max(1000);
  s.integer("search.rounds", "Rounds of the search; each narrows the bracket by particles + 1").def(4).min(1).max(10);
  s.real("numerics.max_step_fraction", "Largest displacement per step, in particle radii").def(0.1).min(1e-3).max(1);
  s.boolean("collector.square_array",
            "Also search in the plane Stokes flow through a square array of posts at the same solid fraction, solved by mmval's fluid "
            "solver (periodic cell): how much a real array differs from the Kuwabara cell")
      .def(false);
  s.integer("numerics.array_cells", "Grid cells along the square array's period (collector.square_array)").def(192).min(32).max(2048);
}

/// Where the search releases particles and what their release offset means.
struct SearchField {
  std::shared_ptr<const FlowField> flow;
  double x_in = 0, outlet = 0;  ///< release line x, m; particles past the outlet have missed
  double y_miss = 0;            ///< a release offset sure to miss the post, m
  double depth_spacing = 0;     ///< z spacing of the particles of one round, m
  /// Flux between y = 0 and y across the release line over the face velocity, m.
  std::function<double(double)> flux;
};

struct SearchResult {
  double lo = 0, hi = 0;  ///< bracket of the grazing release offset, m
  int non_monotone = 0;   ///< captures above a miss (Euler steps on curved streamlines)
  std::int64_t particle_steps = 0, unfinished = 0;
};

/// Multi-section search for the release offset of the trajectory that grazes the post:
/// each round releases `per_round` particles evenly over the bracket (at separate heights,
/// so that they never touch) and keeps the interval between the last capture and the first miss.
SearchResult searchGrazing(const CollectorSetup& s, double a_p, double u, const SearchField& f, int per_round, int rounds) {
  SearchResult res;
  res.hi = f.y_miss;
  const double t_pass = (f.outlet - f.x_in) / u;
  for (int round = 0; round < rounds; ++round) {
    OverdampedEngine engine(f.flow, collectorScene(s, a_p, false, f.outlet, s.seed));
    std::vector<Vec3> pos;
    std::vector<double> y0;
    for (int k = 0; k < per_round; ++k) {
      y0.push_back(res.lo + (res.hi - res.lo) * (k + 1) / (per_round + 1));
      pos.emplace_back(f.x_in, y0.back(), f.depth_spacing * (k + 1));
    }
    // The first round also releases one particle at the upper end, which must miss.
    if (round == 0) pos.emplace_back(f.x_in, res.hi, f.depth_spacing * (per_round + 1));
    engine.insert(pos);
    // Grazing particles creep round the post at ~2 (1 - phi)/Ku R U: allow 200 passes.
    res.unfinished += runUntilDone(engine, t_pass, 200 * t_pass);
    res.particle_steps += engine.stats().particle_steps;
    const auto ps = engine.particles();
    if (round == 0 && ps[per_round].status == ParticleStatus::deposited)
      throw std::logic_error(fmt::format("collector search: the particle released at the upper offset {:.4g} um was captured", res.hi * 1e6));
    int first_miss = per_round;
    for (int k = 0; k < per_round; ++k)
      if (ps[k].status != ParticleStatus::deposited) {
        first_miss = k;
        break;
      }
    for (int k = first_miss + 1; k < per_round; ++k)
      if (ps[k].status == ParticleStatus::deposited) ++res.non_monotone;
    const double lo = first_miss == 0 ? res.lo : y0[first_miss - 1];
    const double hi = first_miss == per_round ? res.hi : y0[first_miss];
    res.lo = lo;
    res.hi = hi;
  }
  return res;
}

struct InterceptionPoint {
  double r = 0, r_capture = 0, eta = 0, eta_uncertainty = 0, theory = 0, lee_liu = 0;
  double eta_array = std::numeric_limits<double>::quiet_NaN(), eta_array_uncertainty = std::numeric_limits<double>::quiet_NaN();
  int non_monotone = 0;
  std::int64_t particle_steps = 0, unfinished = 0;
  void add(const SearchResult& r) {
    non_monotone += r.non_monotone;
    particle_steps += r.particle_steps;
    unfinished += r.unfinished;
  }
};

/// One post in its Kuwabara cell: released upstream of the cell, where the flow is uniform
/// (flux = U y); the grazing streamline starts at a_f f(1 + R) < (1 + R) a_f.
SearchField kuwabaraSearch(const CollectorSetup& s, double a_p, double r_capture, double u, int per_round) {
  SearchField f;
  const double a_f = s.post_radius, b = s.cellRadius();
  f.x_in = -b - 2 * a_p;
  f.outlet = b + 2 * a_p;
  f.y_miss = (1 + r_capture) * a_f;
  f.depth_spacing = 6 * a_p;
  const Bounds2 box{f.x_in - a_f, f.outlet + a_f, -(b + a_f), b + a_f};
  f.flow = std::make_shared<KuwabaraCell>(a_f, s.phi, u, f.depth_spacing * (per_round + 3), box);
  f.flux = [](double y) { return y; };
  return f;
}

/// One period of the solved square array: released on the period's upstream edge; the flux
/// is the field's own u_x integrated along that line (Simpson's rule), over U.
SearchField arraySearch(const std::shared_ptr<const SquareArrayCell>& cell, double a_p, double r_capture, double u) {
  SearchField f;
  const double a_f = cell->postRadius(), half = 0.5 * cell->period();
  f.x_in = -half;
  f.outlet = half;
  f.y_miss = std::min((1 + r_capture) * a_f, half - a_p);
  f.depth_spacing = 6 * a_p;
  f.flow = cell;
  f.flux = [cell, u, x = f.x_in](double y) {
    const int n = 400;
    const double h = y / n;
    double sum = 0;
    for (int i = 0; i <= n; ++i) sum += ((i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0)) * cell->meanVelocity(x, i * h).x();
    return sum * h / 3.0 / u;
  };
  return f;
}

InterceptionPoint interceptionAt(const CollectorSetup& s, double r, double u, int per_round, int rounds,
                                 const std::shared_ptr<const SquareArrayCell>& array) {
  InterceptionPoint p;
  const double a_f = s.post_radius, a_p = r * a_f;
  p.r = r;
  p.r_capture = (a_p + s.capture_distance) / a_f;
  p.theory = interceptionKuwabara(s.phi, p.r_capture);
  p.lee_liu = interceptionLeeLiu(s.phi, p.r_capture);
  const SearchField kf = kuwabaraSearch(s, a_p, p.r_capture, u, per_round);
  const SearchResult k = searchGrazing(s, a_p, u, kf, per_round, rounds);
  p.add(k);
  p.eta = 0.5 * (kf.flux(k.lo) + kf.flux(k.hi)) / a_f;  // both sides over 2 a_f
  p.eta_uncertainty = 0.5 * (kf.flux(k.hi) - kf.flux(k.lo)) / a_f;
  if (array) {
    const SearchField af = arraySearch(array, a_p, p.r_capture, u);
    const SearchResult q = searchGrazing(s, a_p, u, af, per_round, rounds);
    p.add(q);
    p.eta_array = 0.5 * (af.flux(q.lo) + af.flux(q.hi)) / a_f;
    p.eta_array_uncertainty = 0.5 * (af.flux(q.hi) - af.flux(q.lo)) / a_f;
  }
  return p;
}

RunOutput runInterception(const Case& c, const RunContext& ctx) {
  const CollectorSetup s = setupFromCase(c);
  const auto& ratios = c.reals("sweep.interception");
  if (ratios.empty()) throw InputError(c.where("sweep.interception"), "no interception parameters to run", "[]", "a list such as [0.02, 0.05, 0.1, 0.2]");
  for (const double r : ratios) checkCaptureRadius(c, "sweep.interception", s, r * s.post_radius + s.capture_distance);
  const double u = c.quantity("collector.face_velocity");
  const int per_round = static_cast<int>(c.integer("search.particles")), rounds = static_cast<int>(c.integer("search.rounds"));
  const auto t0 = std::chrono::steady_clock::now();
  RunOutput out;
  std::shared_ptr<const SquareArrayCell> array;
  if (c.flag("collector.square_array")) {
    const double r_max = *std::max_element(ratios.begin(), ratios.end());
    nlohmann::json info;
    array = solveSquareArray(s, static_cast<int>(c.integer("numerics.array_cells")), u, 6 * r_max * s.post_radius * (per_round + 3), info);
    out.details["square_array"] = info;
  }
  std::ostringstream csv;
  csv << "R,R_capture,eta_measured,eta_uncertainty,eta_theory_kuwabara,eta_theory_lee_liu,relative_error,eta_square_array,eta_square_array_uncertainty,"
         "non_monotone_captures,unfinished\n";
  nlohmann::json rows = nlohmann::json::array();
  double worst = 0, worst_lee_liu = 0, array_min = std::numeric_limits<double>::infinity(), array_max = -array_min;
  std::int64_t steps = 0, unfinished = 0;
  for (const double r : ratios) {
    const InterceptionPoint p = interceptionAt(s, r, u, per_round, rounds, array);
    const double err = p.eta / p.theory - 1;
    worst = std::max(worst, std::abs(err));
    worst_lee_liu = std::max(worst_lee_liu, std::abs(p.eta / p.lee_liu - 1));
    if (array) {
      array_min = std::min(array_min, p.eta_array / p.theory);
      array_max = std::max(array_max, p.eta_array / p.theory);
    }
    steps += p.particle_steps;
    unfinished += p.unfinished;
    csv << fmt::format("{:.6g},{:.6g},{:.6g},{:.3g},{:.6g},{:.6g},{:.4g},{:.6g},{:.3g},{},{}\n", p.r, p.r_capture, p.eta, p.eta_uncertainty, p.theory, p.lee_liu,
                       err, p.eta_array, p.eta_array_uncertainty, p.non_monotone, p.unfinished);
    nlohmann::json row = {{"R", p.r}, {"R_capture", p.r_capture}, {"eta", p.eta}, {"eta_uncertainty", p.eta_uncertainty}, {"eta_kuwabara", p.theory},
                          {"eta_lee_liu", p.lee_liu}, {"relative_error", err}, {"non_monotone_captures", p.non_monotone}, {"unfinished", p.unfinished}};
    if (array) {
      row["eta_square_array"] = p.eta_array;
      row["eta_square_array_uncertainty"] = p.eta_array_uncertainty;
    }
    rows.push_back(row);
  }
  writeFileAtomic(ctx.out_dir / "collector-interception.csv", csv.str());
  const KuwabaraCell probe(s.post_radius, s.phi, u, 1.0, {-1, 1, -1, 1});
  out.files = {"collector-interception.csv"};
  out.metrics["interception_worst_relative_error"] = worst;
  out.metrics["interception_worst_relative_error_lee_liu"] = worst_lee_liu;
  if (array) {
    out.metrics["square_array_over_kuwabara_min"] = array_min;
    out.metrics["square_array_over_kuwabara_max"] = array_max;
  }
  out.metrics["cell_flux_error"] = cellFluxRatio(probe, s.post_radius, u) - 1;
  out.metrics["unfinished"] = static_cast<double>(unfinished);
  out.metrics["wall_time"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.units["wall_time"] = "s";
  out.details["points"] = rows;
  out.details["particle_steps"] = steps;
  out.details["kuwabara_factor"] = kuwabaraFactor(s.phi);
  out.details["cell_radius_um"] = s.cellRadius() * 1e6;
  out.details["definitions"] = {
      {"R", "particle radius / post radius; R_capture = (particle radius + capture distance) / post radius, the R of the theory"},
      {"eta", "flux between the front stagnation streamline and the grazing trajectory's release offset, both sides, over U 2 a_f"},
      {"eta_uncertainty", "half the flux across the search's final bracket"},
      {"eta_kuwabara", "exact interception in Kuwabara flow, f(1 + R) of the stream function (Stechkina, Kirsch & Fuchs 1969)"},
      {"eta_lee_liu", "(1 - phi)/Ku R^2/(1 + R) (Lee & Liu 1982), the small-R form; shown, not judged"},
      {"eta_square_array", "the same search in the square array's flow solved by mmval's fluid solver at the same phi (NaN when off): "
                           "how much a real array differs from the cell model; shown, not judged"}};
  return out;
}

// ---- diffusion ---------------------------------------------------------------------------------

void declareDiffusion(Schema& s) {
  declareCollectorKeys(s);
  s.quantity("particles.diameter", "um", "Particle diameter (sets the diffusivity, Stokes-Einstein, and the interception R)").def("1 um").positive();
  s.realList("sweep.peclet", "Peclet numbers 2 a_f U / D, one run each; the face velocity is U = Pe D / (2 a_f)").def(std::vector<double>{200, 600, 2000}).min(10).max(1e5);
  s.integer("particles.count", "Particles released per Peclet number").def(6000).min(100).max(10000000);
  s.real("numerics.max_step_fraction", "Largest displacement per step (flow, and Brownian rms), in particle radii").def(1.0).min(1e-3).max(1);
}

struct DiffusionPoint {
  double pe = 0, u = 0, eta = 0, se = 0, theory = 0, eta_d = 0, eta_dr = 0, eta_r = 0, lee_liu = 0;
  double band = 0, outermost_capture = 0;  ///< band half-width (m); largest |y0| of a captured particle / band
  std::int64_t released = 0, captured = 0, unfinished = 0, particle_steps = 0;
};

/// Release positions: uniform over x in [x0, x1], y in [-w, w], z in [a, h - a], no two closer than 2.2 a.
std::vector<Vec3> releasePositions(std::int64_t n, double x0, double x1, double w, double h, double a, std::uint64_t seed) {
  std::mt19937_64 gen(seed);
  const auto unit = [&] { return static_cast<double>(gen() >> 11) * 0x1.0p-53; };
  const double cell = 2.2 * a;
  std::unordered_map<std::int64_t, std::vector<int>> grid;
  const auto key = [&](std::int64_t i, std::int64_t j, std::int64_t k) { return (i * 73856093) ^ (j * 19349663) ^ (k * 83492791); };
  std::vector<Vec3> pos;
  pos.reserve(static_cast<std::size_t>(n));
  while (static_cast<std::int64_t>(pos.size()) < n) {
    const Vec3 p(x0 + (x1 - x0) * unit(), -w + 2 * w * unit(), 1.01 * a + (h - 2.02 * a) * unit());
    const auto i = static_cast<std::int64_t>(std::floor(p.x() / cell)), j = static_cast<std::int64_t>(std::floor(p.y() / cell)),
               k = static_cast<std::int64_t>(std::floor(p.z() / cell));
    bool free = true;
    for (std::int64_t di = -1; di <= 1 && free; ++di)
      for (std::int64_t dj = -1; dj <= 1 && free; ++dj)
        for (std::int64_t dk = -1; dk <= 1 && free; ++dk)
          if (const auto it = grid.find(key(i + di, j + dj, k + dk)); it != grid.end())
            for (const int q : it->second)
              if ((pos[q] - p).norm() < cell) free = false;
    if (!free) continue;
    grid[key(i, j, k)].push_back(static_cast<int>(pos.size()));
    pos.push_back(p);
  }
  return pos;
}

DiffusionPoint diffusionAt(const CollectorSetup& s, double a_p, double pe, std::int64_t n, std::uint64_t seed) {
  DiffusionPoint p;
  const double a_f = s.post_radius, b = s.cellRadius();
  const double diffusivity = kBoltzmann * s.temperature / (6 * kPi * s.viscosity * a_p);  // Stokes-Einstein
  const double r_capture = (a_p + s.capture_distance) / a_f;
  p.pe = pe;
  p.u = pe * diffusivity / (2 * a_f);
  p.eta_d = diffusionStechkina(s.phi, pe);
  p.eta_dr = interactionStechkina(s.phi, pe, r_capture);
  p.eta_r = interceptionKuwabara(s.phi, r_capture);
  p.theory = p.eta_d + p.eta_dr + p.eta_r;  // additive, as Stechkina, Kirsch & Fuchs (1969) combine them
  p.lee_liu = diffusionLeeLiu(s.phi, pe) + interceptionLeeLiu(s.phi, r_capture);
  // Release over x in [x1 - kReleaseDepth b, x1] upstream of the cell, where the flow is uniform
  // (a uniform concentration there is a uniform flux across any line x = const); the band must
  // hold every particle that can reach the post: the captured streamlines (~eta a_f) plus the
  // lateral diffusion on the way. Particles past x = kOutletRadii a_f have left the post's
  // boundary layer (Pe >> 1: none diffuses back against the flow) and count as escaped.
  const double x1 = -b - 2 * a_p, x0 = x1 - kReleaseDepth * b, outlet = kOutletRadii * a_f;
  const double sigma = std::sqrt(2 * diffusivity * (x1 - x0 + b) / p.u);
  p.band = 1.5 * p.theory * a_f + kBandSigmas * sigma;
  // The engine hashes particles by (x, y) column for contacts, so a batch's cost per step grows with
  // the particles per column: the particles run in independent batches (seeds from the batch).
  const std::int64_t batch = std::min<std::int64_t>(n, kBatchParticles);
  const double spacing = kSpacingRadii * a_p;
  const double depth = std::max(20 * a_p, static_cast<double>(batch) * spacing * spacing * spacing / ((x1 - x0) * 2 * p.band));
  const Bounds2 box{x0 - a_f - 10 * sigma, outlet + a_f, -(p.band + b + 10 * sigma), p.band + b + 10 * sigma};
  auto flow = std::make_shared<KuwabaraCell>(a_f, s.phi, p.u, depth, box);
  const double t_pass = (outlet - x0) / p.u;
  for (std::int64_t done = 0, k = 0; done < n; done += batch, ++k) {
    const std::uint64_t bseed = seed * 1000003ULL + static_cast<std::uint64_t>(k);
    OverdampedEngine engine(flow, collectorScene(s, a_p, true, outlet, bseed));
    const auto pos = releasePositions(std::min(batch, n - done), x0, x1, p.band, depth, a_p, bseed * 7919 + 17);
    engine.insert(pos);
    p.unfinished += runUntilDone(engine, 0.1 * t_pass, 6 * t_pass);
    const auto ps = engine.particles();
    for (std::size_t q = 0; q < ps.size(); ++q)
      if (ps[q].status == ParticleStatus::deposited) {
        ++p.captured;
        p.outermost_capture = std::max(p.outermost_capture, std::abs(pos[q].y()) / p.band);
      }
    p.particle_steps += engine.stats().particle_steps;
  }
  p.released = n;
  const double f = static_cast<double>(p.captured) / static_cast<double>(n);
  p.eta = f * p.band / a_f;  // captured flux / (U 2 a_f), released flux U 2 w
  p.se = std::sqrt(std::max(f * (1 - f), 1.0 / static_cast<double>(n)) / static_cast<double>(n)) * p.band / a_f;  // binomial
  return p;
}

/// Weighted least-squares slope of ln(eta) against ln(Pe) (weights 1 / var(ln eta)), and its standard error.
std::pair<double, double> fitExponent(const std::vector<DiffusionPoint>& pts, bool theory) {
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (const auto& p : pts) {
    const double x = std::log(p.pe), y = std::log(theory ? p.theory : p.eta);
    const double rel = theory ? 1.0 : p.se / p.eta;
    const double w = 1 / (rel * rel);
    sw += w;
    sx += w * x;
    sy += w * y;
    sxx += w * x * x;
    sxy += w * x * y;
  }
  const double det = sw * sxx - sx * sx;
  return {(sw * sxy - sx * sy) / det, std::sqrt(sw / det)};
}

RunOutput runDiffusion(const Case& c, const RunContext& ctx) {
  const CollectorSetup s = setupFromCase(c);
  const double a_p = 0.5 * c.quantity("particles.diameter");
  checkCaptureRadius(c, "particles.diameter", s, a_p + s.capture_distance);
  const auto& pes = c.reals("sweep.peclet");
  if (pes.size() < 2) throw InputError(c.where("sweep.peclet"), "the exponent fit needs at least two Peclet numbers", fmt::format("{} value(s)", pes.size()), "a list such as [200, 600, 2000]");
  const auto n = c.integer("particles.count");
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<DiffusionPoint> pts;
  for (std::size_t i = 0; i < pes.size(); ++i) pts.push_back(diffusionAt(s, a_p, pes[i], n, s.seed * 1000 + i));
  std::ostringstream csv;
  csv << "Pe,face_velocity_um_s,released,captured,eta_measured,eta_std_error,eta_theory,eta_D,eta_DR,eta_R,eta_theory_lee_liu,relative_error,"
         "band_half_width_um,outermost_capture_over_band,unfinished\n";
  nlohmann::json rows = nlohmann::json::array();
  double worst = 0, worst_z = 0, worst_lee_liu = 0;
  double captured = 0, expected = 0, variance = 0;  // pooled over the sweep
  std::int64_t steps = 0, unfinished = 0;
  for (const auto& p : pts) {
    const double err = p.eta / p.theory - 1;
    worst = std::max(worst, std::abs(err));
    worst_z = std::max(worst_z, std::abs(p.eta - p.theory) / p.se);
    // Counts the theory expects from this band: eta_theory = expected / released x band / a_f.
    captured += static_cast<double>(p.captured);
    expected += p.theory * s.post_radius / p.band * static_cast<double>(p.released);
    variance += static_cast<double>(p.captured) * (1 - static_cast<double>(p.captured) / static_cast<double>(p.released));
    worst_lee_liu = std::max(worst_lee_liu, std::abs(p.eta / p.lee_liu - 1));
    steps += p.particle_steps;
    unfinished += p.unfinished;
    csv << fmt::format("{:g},{:.6g},{},{},{:.6g},{:.3g},{:.6g},{:.6g},{:.6g},{:.6g},{:.6g},{:.4g},{:.6g},{:.4g},{}\n", p.pe, p.u * 1e6, p.released, p.captured, p.eta,
                       p.se, p.theory, p.eta_d, p.eta_dr, p.eta_r, p.lee_liu, err, p.band * 1e6, p.outermost_capture, p.unfinished);
    rows.push_back({{"Pe", p.pe}, {"face_velocity_m_s", p.u}, {"released", p.released}, {"captured", p.captured}, {"eta", p.eta}, {"eta_std_error", p.se},
                    {"eta_theory", p.theory}, {"eta_D", p.eta_d}, {"eta_DR", p.eta_dr}, {"eta_R", p.eta_r}, {"eta_lee_liu", p.lee_liu},
                    {"relative_error", err}, {"band_half_width_m", p.band}, {"outermost_capture_over_band", p.outermost_capture}, {"unfinished", p.unfinished}});
  }
  writeFileAtomic(ctx.out_dir / "collector-diffusion.csv", csv.str());
  const auto [slope, slope_se] = fitExponent(pts, false);
  const double slope_theory = fitExponent(pts, true).first;
  const KuwabaraCell probe(s.post_radius, s.phi, 1.0, 1.0, {-1, 1, -1, 1});
  RunOutput out;
  out.files = {"collector-diffusion.csv"};
  out.metrics["diffusion_worst_relative_error"] = worst;
  out.metrics["diffusion_worst_z"] = worst_z;
  out.metrics["diffusion_pooled_ratio"] = captured / expected;
  out.metrics["diffusion_pooled_ratio_std_error"] = std::sqrt(variance) / expected;
  out.metrics["diffusion_worst_relative_error_lee_liu"] = worst_lee_liu;
  out.metrics["diffusion_exponent"] = slope;
  out.metrics["diffusion_exponent_std_error"] = slope_se;
  out.metrics["diffusion_exponent_theory"] = slope_theory;
  out.metrics["cell_flux_error"] = cellFluxRatio(probe, s.post_radius, 1.0) - 1;
  out.metrics["unfinished"] = static_cast<double>(unfinished);
  out.metrics["wall_time"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.units["wall_time"] = "s";
  out.details["points"] = rows;
  out.details["particle_steps"] = steps;
  out.details["kuwabara_factor"] = kuwabaraFactor(s.phi);
  out.details["cell_radius_um"] = s.cellRadius() * 1e6;
  out.details["interception_parameter"] = (a_p + s.capture_distance) / s.post_radius;
  out.details["definitions"] = {
      {"Pe", "2 a_f U / D, U the face (superficial) velocity, D = k_B T / (6 pi mu a_p)"},
      {"eta", "captured / released x band half-width / a_f: captured flux / (U 2 a_f)"},
      {"eta_theory", "eta_D + eta_DR + eta_R: Stechkina & Fuchs 2.9 Ku^(-1/3) Pe^(-2/3) + 0.624/Pe, the interaction 1.24 Ku^(-1/2) Pe^(-1/2) R^(2/3), "
                     "and the exact Kuwabara interception (Stechkina, Kirsch & Fuchs 1969)"},
      {"eta_lee_liu", "2.6 ((1 - phi)/Ku)^(1/3) Pe^(-2/3) + (1 - phi)/Ku R^2/(1 + R) (Lee & Liu 1982); shown, not judged"},
      {"diffusion_exponent", "weighted least-squares slope of ln eta against ln Pe (boundary-layer theory: -2/3)"}};
  return out;
}

void interceptionMetrics(Schema& s) {
  s.metric("interception_worst_relative_error", "1", "Largest |eta / eta_Kuwabara - 1| over the R sweep (exact Kuwabara interception)");
  s.metric("interception_worst_relative_error_lee_liu", "1", "Largest |eta / eta_Lee-Liu - 1| (small-R form (1 - phi)/Ku R^2/(1 + R)); information");
  s.metric("square_array_over_kuwabara_min", "1", "Smallest eta in the solved square array over the Kuwabara interception (collector.square_array)");
  s.metric("square_array_over_kuwabara_max", "1", "Largest eta in the solved square array over the Kuwabara interception (collector.square_array)");
  s.metric("cell_flux_error", "1", "Flux of the implemented velocity across x = 0 from the post to the cell boundary over U b, minus 1 (stream-function check)");
  s.metric("unfinished", "1", "Particles still moving when their run's time limit came (counted as not captured)");
  s.metric("wall_time", "s", "Wall-clock time of the sweep");
}

void diffusionMetrics(Schema& s) {
  s.metric("diffusion_worst_relative_error", "1", "Largest |eta / eta_theory - 1| over the Pe sweep (Stechkina, Kirsch & Fuchs 1969 with the exact interception)");
  s.metric("diffusion_worst_z", "1", "Largest |eta - eta_theory| / binomial standard error over the sweep");
  s.metric("diffusion_pooled_ratio", "1", "Captured particles over the number the theory expects, pooled over the sweep (measured / theory, all Pe together)");
  s.metric("diffusion_pooled_ratio_std_error", "1", "Binomial standard error of diffusion_pooled_ratio");
  s.metric("diffusion_worst_relative_error_lee_liu", "1", "Largest |eta / eta_Lee-Liu - 1| over the sweep; information");
  s.metric("diffusion_exponent", "1", "Fitted exponent of eta against Pe (theory -2/3)");
  s.metric("diffusion_exponent_std_error", "1", "Standard error of the fitted exponent (binomial errors)");
  s.metric("diffusion_exponent_theory", "1", "The same fit through the theory's values at the swept Pe (the 1/Pe and R terms bend it from -2/3)");
  s.metric("cell_flux_error", "1", "Flux of the implemented velocity across x = 0 from the post to the cell boundary over U b, minus 1 (stream-function check)");
  s.metric("unfinished", "1", "Particles still moving when their run's time limit came (counted as not captured)");
  s.metric("wall_time", "s", "Wall-clock time of the sweep");
}

}  // namespace

void registerCollectorChecks(CaseKindRegistry& registry) {
  CaseKind interception;
  interception.name = kInterceptionKind;
  interception.summary = "Interception by one post in its Kuwabara cell (plane Stokes flow, Brownian motion off): single-collector efficiency "
                         "over an R sweep against the exact Kuwabara interception; writes collector-interception.csv";
  interception.declare = declareInterception;
  interception.run = runInterception;
  registry.add(interception);
  registry.declareMetrics(kInterceptionKind, interceptionMetrics);

  CaseKind diffusion;
  diffusion.name = kDiffusionKind;
  diffusion.summary = "Brownian capture by one post in its Kuwabara cell (plane Stokes flow): single-collector efficiency over a Pe sweep "
                      "against Stechkina-Fuchs and the Pe^(-2/3) law; writes collector-diffusion.csv";
  diffusion.declare = declareDiffusion;
  diffusion.run = runDiffusion;
  registry.add(diffusion);
  registry.declareMetrics(kDiffusionKind, diffusionMetrics);
}

}  // namespace mmval::particles::checks
