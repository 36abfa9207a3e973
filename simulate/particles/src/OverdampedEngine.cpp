#include "mmval/particles/OverdampedEngine.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <unordered_map>

#include <fmt/format.h>
#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>

#include "mmval/core/Error.hpp"

namespace mmval::particles {

struct OverdampedEngine::Rng {
  gsl_rng* r = nullptr;
  explicit Rng(std::uint64_t seed) : r(gsl_rng_alloc(gsl_rng_mt19937)) { gsl_rng_set(r, static_cast<unsigned long>(seed)); }
  ~Rng() { gsl_rng_free(r); }
  double normal() { return gsl_ran_gaussian_ziggurat(r, 1.0); }
};

OverdampedEngine::OverdampedEngine(std::shared_ptr<const FlowField> flow, SceneConfig config)
    : m_flow(std::move(flow)), m_cfg(std::move(config)), m_model(m_flow, m_cfg) {
  const auto& p = m_cfg.particle;
  if (!(p.diameter > 0) || !(p.density > 0) || !(m_cfg.fluid.viscosity > 0) || !(m_cfg.fluid.temperature > 0))
    throw InputError(keyLocation("particles"), "diameter, densities, viscosity and temperature must be > 0");
  if (!(m_cfg.max_step_fraction > 0) || m_cfg.max_step_fraction > 1)
    throw InputError(keyLocation("numerics.max_step_fraction"), "out of range", std::to_string(m_cfg.max_step_fraction), "(0, 1]");
  m_radius = p.radius();
  m_outlet = std::isnan(m_cfg.outlet_x) ? m_flow->bounds().x1 : m_cfg.outlet_x;
  m_rng = std::make_unique<Rng>(m_cfg.seed);
}

OverdampedEngine::~OverdampedEngine() = default;

Vec3 OverdampedEngine::driftVelocity(const Vec3& x) const {
  if (m_flow->isSolid(x.x(), x.y())) return Vec3::Zero();
  const double h = m_flow->depth(x.x(), x.y()), a = m_radius, g0 = m_model.drag0();
  const auto [par, perp] = m_model.hindrance(x.z(), h);
  const Vec3 f = m_model.force(x);
  Vec3 v = m_model.fluidVelocity(x) + Vec3(f.x() / (g0 * par), f.y() / (g0 * par), f.z() / (g0 * perp));
  if (m_cfg.brownian && m_cfg.wall_hindrance) {
    // Ito drift k_B T d(1/(6 pi mu a lambda_perp))/dz keeps the equilibrium distribution right.
    const double e = 1e-3 * a;
    const double zm = std::max(x.z() - e, a), zp = std::min(x.z() + e, h - a);
    if (zp > zm) v.z() += m_model.diffusivity() * (1.0 / m_model.hindrance(zp, h).second - 1.0 / m_model.hindrance(zm, h).second) / (zp - zm);
  }
  return v;
}

void OverdampedEngine::insert(const std::vector<Vec3>& positions) {
  std::vector<ParticleState> trial = m_particles;
  for (std::size_t k = 0; k < positions.size(); ++k) {
    const std::string why = insertionProblem(*m_flow, m_radius, positions[k], trial);
    if (!why.empty()) throw InputError(keyLocation("particles.insert"), fmt::format("particle {} of this insertion cannot be placed: {}", k, why));
    ParticleState s;
    s.id = static_cast<std::int64_t>(trial.size()) + 1;
    s.x = positions[k];
    trial.push_back(s);
  }
  m_particles = std::move(trial);
}

double OverdampedEngine::chooseStep(const std::vector<Vec3>& drift) const {
  const double lim = m_cfg.max_step_fraction * m_radius;
  // Approaching a plate the mobility changes over the gap, not the radius: the
  // drift across the depth may cover only the same fraction of the gap (floored
  // at the capture distance, or 1 % of a radius), else explicit steps overshoot.
  const double floor = std::max(m_cfg.attachment.capture_distance, 0.01 * m_radius);
  double dt = m_cfg.max_dt;
  for (std::size_t i = 0; i < drift.size(); ++i) {
    const double v = drift[i].norm();
    if (v > 0) dt = std::min(dt, lim / v);
    const auto& x = m_particles[i].x;
    const double vz = std::abs(drift[i].z());
    if (vz > 0 && m_particles[i].status == ParticleStatus::mobile) {
      const double h = m_flow->depth(x.x(), x.y());
      const double gap = vz > 0 && drift[i].z() < 0 ? x.z() - m_radius : h - x.z() - m_radius;
      dt = std::min(dt, m_cfg.max_step_fraction * std::max(gap, floor) / vz);
    }
  }
  if (m_cfg.brownian) dt = std::min(dt, lim * lim / (2.0 * m_model.diffusivity()));
  return dt;
}

void OverdampedEngine::advance(double t_end) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<Vec3> drift;
  while (m_t < t_end * (1 - 1e-14)) {
    drift.assign(m_particles.size(), Vec3::Zero());
    std::int64_t mobile = 0;
    for (std::size_t i = 0; i < m_particles.size(); ++i)
      if (m_particles[i].status == ParticleStatus::mobile) {
        drift[i] = driftVelocity(m_particles[i].x);
        ++mobile;
      }
    double dt = mobile ? chooseStep(drift) : t_end - m_t;
    dt = std::min(dt, t_end - m_t);
    if (mobile) {
      const auto& c = m_cfg;
      for (std::size_t i = 0; i < m_particles.size(); ++i) {
        auto& p = m_particles[i];
        if (p.status != ParticleStatus::mobile) continue;
        const Vec3 before = p.x;
        Vec3 dx = drift[i] * dt;
        if (c.brownian) {
          const auto [par, perp] = m_model.hindrance(p.x.z(), m_flow->depth(p.x.x(), p.x.y()));
          const double sp = std::sqrt(2.0 * m_model.diffusivity() * dt / par), sz = std::sqrt(2.0 * m_model.diffusivity() * dt / perp);
          dx += Vec3(sp * m_rng->normal(), sp * m_rng->normal(), sz * m_rng->normal());
        }
        p.x += dx;
        p.v = drift[i];
        applyWallsAndCapture(p, before);
        if (p.status != ParticleStatus::mobile) p.t_event = m_t + dt;
      }
      resolveContacts();
      for (auto& p : m_particles)
        if (p.status != ParticleStatus::mobile && std::isnan(p.t_event)) p.t_event = m_t + dt;
      m_stats.particle_steps += mobile;
      ++m_stats.steps;
      m_stats.last_dt = dt;
      m_stats.min_dt = std::min(m_stats.min_dt, dt);
      m_stats.max_dt = std::max(m_stats.max_dt, dt);
    }
    m_t += dt;
  }
  m_t = std::max(m_t, t_end);
  m_stats.wall_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void OverdampedEngine::applyWallsAndCapture(ParticleState& p, const Vec3& before) {
  const auto& at = m_cfg.attachment;
  const double a = m_radius;
  const bool capture = at.capture_distance > 0;
  // Grains and side walls: a step into solid is taken back in-plane; a particle
  // closer than a radius is pushed out along the wall normal.
  bool touched_grain = false;
  if (m_flow->isSolid(p.x.x(), p.x.y())) {
    p.x.x() = before.x();
    p.x.y() = before.y();
    touched_grain = true;
  }
  const Bounds2 b = m_flow->bounds();
  if (p.x.x() > m_outlet || p.x.x() < b.x0 || p.x.y() < b.y0 || p.x.y() > b.y1) {
    p.status = ParticleStatus::left;
    return;
  }
  const double d = m_flow->wallDistance(p.x.x(), p.x.y());
  if (d < a) {
    const Vec2 n = m_flow->wallNormal(p.x.x(), p.x.y());
    p.x.x() += n.x() * (a - d);
    p.x.y() += n.y() * (a - d);
    touched_grain = true;
  }
  const double h = m_flow->depth(p.x.x(), p.x.y());
  bool touched_bottom = false, touched_top = false;
  if (p.x.z() < a) {
    p.x.z() = a;
    touched_bottom = true;
  }
  if (p.x.z() > h - a) {
    p.x.z() = h - a;
    touched_top = true;
  }
  if (!capture) return;
  const double cd = at.capture_distance;
  if ((at.bottom && (touched_bottom || p.x.z() - a <= cd)) || (at.top && (touched_top || h - p.x.z() - a <= cd)) ||
      (at.grains && (touched_grain || m_flow->wallDistance(p.x.x(), p.x.y()) - a <= cd)))
    p.status = ParticleStatus::deposited;
}

void OverdampedEngine::resolveContacts() {
  const double a = m_radius, d = 2 * a, cs = d;
  const auto key = [&](const Vec3& x) {
    const auto ix = static_cast<std::int64_t>(std::floor(x.x() / cs)), iy = static_cast<std::int64_t>(std::floor(x.y() / cs)),
               iz = static_cast<std::int64_t>(std::floor(x.z() / cs));
    return (ix * 73856093) ^ (iy * 19349663) ^ (iz * 83492791);
  };
  const bool stick = m_cfg.attachment.deposited && m_cfg.attachment.capture_distance > 0;
  // A few Heyes-Melrose sweeps: each removes every overlap found; new ones made
  // by a push are caught by the next sweep. Dilute scenes need one.
  for (int sweep = 0; sweep < 4; ++sweep) {
    std::unordered_map<std::int64_t, std::vector<int>> cells;
    for (int i = 0; i < static_cast<int>(m_particles.size()); ++i)
      if (m_particles[i].status != ParticleStatus::left) cells[key(m_particles[i].x)].push_back(i);
    bool any = false;
    for (int i = 0; i < static_cast<int>(m_particles.size()); ++i) {
      auto& p = m_particles[i];
      if (p.status != ParticleStatus::mobile) continue;
      const auto ix = static_cast<std::int64_t>(std::floor(p.x.x() / cs)), iy = static_cast<std::int64_t>(std::floor(p.x.y() / cs)),
                 iz = static_cast<std::int64_t>(std::floor(p.x.z() / cs));
      for (int dx = -1; dx <= 1; ++dx)
        for (int dy = -1; dy <= 1; ++dy)
          for (int dz = -1; dz <= 1; ++dz) {
            const auto it = cells.find(((ix + dx) * 73856093) ^ ((iy + dy) * 19349663) ^ ((iz + dz) * 83492791));
            if (it == cells.end()) continue;
            for (int j : it->second) {
              if (j == i) continue;
              auto& q = m_particles[j];
              if (q.status == ParticleStatus::mobile && j < i) continue;  // each mobile pair once
              Vec3 r = p.x - q.x;
              const double dist = r.norm();
              if (dist >= d || (std::abs(r.x()) >= d)) continue;
              if (dist < 1e-12 * d) r = Vec3(0, 0, 1); else r /= dist;
              const double overlap = d - std::max(dist, 0.0);
              any = true;
              if (q.status == ParticleStatus::deposited) {
                p.x += r * overlap;
                if (stick) p.status = ParticleStatus::deposited;
              } else {
                p.x += 0.5 * overlap * r;
                q.x -= 0.5 * overlap * r;
              }
            }
          }
    }
    // Pushes may have moved particles into the plates: clamp again (no capture here
    // beyond the plate rule, which the next step's wall check applies).
    for (auto& p : m_particles) {
      if (p.status == ParticleStatus::left) continue;
      const double h = m_flow->depth(p.x.x(), p.x.y());
      p.x.z() = std::clamp(p.x.z(), a, std::max(a, h - a));
    }
    if (!any) break;
  }
}

nlohmann::json OverdampedEngine::describe() const {
  const auto& c = m_cfg;
  return {{"engine", "overdamped"},
          {"diameter_um", c.particle.diameter * 1e6},
          {"density_kg_m3", c.particle.density},
          {"tau_p_s", relaxationTime(c.fluid, c.particle)},
          {"diffusivity_m2_s", m_model.diffusivity()},
          {"settling_speed_m_s", settlingSpeed(c.fluid, c.particle, c.gravity)},
          {"brownian", c.brownian},
          {"wall_hindrance", c.wall_hindrance},
          {"faxen_curvature", c.faxen_curvature},
          {"capture_distance_um", c.attachment.capture_distance * 1e6},
          {"hamaker_J", c.attachment.hamaker},
          {"max_step_fraction", c.max_step_fraction},
          {"seed", c.seed},
          {"contacts", "hard spheres, Heyes-Melrose overlap removal"}};
}

}  // namespace mmval::particles
