#include "mmval/particles/HydroModel.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace mmval::particles {

namespace {
// Brenner factor tabulated against log(gap / a) for gap/a in [1e-4, 1e4]: the
// exact series costs thousands of sinh near contact.
constexpr double kLn10 = 2.302585092994046;
constexpr double kLogGapMin = -4.0 * kLn10, kLogGapMax = 4.0 * kLn10;
constexpr int kTable = 801;
// Gaps below this fraction of the radius are evaluated at it: the factor is
// ~1000 there, and a smaller floor only makes a non-sticky wall a trap.
constexpr double kMinGapFraction = 1e-3;

}  // namespace

HydroModel::HydroModel(std::shared_ptr<const FlowField> flow, const SceneConfig& config) : m_flow(std::move(flow)), m_cfg(config) {
  if (!m_flow) throw std::invalid_argument("HydroModel: no flow field");
  m_radius = m_cfg.particle.radius();
  m_drag0 = stokesDragCoefficient(m_cfg.fluid, m_cfg.particle.diameter);
  m_diffusivity = stokesEinstein(m_cfg.fluid, m_cfg.particle.diameter);
  // No wall hydrodynamics at all without wall_hindrance (a point particle): no lag either.
  m_near_wall_shear = m_cfg.wall_hindrance && m_cfg.near_wall_shear;
  m_near_contact_drag = m_cfg.near_contact_drag;
  if (m_cfg.attachment.rule == AttachmentModel::Rule::dlvo) {
    // Plates and grains are the chip's material: sphere-plate against the collector potential
    // (the engine's attachment uses the same parameters, OverdampedEngine.cpp).
    DlvoParameters p = m_cfg.attachment.chemistry;
    p.particle_radius = m_radius;
    p.collector_radius = std::numeric_limits<double>::infinity();
    m_wall_dlvo = std::make_shared<const DlvoInteraction>(p);
  }
  m_perp_table.resize(kTable);
  for (int i = 0; i < kTable; ++i) {
    const double g = std::exp(kLogGapMin + (kLogGapMax - kLogGapMin) * i / (kTable - 1));
    m_perp_table[i] = brennerPerpendicular(1.0, 1.0 + g);
  }
  m_perp_log.resize(kTable);
  for (int i = 0; i < kTable; ++i) m_perp_log[i] = std::log(m_perp_table[i]);
}

double HydroModel::perpendicularFactor(double gap) const {
  const double s = std::log(std::max(gap / m_radius, kMinGapFraction));
  if (s >= kLogGapMax) return 1.0 + 9.0 / 8.0 * m_radius / (m_radius + gap);  // Lorentz far field
  const double f = (s - kLogGapMin) / (kLogGapMax - kLogGapMin) * (kTable - 1);
  const int i = std::clamp(static_cast<int>(f), 0, kTable - 2);
  const double w = f - i;
  // log-linear: the factor behaves like a / gap near contact
  return std::exp((1 - w) * m_perp_log[i] + w * m_perp_log[i + 1]);
}

std::pair<double, double> HydroModel::hindrance(double z, double h) const {
  if (!m_cfg.wall_hindrance) return {1.0, 1.0};
  const double a = m_radius, floor = a * kMinGapFraction;
  const double g_b = std::max(z - a, floor), g_t = std::max(h - z - a, floor);
  const auto parallel = [&](double gap) { return m_near_contact_drag ? freeSphereParallel(a, a + gap) : faxenParallel(a, a + gap); };
  const double par = 1.0 + (parallel(g_b) - 1.0) + (parallel(g_t) - 1.0);
  const double perp = 1.0 + (perpendicularFactor(g_b) - 1.0) + (perpendicularFactor(g_t) - 1.0);
  return {par, perp};
}

double HydroModel::normalHindrance(double z, double h) const {
  if (!m_cfg.wall_hindrance) return 1.0;
  const double a = m_radius, floor = a * kMinGapFraction;
  const double g_b = std::max(z - a, floor), g_t = std::max(h - z - a, floor);
  return 1.0 + (perpendicularFactor(g_b) - 1.0) + (perpendicularFactor(g_t) - 1.0);
}

Vec3 HydroModel::fluidVelocity(const Vec3& x) const {
  if (m_flow->isSolid(x.x(), x.y())) return Vec3::Zero();
  const double h = m_flow->depth(x.x(), x.y()), a = m_radius;
  const Vec2 um = m_flow->meanVelocity(x.x(), x.y());
  if (!m_cfg.depth_profile) return {um.x(), um.y(), 0.0};
  double profile = poiseuilleProfile(x.z(), h);
  if (m_cfg.faxen_curvature) profile -= 2.0 * a * a / (h * h);  // a^2/6 d2u/dz2 of the parabola
  return {um.x() * profile, um.y() * profile, 0.0};
}

