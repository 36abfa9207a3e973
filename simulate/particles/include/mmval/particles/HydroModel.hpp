// Forces and mobilities of one particle in the chip, shared by both engines so
// that their comparison measures the engines (inertia, contacts), not two
// different force models.
//   fluid velocity   u_f = u_mean(x, y) [6 z (h - z) / h^2 - 2 a^2 / h^2]
//                    (Hele-Shaw depth profile + Faxen's a^2/6 lap u term; Faxen 1922)
//   drag factors     lambda_par (Goldman, Cox & Brenner 1967 for a sphere free to
//                    rotate: lubrication near contact joined to Faxen's series; Faxen
//                    alone with SceneConfig::near_contact_drag off) and lambda_perp
//                    (Brenner 1961), the two plates superposed (Physics.hpp)
//   shear lag        a free sphere near a plate in shear lags the fluid (Goldman, Cox &
//                    Brenner 1967, II): U = gamma d f(d/a) with f -> 1 - 5/16 (a/d)^3
//                    far away and -> 0 (logarithmically) at contact (Physics.hpp,
//                    freeSphereInShear). Each plate contributes gamma d (f - 1) with its
//                    own wall shear gamma = 6 u_mean / h and centre distance d; the two
//                    are added (first reflection, as for the drag). Approximations: the
//                    other plate's reflection of each plate's disturbance is left out
//                    (error of order (a/h)^3 and more near contact with a thin chip),
//                    and the lag is that of the linear part of the profile at the plate:
//                    the parabola's curvature adds a relative error ~ d/h to the lag
//                    (2a/h at contact: 0.1-0.25 for 5 um particles in 20-50 um chips).
//                    Switched by SceneConfig::near_wall_shear (and off with
//                    wall_hindrance, which drops all wall hydrodynamics); plane flow
//                    has no lag.
//   body force       -(rho_p - rho_f) V g e_z
//   attraction       towards sticky surfaces within `attraction_range` (AttachmentModel):
//                    capture rule: sphere-plate van der Waals A a / (6 gap^2) with
//                    deposition.hamaker; dlvo rule: the same DLVO force that decides
//                    attachment (Dlvo.hpp: double layer + retarded van der Waals, sphere-plate
//                    with the case's chemistry), so that transport and attachment see one
//                    profile. Both are evaluated at gaps of at least the capture distance:
//                    inside it the attachment rule decides.
//   capture          gap to a sticky surface <= capture distance (an arrival; the
//                    engine's attachment rule decides whether it attaches)
//   plate adhesion   (optional) torque balance of a sphere resting on a plate in
//                    the wall shear of the depth profile: Goldman, Cox & Brenner
//                    (1967, Chem. Eng. Sci. 22:653) drag 1.7009 x 6 pi mu a^2 G and
//                    torque 0.944 x 4 pi mu a^3 G (G the wall shear rate), moment about
//                    the contact F a + T; against the DMT adhesion (Derjaguin, Muller
//                    & Toporov 1975) F_A = A a / (6 z0^2) (+ net weight on the bottom
//                    plate) acting at the Hertz/DMT contact radius (F_A a / K)^(1/3)
//                    (Johnson, Contact Mechanics, 1985), as in colloid-detachment
//                    models (Bergendahl & Grasso 2000; Torkzaban, Bradford & Walker
//                    2007, Langmuir 23:9652).
#pragma once
#include <memory>
#include <utility>
#include <vector>

#include "mmval/particles/Dlvo.hpp"
#include "mmval/particles/Scene.hpp"

namespace mmval::particles {

class HydroModel {
 public:
  HydroModel(std::shared_ptr<const FlowField> flow, const SceneConfig& config);

  const FlowField& flow() const { return *m_flow; }
  double radius() const { return m_radius; }
  double drag0() const { return m_drag0; }            ///< 6 pi mu a, N s/m
  double diffusivity() const { return m_diffusivity; }  ///< k_B T / (6 pi mu a), m2/s

  /// Fluid velocity the particle centre sees at x (with Faxen's curvature term when enabled), m/s.
  Vec3 fluidVelocity(const Vec3& x) const;
  /// Velocity a free sphere at x lags the fluid velocity by because of the plates in the
  /// shear of the depth profile (header, "shear lag"; zero when switched off, in plane
  /// flow and in solid), m/s. The overdamped engine adds it to fluidVelocity().
  Vec3 shearLag(const Vec3& x) const;
  /// Drag factors (lambda_par, lambda_perp) at centre height z in depth h (1, 1 when hindrance is off).
  std::pair<double, double> hindrance(double z, double h) const;
  /// lambda_perp alone (hindrance(z, h).second without the parallel factor; the Ito drift needs only it).
  double normalHindrance(double z, double h) const;
  /// Gravity-buoyancy + attraction at x, N.
  Vec3 force(const Vec3& x) const;
  /// Force pulling a particle towards a sticky plate or grain wall at surface gap `gap`
  /// (N, > 0 attracts, < 0 repels; gaps below the capture distance count as the capture
  /// distance): the header's "attraction" of the case's attachment rule.
  double surfaceAttraction(double gap) const;
  /// True when x is within the capture distance of a sticky plate, grain or side wall.
  bool captured(const Vec3& x) const;
  /// Torque balance of a particle resting on the bottom (or top) plate at x (header
  /// comment): true when adhesion holds it. `margin` receives adhesive / applied torque.
  /// `adhesion_force` (N, >= 0) replaces the DMT contact adhesion A a / (6 z0^2): the
  /// dlvo rule passes the largest attraction of the secondary minimum (a particle held there).
  bool plateAdhesionHolds(const Vec3& x, bool bottom, double* margin = nullptr, double adhesion_force = -1.0) const;
  /// The same torque balance for a particle held beside a grain wall or a deposit by a pull-off
  /// force `adhesion_force` (N): the local shear is the fluid speed at the centre over the
  /// centre's distance from the surface (the radius; GCB's wall drag and torque for a sphere
  /// touching a wall in linear shear), no weight in the load (grain walls are vertical; the
  /// direction of a deposit contact is not tracked, so gravity is left out for it too).
  bool surfaceAdhesionHolds(const Vec3& x, double adhesion_force, double* margin = nullptr) const;
  /// DMT contact adhesion of the capture rule (N): A a / (6 z0^2) against a wall, A (a/2) / (6 z0^2)
  /// against another particle of the same radius (Derjaguin's effective radius); 0 without a
  /// Hamaker constant.
  double contactAdhesion(bool sphere_sphere) const;
  bool nearWallShear() const { return m_near_wall_shear; }    ///< shear lag on (SceneConfig::near_wall_shear and wall_hindrance)
  bool nearContactDrag() const { return m_near_contact_drag; }  ///< GCB parallel drag on (SceneConfig::near_contact_drag)
  /// Single-wall Brenner factor at surface gap `gap` (tabulated, log-interpolated; exact series in Physics.hpp).
  double perpendicularFactor(double gap) const;

 private:
  std::shared_ptr<const FlowField> m_flow;
  SceneConfig m_cfg;
  double m_radius, m_drag0, m_diffusivity;
  bool m_near_wall_shear = true, m_near_contact_drag = true;
  std::shared_ptr<const DlvoInteraction> m_wall_dlvo;  ///< dlvo rule: sphere-plate profile of plates and grains
  std::vector<double> m_perp_table;
  std::vector<double> m_perp_log;  ///< log of m_perp_table, entry by entry (interpolated per call)
};

}  // namespace mmval::particles
