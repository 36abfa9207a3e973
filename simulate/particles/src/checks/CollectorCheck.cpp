// Single-collector efficiency of a post array against fibre-filtration theory
// (check 5). The overdamped engine moves particles through one post in
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
// This file: the shared set-up (CollectorSetup.hpp) and the interception kind;
// the diffusion kind is in CollectorDiffusion.cpp.
#include "CollectorSetup.hpp"
#include "PhysicsChecks.hpp"

#include "../CaseScene.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <sstream>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/simulate/FlowSolver.hpp"

namespace mmval::particles::checks {

void declareCollectorKeys(Schema& s) {
  s.quantity("collector.radius", "um", "Post radius a_f").def("50 um").positive();
  s.real("collector.solid_fraction", "Solid fraction phi of the post array; the Kuwabara cell radius is a_f / sqrt(phi)").def(0.1).min(0.01).max(0.5);
  declareFluid(s, {.with_density = false, .with_temperature = true});
  s.quantity("deposition.capture_distance", "um",
             "Gap to the post at which a particle sticks; the capture radius is the particle radius plus this gap (R = capture radius / a_f)")
      .def("0.01 um")
      .positive();
  s.integer("run.seed", "Random seed (release positions, Brownian motion)").def(1).min(0);
  declareDriftIntegrator(s);
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
  s.heun_drift = heunDriftFromCase(c);
  return s;
}

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
  cfg.heun_drift = s.heun_drift;
  return cfg;
}

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

std::int64_t runUntilDone(OverdampedEngine& engine, double chunk, double t_max) {
  while (engine.time() < t_max) {
    engine.advance(std::min(engine.time() + chunk, t_max));
    if (engine.counts().inside == 0) return 0;
  }
  return engine.counts().inside;
}

void declareCollectorCommonMetrics(Schema& s) {
  s.metric("cell_flux_error", "1", "Flux of the implemented velocity across x = 0 from the post to the cell boundary over U b, minus 1 (stream-function check)");
  s.metric("unfinished", "1", "Particles still moving when their run's time limit came (counted as not captured)");
  s.metric("wall_time", "s", "Wall-clock time of the sweep");
}

void checkCaptureRadius(const Case& c, const char* key, const CollectorSetup& s, double capture_radius) {
  if (capture_radius >= 0.5 * s.cellRadius() - s.post_radius)
    throw InputError(c.where(key), "the capture radius reaches half-way to the Kuwabara cell boundary, where the cell model no longer describes the flow",
                     fmt::format("capture radius {:.4g} um", capture_radius * 1e6),
                     fmt::format("< {:.4g} um for a_f = {:.4g} um and phi = {:g}", (0.5 * s.cellRadius() - s.post_radius) * 1e6, s.post_radius * 1e6, s.phi));
}

namespace {

constexpr const char* kInterceptionKind = "physics-collector-interception";

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

void interceptionMetrics(Schema& s) {
  s.metric("interception_worst_relative_error", "1", "Largest |eta / eta_Kuwabara - 1| over the R sweep (exact Kuwabara interception)");
  s.metric("interception_worst_relative_error_lee_liu", "1", "Largest |eta / eta_Lee-Liu - 1| (small-R form (1 - phi)/Ku R^2/(1 + R)); information");
  s.metric("square_array_over_kuwabara_min", "1", "Smallest eta in the solved square array over the Kuwabara interception (collector.square_array)");
  s.metric("square_array_over_kuwabara_max", "1", "Largest eta in the solved square array over the Kuwabara interception (collector.square_array)");
  declareCollectorCommonMetrics(s);
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

  registerCollectorDiffusion(registry);
}

}  // namespace mmval::particles::checks