Vec3 HydroModel::shearLag(const Vec3& x) const {
  if (!m_near_wall_shear || !m_cfg.depth_profile || m_flow->isSolid(x.x(), x.y())) return Vec3::Zero();
  const double f = slitShearLag(m_radius, x.z(), m_flow->depth(x.x(), x.y()));
  const Vec2 um = m_flow->meanVelocity(x.x(), x.y());
  return {um.x() * f, um.y() * f, 0.0};
}

Vec3 HydroModel::force(const Vec3& x) const {
  const auto& c = m_cfg;
  Vec3 f(0, 0, -(c.particle.density - c.fluid.density) * c.particle.volume() * c.gravity);
  const auto& at = c.attachment;
  if (m_wall_dlvo || at.hamaker > 0) {
    const double a = m_radius;
    const double h = m_flow->depth(x.x(), x.y());
    if (at.bottom && x.z() - a < at.attraction_range) f.z() -= surfaceAttraction(x.z() - a);
    if (at.top && h - x.z() - a < at.attraction_range) f.z() += surfaceAttraction(h - x.z() - a);
    if (at.grains) {
      const double gap = m_flow->wallDistance(x.x(), x.y()) - a;
      if (gap < at.attraction_range) {
        const Vec2 n = m_flow->wallNormal(x.x(), x.y());
        const double pull = surfaceAttraction(gap);
        f.x() -= n.x() * pull;
        f.y() -= n.y() * pull;
      }
    }
  }
  return f;
}

double HydroModel::surfaceAttraction(double gap) const {
  const auto& at = m_cfg.attachment;
  const double g = std::max(gap, std::max(at.capture_distance, m_radius * kMinGapFraction));
  if (m_wall_dlvo) return -m_wall_dlvo->force(g);  // DlvoInteraction::force > 0 pushes apart
  return at.hamaker * m_radius / (6.0 * g * g);
}

namespace {

/// Goldman, Cox & Brenner (1967) for a sphere touching a wall in linear shear of rate `shear`:
/// drag 1.7009 x 6 pi mu a^2 shear and torque 0.944 x 4 pi mu a^3 shear; the moment about the
/// contact point is drag x a + torque. Held when the adhesive moment load x contact radius (JKR/DMT
/// radius (load a / K)^(1/3)) is at least that.
bool torqueBalanceHolds(double shear, double load, double a, double mu, double modulus, double* margin) {
  const double drag = 1.7009 * 6.0 * kPi * mu * a * a * shear;
  const double torque = 0.944 * 4.0 * kPi * mu * a * a * a * shear;
  const double applied = drag * a + torque;
  const double contact = modulus > 0 ? std::cbrt(std::max(load, 0.0) * a / modulus) : 0.0;
  const double resisting = std::max(load, 0.0) * contact;
  if (margin != nullptr) *margin = applied > 0 ? resisting / applied : std::numeric_limits<double>::infinity();
  return resisting >= applied;
}

}  // namespace

bool HydroModel::plateAdhesionHolds(const Vec3& x, bool bottom, double* margin, double adhesion_force) const {
  const auto& c = m_cfg;
  const auto& at = c.attachment;
  const double a = m_radius;
  const double h = m_flow->depth(x.x(), x.y());
  // Wall shear rate of the plane-Poiseuille depth profile: du/dz = 6 u_mean / h at both plates.
  const double shear = m_flow->isSolid(x.x(), x.y()) ? 0.0 : 6.0 * m_flow->meanVelocity(x.x(), x.y()).norm() / h;
  const double adhesion = adhesion_force >= 0 ? adhesion_force : contactAdhesion(false);
  const double weight = (c.particle.density - c.fluid.density) * c.particle.volume() * c.gravity;
  return torqueBalanceHolds(shear, adhesion + (bottom ? weight : -weight), a, c.fluid.viscosity, at.contact_modulus, margin);
}

double HydroModel::contactAdhesion(bool sphere_sphere) const {
  const auto& at = m_cfg.attachment;
  const double z0 = at.adhesion_separation, r = sphere_sphere ? 0.5 * m_radius : m_radius;
  return at.hamaker > 0 && z0 > 0 ? at.hamaker * r / (6.0 * z0 * z0) : 0.0;
}

bool HydroModel::surfaceAdhesionHolds(const Vec3& x, double adhesion_force, double* margin) const {
  const double a = m_radius;
  const double shear = fluidVelocity(x).norm() / a;
  return torqueBalanceHolds(shear, adhesion_force, a, m_cfg.fluid.viscosity, m_cfg.attachment.contact_modulus, margin);
}

bool HydroModel::captured(const Vec3& x) const {
  const auto& at = m_cfg.attachment;
  if (!(at.capture_distance > 0)) return false;
  const double a = m_radius, cd = at.capture_distance;
  if (at.bottom && x.z() - a <= cd) return true;
  if (at.top && m_flow->depth(x.x(), x.y()) - x.z() - a <= cd) return true;
  if (at.grains && m_flow->wallDistance(x.x(), x.y()) - a <= cd) return true;
  return false;
}

}  // namespace mmval::particles
