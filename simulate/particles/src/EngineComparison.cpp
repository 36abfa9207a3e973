#include "mmval/particles/EngineComparison.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

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

EngineComparison compareEngines(ParticleEngine& reference, ParticleEngine& candidate, const std::vector<Vec3>& positions, double window,
                                double interval) {
  if (!(window > 0) || !(interval > 0) || interval > window) throw std::invalid_argument("compareEngines: need 0 < interval <= window");
  if (!reference.particles().empty() || !candidate.particles().empty()) throw std::invalid_argument("compareEngines: engines must be empty");
  reference.insert(positions);
  candidate.insert(positions);
  EngineComparison r;
  r.window_s = window;
  r.particles = static_cast<int>(positions.size());
  double sum2 = 0;
  long n = 0;
  const auto steps = static_cast<int>(std::llround(window / interval));
  for (int k = 1; k <= steps; ++k) {
    reference.advance(k * interval);
    candidate.advance(k * interval);
    const auto a = reference.particles(), b = candidate.particles();
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (a[i].status == ParticleStatus::left || b[i].status == ParticleStatus::left) continue;
      const double d = (a[i].x - b[i].x).norm();
      sum2 += d * d;
      ++n;
      r.max_position_difference = std::max(r.max_position_difference, d);
    }
  }
  r.rms_position_difference = n ? std::sqrt(sum2 / n) : 0.0;
  const auto a = reference.particles(), b = candidate.particles();
  double dt2 = 0;
  std::vector<double> final_diff;
  for (std::size_t i = 0; i < a.size(); ++i)
    if (a[i].status != ParticleStatus::left && b[i].status != ParticleStatus::left) final_diff.push_back((a[i].x - b[i].x).norm());
  if (!final_diff.empty()) {
    std::nth_element(final_diff.begin(), final_diff.begin() + final_diff.size() / 2, final_diff.end());
    r.median_final_difference = final_diff[final_diff.size() / 2];
  }
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
  r.wall_seconds_candidate = candidate.stats().wall_seconds;
  r.steps_reference = reference.stats().steps;
  r.steps_candidate = candidate.stats().steps;
  return r;
}

}  // namespace mmval::particles
