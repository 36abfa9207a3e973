// The overdamped colloid engine (ours): for Stokes numbers << 1 a particle's
// inertia relaxes in tau_p (~1.5 us for 5 um polystyrene), far below any time
// that matters, so its velocity is the force balance
//   v = u_f(x, z) + u_lag(x, z) + M(z) F + Brownian,    (Ermak & McCammon 1978)
//   u_f = u_mean(x, y) [6 z (h - z) / h^2 - 2 a^2 / h^2]  (depth profile + Faxen's a^2/6 lap u)
//   u_lag: a free sphere's lag behind the shear near each plate (Goldman, Cox &
//          Brenner 1967; HydroModel::shearLag, the plates superposed)
//   M = diag(1/lambda_par, 1/lambda_par, 1/lambda_perp) / (6 pi mu a)
//       (Goldman-Cox-Brenner joined to Faxen for a sphere free to rotate, Brenner; two plates)
//   F = gravity - buoyancy along -z + van der Waals attraction to sticky surfaces
//   dx_B = sqrt(2 D dt) xi with D = k_B T M, plus the drift k_B T dM/dz (Ito).
//   Only M_zz depends on z in a way the drift sees (M_xx depends on z, not x), so the
//   drift is k_B T d(1/lambda_perp)/dz / (6 pi mu a) alone, unchanged by the parallel model.
// Contacts are hard: after each step overlaps with other particles, the plates
// and grains are removed by moving particles apart along the line of centres
// (Heyes & Melrose 1993, J. Non-Newtonian Fluid Mech. 46:1), so no contact
// stiffness limits the step. The step is chosen so that no particle moves more
// than `max_step_fraction` radii (flow, forces and Brownian rms), not by tau_p.
// A move (or a contact push) that leaves a particle overlapping a grain after
// three pushes along the wall normal is refused: particles never squeeze
// through a throat narrower than themselves (straining).
// Attachment: a particle whose gap to a sticky surface falls below the capture
// distance, or that would have penetrated it, deposits and stays; on the plates
// optionally only when the adhesive torque holds against the shear's
// (AttachmentModel::torque_balance, HydroModel::plateAdhesionHolds).
// Not modelled: the wall correction of the lag for the parabola's curvature (the
// lag is that of the wall's linear shear), in-plane hindrance by grains,
// hydrodynamic interactions between particles, re-entrainment.
#pragma once
#include <memory>
#include <unordered_map>

#include "mmval/core/Checkpoint.hpp"
#include "mmval/particles/HydroModel.hpp"
#include "mmval/particles/Scene.hpp"

namespace mmval::particles {

class OverdampedEngine final : public ParticleEngine {
 public:
  OverdampedEngine(std::shared_ptr<const FlowField> flow, SceneConfig config);
  ~OverdampedEngine() override;
  OverdampedEngine(const OverdampedEngine&) = delete;
  OverdampedEngine& operator=(const OverdampedEngine&) = delete;

  std::string name() const override { return "overdamped"; }
  void insert(const std::vector<Vec3>& positions) override;
  void advance(double t_end) override;
  double time() const override { return m_t; }
  std::vector<ParticleState> particles() const override { return m_particles; }
  Counts counts() const override { return countParticles(m_particles); }
  EngineStats stats() const override { return m_stats; }
  nlohmann::json describe() const override;

  /// Deterministic velocity (flow + M F + Ito drift) of a particle at x, m/s. For tests.
  Vec3 driftVelocity(const Vec3& x) const;
  const HydroModel& model() const { return m_model; }

  /// After the flow field changed (deposits turned cells solid): mobile
  /// particles now inside solid are deposited there (they are part of the
  /// deposit that closed the cell). Returns how many.
  std::int64_t captureInSolid();
  /// Everything that determines the future of the run (time, particles,
  /// statistics, the random generator's state), for checkpoints: a run
  /// restored with loadState() continues bit for bit like the original.
  void saveState(CheckpointWriter& w) const;
  /// Throws std::runtime_error when the data do not fit this engine.
  void loadState(CheckpointReader& r);

 private:
  void step(double dt);
  void resolveContacts();
  void applyWallsAndCapture(ParticleState& p, const Vec3& before);
  /// Uniform [0, 1) draw of a particle's n-th plate arrival (plate attachment efficiency).
  double arrivalDraw(std::int64_t id, std::uint32_t arrival) const;
  double chooseStep(const std::vector<Vec3>& drift) const;  ///< drift indexed like m_mobile
  std::int64_t cellKey(const Vec3& x) const;
  void indexDeposited(int i);
  void compactMobile(double t_event);

  std::shared_ptr<const FlowField> m_flow;
  SceneConfig m_cfg;
  HydroModel m_model;
  double m_radius, m_outlet;
  std::vector<ParticleState> m_particles;
  std::vector<int> m_mobile;  ///< indices of mobile particles, ascending
  std::unordered_map<std::int64_t, std::vector<int>> m_dep_cells;  ///< deposited particles by contact cell
  std::vector<int> m_dep_order;  ///< deposited particles in the order they were indexed (restores m_dep_cells exactly)
  double m_t = 0.0;
  EngineStats m_stats;
  struct Rng;
  std::unique_ptr<Rng> m_rng;
};

}  // namespace mmval::particles
