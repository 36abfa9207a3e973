#include "mmval/particles/EngineComparison.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/particles/EngineFactory.hpp"

namespace mmval::particles {

nlohmann::json EngineComparison::toJson() const {
  return {{"window_s", window_s},
          {"particles", particles},
          {"rms_position_difference_m", rms_position_difference},
          {"max_position_difference_m", max_position_difference},
          {"median_final_difference_m", median_final_difference},
          {"captured_reference", captured_reference},
          {"captured_candidate", captured_candidate},
          {"captured_both", captured_both},
          {"rms_capture_time_difference_s", rms_capture_time_difference},
          {"retained_fraction_reference", retained_fraction_reference},
          {"retained_fraction_candidate", retained_fraction_candidate},
          {"wall_seconds_reference", wall_seconds_reference},
          {"wall_seconds_candidate", wall_seconds_candidate},
          {"steps_reference", steps_reference},
          {"steps_candidate", steps_candidate}};
}

std::vector<EngineComparison> compareEngines(ParticleEngine& reference, const std::vector<ParticleEngine*>& candidates, const std::vector<Vec3>& positions,
                                             double window, double interval) {
  if (!(window > 0) || !(interval > 0) || interval > window) throw std::invalid_argument("compareEngines: need 0 < interval <= window");
  if (!reference.particles().empty()) throw std::invalid_argument("compareEngines: engines must be empty");
  for (auto* c : candidates)
    if (c == nullptr || !c->particles().empty()) throw std::invalid_argument("compareEngines: engines must be empty");
  reference.insert(positions);
  for (auto* c : candidates) c->insert(positions);
  std::vector<EngineComparison> out(candidates.size());
  std::vector<double> sum2(candidates.size(), 0.0);
  std::vector<long> n(candidates.size(), 0);
  const auto steps = static_cast<int>(std::llround(window / interval));
  for (int k = 1; k <= steps; ++k) {
    reference.advance(k * interval);
    const auto a = reference.particles();
    for (std::size_t j = 0; j < candidates.size(); ++j) {
      candidates[j]->advance(k * interval);
      const auto b = candidates[j]->particles();
      for (std::size_t i = 0; i < a.size(); ++i) {
        if (a[i].status == ParticleStatus::left || b[i].status == ParticleStatus::left) continue;
        const double d = (a[i].x - b[i].x).norm();
        sum2[j] += d * d;
        ++n[j];
        out[j].max_position_difference = std::max(out[j].max_position_difference, d);
      }
    }
  }
  const auto a = reference.particles();
  for (std::size_t j = 0; j < candidates.size(); ++j) {
    EngineComparison& r = out[j];
    const auto b = candidates[j]->particles();
    r.window_s = window;
    r.particles = static_cast<int>(positions.size());
    r.rms_position_difference = n[j] ? std::sqrt(sum2[j] / n[j]) : 0.0;
    std::vector<double> final_diff;
    for (std::size_t i = 0; i < a.size(); ++i)
      if (a[i].status != ParticleStatus::left && b[i].status != ParticleStatus::left) final_diff.push_back((a[i].x - b[i].x).norm());
    if (!final_diff.empty()) {
      std::nth_element(final_diff.begin(), final_diff.begin() + final_diff.size() / 2, final_diff.end());
      r.median_final_difference = final_diff[final_diff.size() / 2];
    }
    double dt2 = 0;
    for (std::size_t i = 0; i < a.size(); ++i) {
      const bool ca = a[i].status == ParticleStatus::deposited, cb = b[i].status == ParticleStatus::deposited;
      r.captured_reference += ca;
      r.captured_candidate += cb;
      if (ca && cb) {
        ++r.captured_both;
        dt2 += std::pow(a[i].t_event - b[i].t_event, 2);
      }
    }
    r.rms_capture_time_difference = r.captured_both ? std::sqrt(dt2 / r.captured_both) : 0.0;
    r.retained_fraction_reference = a.empty() ? 0.0 : static_cast<double>(r.captured_reference) / a.size();
    r.retained_fraction_candidate = b.empty() ? 0.0 : static_cast<double>(r.captured_candidate) / b.size();
    r.wall_seconds_reference = reference.stats().wall_seconds;
    r.wall_seconds_candidate = candidates[j]->stats().wall_seconds;
    r.steps_reference = reference.stats().steps;
    r.steps_candidate = candidates[j]->stats().steps;
    r.reference_version = reference.engineVersion();
  }
  return out;
}

EngineComparison compareEngines(ParticleEngine& reference, ParticleEngine& candidate, const std::vector<Vec3>& positions, double window,
                                double interval) {
  return compareEngines(reference, std::vector<ParticleEngine*>{&candidate}, positions, window, interval).front();
}

std::vector<Vec3> samplePoreSpace(const FlowField& flow, double radius, int n, std::uint64_t seed) {
  const Bounds2 b = flow.bounds();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> ux(b.x0, b.x1), uy(b.y0, b.y1), unit(0.0, 1.0);
  std::vector<ParticleState> placed;
  std::vector<Vec3> out;
  const long tries = 1000L * std::max(n, 1);
  for (long t = 0; t < tries && static_cast<int>(out.size()) < n; ++t) {
    const double x = ux(rng), y = uy(rng);
    const double h = flow.depth(x, y);
    const Vec3 p(x, y, radius + unit(rng) * std::max(h - 2 * radius, 0.0));
    if (!insertionProblem(flow, radius, p, placed).empty()) continue;
    ParticleState s;
    s.id = static_cast<std::int64_t>(placed.size()) + 1;
    s.x = p;
    placed.push_back(s);
    out.push_back(p);
  }
  if (static_cast<int>(out.size()) < n)
    throw InputError(keyLocation("engines.compare_particles"), "the pore space cannot take that many particles apart from each other",
                     fmt::format("{} placed of {}", out.size(), n), "fewer particles");
  return out;
}

std::vector<EngineComparison> compareOnScene(std::shared_ptr<const FlowField> flow, SceneConfig config, const SceneWindow& w,
                                             const std::vector<SceneConfig>& candidates) {
  config.brownian = false;
  config.gravity *= w.gravity_factor;
  const auto positions = samplePoreSpace(*flow, config.particle.radius(), w.particles, w.seed);
  auto reference = makeEngine(EngineKind::liggghts, flow, config);
  std::vector<std::unique_ptr<ParticleEngine>> cheap;
  std::vector<ParticleEngine*> raw;
  for (SceneConfig od : candidates.empty() ? std::vector<SceneConfig>{config} : candidates) {
    od.brownian = false;
    od.gravity = config.gravity;
    cheap.push_back(makeEngine(EngineKind::overdamped, flow, od));
    raw.push_back(cheap.back().get());
  }
  return compareEngines(*reference, raw, positions, w.window, w.interval);
}

}  // namespace mmval::particles
