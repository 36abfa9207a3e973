#include "mmval/particles/Scene.hpp"

#include <cmath>
#include <random>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace mmval::particles {

const char* statusName(ParticleStatus s) {
  switch (s) {
    case ParticleStatus::mobile: return "mobile";
    case ParticleStatus::deposited: return "deposited";
    case ParticleStatus::left: return "left";
  }
  return "?";
}

Counts countParticles(const std::vector<ParticleState>& ps) {
  Counts c;
  c.injected = static_cast<std::int64_t>(ps.size());
  for (const auto& p : ps) {
    if (p.status == ParticleStatus::mobile) ++c.inside;
    else if (p.status == ParticleStatus::deposited) {
      ++c.deposited;
      if (p.held_by == Surface::strained) ++c.strained;
    }
    else ++c.left;
  }
  return c;
}

std::string insertionProblem(const FlowField& flow, double radius, const Vec3& x, const std::vector<ParticleState>& others) {
  if (!x.allFinite()) return "position is not finite";
  if (flow.isSolid(x.x(), x.y())) return fmt::format("({:.4g}, {:.4g}) um is inside a grain or outside the chip", x.x() * 1e6, x.y() * 1e6);
  const double h = flow.depth(x.x(), x.y());
  if (x.z() < radius || x.z() > h - radius)
    return fmt::format("z = {:.4g} um is outside [a, h - a] = [{:.4g}, {:.4g}] um", x.z() * 1e6, radius * 1e6, (h - radius) * 1e6);
  if (flow.wallDistance(x.x(), x.y()) < radius)
    return fmt::format("({:.4g}, {:.4g}) um is closer than one radius to a wall", x.x() * 1e6, x.y() * 1e6);
  for (const auto& o : others)
    if (o.status != ParticleStatus::left && (o.x - x).norm() < 2 * radius)
      return fmt::format("overlaps particle {} at ({:.4g}, {:.4g}, {:.4g}) um", o.id, o.x.x() * 1e6, o.x.y() * 1e6, o.x.z() * 1e6);
  return {};
}

std::vector<Vec3> sampleInlet(const FlowField& flow, double radius, double x_in, double strip, int n, std::uint64_t seed,
                              const std::vector<ParticleState>& others) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const Bounds2 b = flow.bounds();
  std::vector<ParticleState> taken = others;
  std::vector<Vec3> out;
  const int max_tries = 1000 * std::max(n, 1);
  int tries = 0;
  while (static_cast<int>(out.size()) < n) {
    if (++tries > max_tries)
      throw InputError(keyLocation("particles"),
                       fmt::format("could not place {} particles of radius {:.3g} um in the inlet strip without overlaps ({} placed)", n,
                                   radius * 1e6, out.size()),
                       {}, "a lower concentration or injection rate, a longer output interval, or smaller particles");
    const double y = b.y0 + U(rng) * (b.y1 - b.y0), x_probe = x_in + radius;
    if (flow.isSolid(x_probe, y)) continue;
    const double h = flow.depth(x_probe, y);
    if (h <= 2 * radius) continue;
    // Flux-weighted height: accept z with probability u(z) / u_max (u_max = 1.5 u_mean).
    const double z = radius + U(rng) * (h - 2 * radius);
    const double f = poiseuilleProfile(z, h) / 1.5;
    if (U(rng) > f) continue;
    // Entered some time during the last interval: a particle at height z has moved
    // up to strip * u(z) / u_max, so the number density comes out uniform in z.
    const Vec3 p(x_in + radius + U(rng) * strip * f, y, z);
    if (flow.isSolid(p.x(), p.y())) continue;
    if (!insertionProblem(flow, radius, p, taken).empty()) continue;
    out.push_back(p);
    ParticleState s;
    s.x = p;
    taken.push_back(s);
  }
  return out;
}

}  // namespace mmval::particles
