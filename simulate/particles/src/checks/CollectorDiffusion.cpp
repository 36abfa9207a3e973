// Check 5b, physics-collector-diffusion: Brownian particles released uniformly over a
// band upstream of one post in its Kuwabara cell (CollectorSetup.hpp: the scene shared
// with the interception check); eta = captured fraction x band width / (2 a_f), against
// Stechkina, Kirsch & Fuchs (1969) (CollectorFlow.hpp) and the Pe^(-2/3) law, over a Pe sweep.
#include "CollectorSetup.hpp"
#include "PhysicsChecks.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <sstream>
#include <unordered_map>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"

namespace mmval::particles::checks {

std::pair<double, double> fitPowerLaw(const std::vector<double>& xs, const std::vector<double>& ys, const std::vector<double>& rel_err) {
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t i = 0; i < xs.size(); ++i) {
    const double x = std::log(xs[i]), y = std::log(ys[i]);
    const double rel = rel_err[i];
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

namespace {

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

/// Fitted exponent of eta (theory: of the theory's values, unweighted) against Pe, and its standard error.
std::pair<double, double> fitExponent(const std::vector<DiffusionPoint>& pts, bool theory) {
  std::vector<double> pe, eta, rel;
  for (const auto& p : pts) {
    pe.push_back(p.pe);
    eta.push_back(theory ? p.theory : p.eta);
    rel.push_back(theory ? 1.0 : p.se / p.eta);
  }
  return fitPowerLaw(pe, eta, rel);
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

void diffusionMetrics(Schema& s) {
  s.metric("diffusion_worst_relative_error", "1", "Largest |eta / eta_theory - 1| over the Pe sweep (Stechkina, Kirsch & Fuchs 1969 with the exact interception)");
  s.metric("diffusion_worst_z", "1", "Largest |eta - eta_theory| / binomial standard error over the sweep");
  s.metric("diffusion_pooled_ratio", "1", "Captured particles over the number the theory expects, pooled over the sweep (measured / theory, all Pe together)");
  s.metric("diffusion_pooled_ratio_std_error", "1", "Binomial standard error of diffusion_pooled_ratio");
  s.metric("diffusion_worst_relative_error_lee_liu", "1", "Largest |eta / eta_Lee-Liu - 1| over the sweep; information");
  s.metric("diffusion_exponent", "1", "Fitted exponent of eta against Pe (theory -2/3)");
  s.metric("diffusion_exponent_std_error", "1", "Standard error of the fitted exponent (binomial errors)");
  s.metric("diffusion_exponent_theory", "1", "The same fit through the theory's values at the swept Pe (the 1/Pe and R terms bend it from -2/3)");
  declareCollectorCommonMetrics(s);
}

}  // namespace

void registerCollectorDiffusion(CaseKindRegistry& registry) {
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
