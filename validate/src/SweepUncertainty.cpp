// The statistics of a sweep (src/Sweep.cpp): a sample's mean and spread over seeds, and the grid
// and step parts of a metric's uncertainty from its discretisation ladders.
#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include <fmt/format.h>

#include "mmval/validate/Sweep.hpp"

namespace mmval::validate {

nlohmann::json SampleStats::toJson() const {
  if (n == 0) return {{"n", 0}, {"mean", nullptr}, {"sd", nullptr}, {"se", nullptr}, {"min", nullptr}, {"max", nullptr}};
  return {{"n", n}, {"mean", mean}, {"sd", sd}, {"se", se}, {"min", min}, {"max", max}};
}

SampleStats sampleStats(const std::vector<double>& values) {
  SampleStats s;
  double sum = 0;
  s.min = std::numeric_limits<double>::infinity();
  s.max = -s.min;
  for (double v : values) {
    if (!std::isfinite(v)) continue;
    ++s.n;
    sum += v;
    s.min = std::min(s.min, v);
    s.max = std::max(s.max, v);
  }
  if (s.n == 0) return SampleStats{};
  s.mean = sum / s.n;
  double ss = 0;
  for (double v : values)
    if (std::isfinite(v)) ss += (v - s.mean) * (v - s.mean);
  s.sd = s.n > 1 ? std::sqrt(ss / (s.n - 1)) : 0.0;  // sample standard deviation
  s.se = s.sd / std::sqrt(static_cast<double>(s.n));
  return s;
}

DifferenceError differenceError(const LadderLevel& a, const LadderLevel& b) {
  DifferenceError e;
  // Paired only when the two levels have values for the same seeds: the mean of the per-seed
  // differences is then exactly mean(a) - mean(b), and what the seed adds to both cancels.
  bool same_seeds = !a.by_seed.empty() && a.by_seed.size() == b.by_seed.size();
  std::vector<double> d;
  for (std::size_t i = 0; i < std::min(a.by_seed.size(), b.by_seed.size()); ++i) {
    const bool in_a = std::isfinite(a.by_seed[i]), in_b = std::isfinite(b.by_seed[i]);
    same_seeds = same_seeds && in_a == in_b;
    if (in_a && in_b) d.push_back(a.by_seed[i] - b.by_seed[i]);
  }
  e.pairs = static_cast<int>(d.size());
  if (same_seeds && d.size() >= 2) {
    e.paired = true;
    e.se = sampleStats(d).se;
    return e;
  }
  const auto var = [](const LadderLevel& l) { return l.stats.n > 1 ? l.stats.se * l.stats.se : 0.0; };
  e.se = std::sqrt(var(a) + var(b));
  return e;
}

DiscretisationPart discretisationPart(std::vector<LadderLevel> levels, Finer finer) {
  DiscretisationPart p;
  levels.erase(std::remove_if(levels.begin(), levels.end(), [](const LadderLevel& l) { return l.stats.n == 0; }), levels.end());
  // h: the cell or step size the value stands for; the finest first.
  const auto h = [&](const LadderLevel& l) { return finer == Finer::larger ? 1 / l.value : l.value; };
  std::sort(levels.begin(), levels.end(), [&](const LadderLevel& a, const LadderLevel& b) { return h(a) < h(b); });
  p.levels = levels;
  if (levels.size() < 2) {
    p.note = levels.empty() ? "no level has a value" : "one level has a value";
    return p;
  }
  const double f1 = levels[0].stats.mean, f2 = levels[1].stats.mean;
  p.difference = f1 - f2;
  const DifferenceError e21_error = differenceError(levels[0], levels[1]);
  p.difference_se = e21_error.se;
  p.difference_se_rule = e21_error.paired ? "paired" : "independent";
  p.paired_seeds = e21_error.pairs;
  p.resolved = std::abs(p.difference) > 2 * p.difference_se;
  p.method = "difference";
  p.part = std::abs(p.difference);
  p.part_se = p.difference_se;
  if (levels.size() < 3) {
    p.note = "two levels: the difference of their means";
    return p;
  }
  const double f3 = levels[2].stats.mean;
  const double e21 = f2 - f1, e32 = f3 - f2;  // Celik et al.'s eps21, eps32
  const double e32_se = differenceError(levels[2], levels[1]).se;
  if (!(e21 * e32 > 0)) {
    p.note = "not monotone over the three finest levels: the difference of the two finest";
    return p;
  }
  if (!(std::abs(e21) < std::abs(e32))) {
    p.note = "the differences do not shrink towards the finest level: the difference of the two finest";
    return p;
  }
  if (!p.resolved || !(std::abs(e32) > 2 * e32_se)) {
    p.note = "a difference of the three finest levels is within 2 standard errors of the seeds (no credible order): the difference of the two finest";
    return p;
  }
  // Observed order for refinement ratios r21, r32 (Celik et al. 2008, eqs. 3a-3c), by fixed-point iteration.
  const double r21 = h(levels[1]) / h(levels[0]), r32 = h(levels[2]) / h(levels[1]);
  double order = std::log(e32 / e21) / std::log(r21);
  bool settled = false;
  for (int it = 0; it < 100 && std::isfinite(order) && order > 0; ++it) {
    const double q = std::log((std::pow(r21, order) - 1) / (std::pow(r32, order) - 1));
    const double next = (std::log(e32 / e21) + q) / std::log(r21);
    settled = std::abs(next - order) < 1e-12 * std::max(1.0, std::abs(order));
    order = next;
    if (settled) break;
  }
  if (!settled || !(order > 0)) {
    p.note = "no observed order found for these refinement ratios: the difference of the two finest";
    return p;
  }
  const double denominator = std::pow(r21, order) - 1;
  p.method = "richardson";
  p.observed_order = order;
  p.extrapolated = f1 + (f1 - f2) / denominator;
  p.part = std::abs(p.difference) / denominator;
  p.part_se = p.difference_se / denominator;  // the order taken as exact
  p.note = fmt::format("observed order {:.3g} from the three finest levels (ratios {:.3g}, {:.3g}); part = |difference| / (r21^p - 1)", order, r21, r32);
  return p;
}

MetricUncertainty metricUncertainty(const SampleStats& finest, std::optional<DiscretisationPart> grid, std::optional<DiscretisationPart> step,
                                    double tolerance) {
  MetricUncertainty u;
  u.finest = finest;
  u.grid = std::move(grid);
  u.step = std::move(step);
  if (finest.n > 1) u.seed_se = finest.se;
  double sum = 0;
  bool any = false;
  for (double part : {u.seed_se, u.grid ? u.grid->part : NAN, u.step ? u.step->part : NAN})
    if (std::isfinite(part)) {
      sum += part * part;
      any = true;
    }
  if (any && finest.n > 0) u.combined = std::sqrt(sum);
  if (std::isnan(tolerance)) return u;
  if (!u.grid && !u.step) {
    u.verdict = "no verdict: the sweep has no grid or step axis";
    return u;
  }
  bool within = true, within_2se = true, known = true;
  std::string why;
  const std::pair<const char*, const DiscretisationPart*> parts[] = {{"grid", u.grid ? &*u.grid : nullptr}, {"step", u.step ? &*u.step : nullptr}};
  for (const auto& [axis, part] : parts) {
    if (part == nullptr) continue;
    if (!std::isfinite(part->part)) {
      known = false;
      why += fmt::format("{}{} part not estimated", why.empty() ? "" : "; ", axis);
      continue;
    }
    const bool ok = std::abs(part->difference) <= tolerance && part->part <= tolerance;
    const bool ok_2se = ok && part->part + 2 * (std::isfinite(part->part_se) ? part->part_se : 0.0) <= tolerance;
    within = within && ok;
    within_2se = within_2se && ok_2se;
    if (!ok) why += fmt::format("{}{} part {:.3g} (difference {:+.3g}) beyond {:g}", why.empty() ? "" : "; ", axis, part->part, part->difference, tolerance);
    else if (!ok_2se) why += fmt::format("{}{} part + 2 SE {:.3g} beyond {:g}", why.empty() ? "" : "; ", axis, part->part + 2 * part->part_se, tolerance);
  }
  if (!known) {
    u.verdict = "no verdict: " + why;
    return u;
  }
  u.converged = within;
  u.converged_2se = within_2se;
  u.verdict = within ? (within_2se ? fmt::format("converged within {:g}, also at 2 standard errors", tolerance)
                                   : fmt::format("converged within {:g}, not beyond the seed noise ({})", tolerance, why))
                     : fmt::format("NOT converged within {:g} ({})", tolerance, why);
  return u;
}

}  // namespace mmval::validate
