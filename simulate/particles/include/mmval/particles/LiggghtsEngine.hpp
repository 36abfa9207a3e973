// LIGGGHTS 3.8 driven in-process (the Debian libliggghts-dev): Hertz normal contact with
// damping and tangential history (+ sjkr cohesion), the chip's plates (and a
// channel's side walls) as primitive walls, Newton-Euler integration
// (nve/sphere). The paper's particle physics, resolved in time.
//
// Fluid forces enter through `fix external pf/callback 1 1`, evaluated every
// DEM step on each rank's own atoms (per-rank pointers, no global arrays).
// The drag is integrated exactly for a constant fluid velocity and force over
// a step: with nve/sphere the half-step velocity obeys v' = v + dt F / m, so
//   F = (m / dt) (1 - exp(-K dt / m)) (u + F_other / K - v),   K = 6 pi mu a lambda,
// makes v' relax exponentially with tau = m / K for any dt (an implicit drag
// path with the same intent as couple/cfd/force/implicit). F_other includes the
// contact forces already accumulated, gravity-buoyancy and attraction
// (HydroModel, shared with the overdamped engine). A Stokes torque 8 pi mu a^3
// relaxes the spin towards half the fluid vorticity the same way.
// Deposited particles (capture rule of AttachmentModel) and particles past the
// outlet are frozen in place by the same callback. Grains of a gridded field are
// an STL mesh wall (LiggghtsInput.hpp). Not modelled here: Brownian motion,
// attachment to deposited particles (sjkr cohesion stands in).
//
// Time step (paper Eq. 14, adjusted at run time): each advance() first sets
// dt = min(dt0, t_Hertz(2 v_max) / 20), v_max the fastest mobile particle (2 v_max:
// a head-on pair), dt0 the setup's step (a fraction of the Rayleigh time, and the
// Hertz time at the flow's speed); LIGGGHTS gets a `timestep` command when it
// changes. The fluid forces are exchanged every DEM step (the coupling interval
// of the paper's Eq. 15 is 1: the steady Stokes field needs no time step of its
// own, Eq. 13's Courant limit belongs to UnsteadyFlowSolver).
#pragma once
#ifndef MMVAL_WITH_LIGGGHTS
#error "LiggghtsEngine.hpp needs the LIGGGHTS engine (configure with MMVAL_WITH_LIGGGHTS=ON)"
#endif
#include <mpi.h>

#include <memory>

#include "mmval/particles/HydroModel.hpp"
#include "mmval/particles/LiggghtsInput.hpp"
#include "mmval/particles/Scene.hpp"

namespace mmval::particles {

class LiggghtsEngine final : public ParticleEngine {
 public:
  /// Opens LIGGGHTS on `comm` (MPI is initialised if nobody did) and issues the
  /// validated setup. Throws InputError for scenes it cannot model.
  LiggghtsEngine(std::shared_ptr<const FlowField> flow, SceneConfig config, MPI_Comm comm = MPI_COMM_WORLD);
  ~LiggghtsEngine() override;
  LiggghtsEngine(const LiggghtsEngine&) = delete;
  LiggghtsEngine& operator=(const LiggghtsEngine&) = delete;

  std::string name() const override { return "liggghts"; }
  void insert(const std::vector<Vec3>& positions) override;
  /// Runs round((t_end - time()) / dt) DEM steps.
  void advance(double t_end) override;
  double time() const override { return m_t; }
  std::vector<ParticleState> particles() const override { return m_particles; }
  Counts counts() const override { return countParticles(m_particles); }
  EngineStats stats() const override { return m_stats; }
  nlohmann::json describe() const override;
  /// The version this LIGGGHTS library reports, as the first line of its log
  /// prints it (liggghtsVersionFromHeader), e.g. "LIGGGHTS-PUBLIC 3.8.0, compiled ...".
  std::string engineVersion() const override { return m_version; }
  double dt() const { return m_setup.dt; }
  /// Sets the velocity of particle `id` (m/s), e.g. for collision tests.
  void setVelocity(std::int64_t id, const Vec3& v);
  const LiggghtsSetup& setup() const { return m_setup; }

  /// Called by the fix external callback (public for the C callback only).
  void applyFluidForces(long long ntimestep, int nlocal, int* tag, double** x, double** fext);

 private:
  void command(const std::string& c);
  void gather();
  /// Eq. 14 at run time: dt from the fastest mobile particle (see the file comment).
  void retime();

  std::shared_ptr<const FlowField> m_flow;
  SceneConfig m_cfg;
  HydroModel m_model;
  MPI_Comm m_comm;
  LiggghtsSetup m_setup;
  void* m_lmp = nullptr;
  std::string m_version;
  double m_outlet = 0.0;
  double m_t = 0.0;
  double m_t_base = 0.0;      ///< time at LIGGGHTS step m_step_base (the last dt change)
  long long m_step_base = 0;  ///< LIGGGHTS step count at m_t_base
  double m_dt0 = 0.0;         ///< the setup's step: the largest dt ever used
  bool m_need_setup = true;   ///< next run must re-run the setup (after insertion)
  std::vector<ParticleState> m_particles;  ///< by id - 1
  std::vector<std::uint8_t> m_status;      ///< by id - 1; updated per rank, merged after each run
  std::vector<double> m_event;             ///< by id - 1; time of deposition / leaving, +inf before
  EngineStats m_stats;
};

}  // namespace mmval::particles
