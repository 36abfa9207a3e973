// decideMotion (Brownian.hpp): analysis.motion = "auto".
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "mmval/tracking/Brownian.hpp"

namespace mmval::tracking {

MotionDecision decideMotion(const Tracks& tracks, double z_directed, double peclet) {
  MotionDecision m;
  m.requested = MotionModel::automatic;
  const EnsembleDrift drift = ensembleDrift(tracks);
  const Tracks c = driftCorrected(tracks, drift);
  const auto& pts = c.points;
  // Pooled lag-1 correlation of successive drift-corrected steps; per track the sums
  // for the ratio estimator's variance.
  double num = 0, den = 0, step_sq = 0;
  long long steps = 0;
  std::vector<std::pair<double, double>> per_track;
  for (const auto& [i, j] : trackRanges(pts)) {
    double tn = 0, td = 0;
    for (std::size_t k = i + 1; k + 1 < j; ++k) {
      if (pts[k].frame - pts[k - 1].frame != 1 || pts[k + 1].frame - pts[k].frame != 1) continue;
      const double ax = pts[k].x - pts[k - 1].x, ay = pts[k].y - pts[k - 1].y;
      const double bx = pts[k + 1].x - pts[k].x, by = pts[k + 1].y - pts[k].y;
      tn += ax * bx + ay * by;
      td += 0.5 * (ax * ax + ay * ay + bx * bx + by * by);
      ++m.step_pairs;
    }
    for (std::size_t k = i + 1; k < j; ++k)
      if (pts[k].frame - pts[k - 1].frame == 1) {
        step_sq += std::pow(pts[k].x - pts[k - 1].x, 2) + std::pow(pts[k].y - pts[k - 1].y, 2);
        ++steps;
      }
    if (td > 0) per_track.emplace_back(tn, td);
    num += tn;
    den += td;
  }
  m.tracks = static_cast<int>(per_track.size());
  if (per_track.size() < 2 || !(den > 0)) {
    m.model = MotionModel::flow;
    m.reason = "flow: too few tracks with successive steps to judge (" + std::to_string(per_track.size()) + "); flow is the default";
    return m;
  }
  m.step_correlation = num / den;
  double var = 0;
  for (const auto& [tn, td] : per_track) var += (tn - m.step_correlation * td) * (tn - m.step_correlation * td);
  m.step_correlation_se = std::sqrt(var) / den;
  m.z_directed = (m.step_correlation - m.correlation_bound) / m.step_correlation_se;
  // The ensemble's own motion per frame against the drift-corrected step, each frame's
  // mean displacement less its noise (step variance / (pairs - 1)).
  const double step_ms = steps > 0 ? step_sq / static_cast<double>(steps) : 0.0;
  double drift_sq = 0;
  int frames = 0;
  for (std::size_t f = 1; f < drift.frame.size(); ++f) {
    if (drift.pairs[f] < 2 || drift.frame[f] - drift.frame[f - 1] != 1) continue;
    const double ux = drift.x[f] - drift.x[f - 1], uy = drift.y[f] - drift.y[f - 1];
    drift_sq += ux * ux + uy * uy - step_ms / (drift.pairs[f] - 1);
    ++frames;
  }
  if (frames > 0 && step_ms > 0) m.drift_peclet = std::sqrt(std::max(0.0, drift_sq / frames) / step_ms);
  const bool directed = m.z_directed > z_directed;
  const bool carried = std::isfinite(m.drift_peclet) && m.drift_peclet > peclet;
  // Localisation noise about fixed places alone correlates successive steps at -1/2:
  // Brownian needs the steps to be significantly less anticorrelated than that.
  m.z_diffusing = (m.step_correlation + 0.5) / m.step_correlation_se;
  const bool still = m.z_diffusing < z_directed;
  m.model = directed || carried || still ? MotionModel::flow : MotionModel::brownian;
  const std::string numbers =
      fmt::format("lag-1 correlation of drift-corrected steps {:.3f} +- {:.3f} over {} tracks ({} step pairs), {:.1f} standard errors from "
                  "the Brownian bound {:.2f} (flow above {:.0f}); ensemble drift per frame {:.3g} x the rms drift-corrected step (flow above {:.0f})",
                  m.step_correlation, m.step_correlation_se, m.tracks, m.step_pairs, m.z_directed, m.correlation_bound, z_directed,
                  m.drift_peclet, peclet);
  if (directed)
    m.reason = "flow: the steps are directed: " + numbers;
  else if (carried)
    m.reason = "flow: the particles are carried together: " + numbers;
  else if (still)
    m.reason = fmt::format("flow: nothing moves beyond localisation noise (step correlation {:.1f} standard errors above the -0.5 of noise "
                           "alone, Brownian above {:.0f}); flow is the default: ",
                           m.z_diffusing, z_directed) + numbers;
  else
    m.reason = "brownian: steps neither directed nor carried: " + numbers;
  return m;
}

}  // namespace mmval::tracking
