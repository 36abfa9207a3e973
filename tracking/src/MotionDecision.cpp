// decideMotion (Brownian.hpp): analysis.motion = "auto".
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "mmval/tracking/Brownian.hpp"

namespace mmval::tracking {

namespace {

/// Shortest track judged for persistence: 4 successive steps (below, even a straight
/// track's R = n cannot reach the 1 % threshold of widened diffusion by a useful margin).
constexpr int kPersistenceSteps = 4;
/// Full-frame exposure correlates successive diffusive steps at up to +0.25, which
/// scales the variance of their sum by up to 1 + 2 x 0.25 (the test's widened null).
constexpr double kExposureWidening = 1.5;

/// Tracks of >= kPersistenceSteps successive steps (`judged`) and those whose
/// R = |sum of steps|^2 / sum of |step|^2 exceeds what diffusion exceeds with probability
/// `alpha` (`persistent`). For n Gaussian isotropic steps, R = n X / (X + Y) with X the
/// chi^2_2 of the sum and Y the independent chi^2_2(n-1) of the steps about their mean,
/// so P(R > n q / (1 + q)) = P(X / Y > q) = (1 + q)^-(n-1) (the F(2, 2(n-1)) tail);
/// X widened by kExposureWidening: q = w (alpha^(-1/(n-1)) - 1).
std::pair<int, int> countPersistent(const std::vector<TrackPoint>& pts, double alpha) {
  int judged = 0, persistent = 0;
  for (const auto& [i, j] : trackRanges(pts)) {
    double sx = 0, sy = 0, s2 = 0;
    int n = 0;
    for (std::size_t k = i + 1; k < j; ++k) {
      if (pts[k].frame - pts[k - 1].frame != 1) continue;
      const double dx = pts[k].x - pts[k - 1].x, dy = pts[k].y - pts[k - 1].y;
      sx += dx;
      sy += dy;
      s2 += dx * dx + dy * dy;
      ++n;
    }
    if (n < kPersistenceSteps || !(s2 > 0)) continue;
    ++judged;
    const double q = kExposureWidening * (std::pow(alpha, -1.0 / (n - 1)) - 1);
    if ((sx * sx + sy * sy) / s2 > n * q / (1 + q)) ++persistent;
  }
  return {judged, persistent};
}

/// P(K >= k) for K binomial(n, p).
double binomialUpperTail(int n, int k, double p) {
  if (k <= 0) return 1.0;
  double sum = 0;
  for (int i = k; i <= n; ++i) {
    const double log_term = std::lgamma(n + 1.0) - std::lgamma(i + 1.0) - std::lgamma(n - i + 1.0) + i * std::log(p) + (n - i) * std::log1p(-p);
    const double term = std::exp(log_term);
    sum += term;
    if (term < 1e-18 * sum) break;  // past the mode the terms only fall
  }
  return std::min(1.0, sum);
}

}  // namespace

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
  // Persistent tracks: judged on each track alone, so a video of deposits at rest with a
  // few particles crossing it (their steps a small share of all) is still told flow.
  const auto [judged, persistent] = countPersistent(pts, m.persistent_alpha);
  m.persistence_tracks = judged;
  m.persistent_tracks = persistent;
  if (judged > 0) m.persistent_p = binomialUpperTail(judged, persistent, m.persistent_alpha);
  const double one_sided = 0.5 * std::erfc(z_directed / std::sqrt(2.0));
  const bool persists = std::isfinite(m.persistent_p) && m.persistent_p < one_sided;
  const bool directed = m.z_directed > z_directed;
  const bool carried = std::isfinite(m.drift_peclet) && m.drift_peclet > peclet;
  // Localisation noise about fixed places alone correlates successive steps at -1/2:
  // Brownian needs the steps to be significantly less anticorrelated than that.
  m.z_diffusing = (m.step_correlation + 0.5) / m.step_correlation_se;
  const bool still = m.z_diffusing < z_directed;
  m.model = directed || carried || persists || still ? MotionModel::flow : MotionModel::brownian;
  const std::string numbers = fmt::format(
      "lag-1 correlation of drift-corrected steps {:.3f} +- {:.3f} over {} tracks ({} step pairs), {:.1f} standard errors from "
      "the Brownian bound {:.2f} (flow above {:.0f}); ensemble drift per frame {:.3g} x the rms drift-corrected step (flow above {:.0f}); "
      "{} of {} tracks of >= {} steps keep their direction beyond diffusion ({:.1f} expected at {:.0f} % each; chance {:.2g}, flow below {:.2g})",
      m.step_correlation, m.step_correlation_se, m.tracks, m.step_pairs, m.z_directed, m.correlation_bound, z_directed, m.drift_peclet, peclet,
      m.persistent_tracks, m.persistence_tracks, kPersistenceSteps, m.persistent_alpha * m.persistence_tracks, 100 * m.persistent_alpha,
      m.persistent_p, one_sided);
  if (directed)
    m.reason = "flow: the steps are directed: " + numbers;
  else if (carried)
    m.reason = "flow: the particles are carried together: " + numbers;
  else if (persists)
    m.reason = "flow: more tracks keep their direction than diffusion gives (moving tracks judged alone, whatever rests beside them): " + numbers;
  else if (still)
    m.reason = fmt::format("flow: nothing moves beyond localisation noise (step correlation {:.1f} standard errors above the -0.5 of noise "
                           "alone, Brownian above {:.0f}); flow is the default: ",
                           m.z_diffusing, z_directed) + numbers;
  else
    m.reason = "brownian: steps neither directed nor carried: " + numbers;
  return m;
}

}  // namespace mmval::tracking
