// Internal: one time step of UnsteadyFlowSolver by incremental pressure correction
// (a fractional-step / projection method) instead of the coupled velocity-pressure solve.
//
// The step's linear system is the coupled solver's, [A G; D C] [u; p] = [f; g], built row by
// row from the same FlowOperator (BDF2 transient term, Picard convection about the
// extrapolated velocity, sharp immersed boundary, merged and pinned cells, pressure outlet).
// It is split algebraically (Perot 1993, "An analysis of the fractional step method"; the
// incremental form of Van Kan 1986 with the pressure of the last step in the predictor):
//   1. velocity predictor   A u' = f - G p^n                    (GMRES, ILU(0))
//   2. pressure correction  -D M^-1 G dp = g - D u' - C p^n       (LU made once; CG, BoomerAMG on several ranks)
//   3. velocity correction  u = u' - M^-1 G dp,  p = p^n + dp  [- mu div u']
// with M = (rho a0 / dt) V, the transient term's diagonal (V: the rows' control volumes, as
// the momentum rows weigh them). D u + C p = g holds to the pressure solve's tolerance after
// every step: the continuity is exact as in the coupled solve. What the split leaves is the
// momentum residual (A - M) M^-1 G dp, O(dt) times the pressure increment dp = O(dt): the
// splitting error of incremental pressure correction, second order in dt for the velocity
// with BDF2 (Guermond, Minev & Shen 2006, section 3.3).
// [- mu div u'] is the rotational form (Timmermans, Minev & Van de Vosse 1996; Guermond, Minev &
// Shen 2006, section 3.4): with A - M = -mu Laplacian, the identity Laplacian = grad div - curl
// curl makes G (-mu div u') cancel the viscous part of the residual, and the pressure loses the
// O(dt) numerical boundary layer of the standard form. div u' is read from the continuity
// residual (the outflow of u' over the cell's fluid area). Off by default: it moved the tests'
// split errors by < 3 % (no walls, or a viscous number << 1) and the unconfined Re 100 cylinder's
// c_D and St by < 1e-4; on 2D-2 (viscous number ~1 on the finest cells) it is not measured yet. An extrapolated predictor
// pressure, p^n + w (p^n - p^{n-1}), cut the Taylor-Green split error 300x but made the unconfined
// Re 100 cylinder drift (docs/validation/cylinder-unsteady.md, 2026-12-05): not kept.
// The pressure matrix -D M^-1 G depends on the geometry only, up to the factor rho a0 / dt,
// so it is factorised once (one rank: an LU, two triangular solves per step) or its multigrid
// hierarchy is built once (several ranks), and again after setShape. Pinned cells and merged
// cells' own pressures carry no continuity flux: they enter the pressure solve as identity
// rows, and a merged cell takes its master's increment afterwards.
#pragma once
#include <memory>
#include <vector>

#include <mpi.h>

#include "FlowOperator.hpp"

namespace mmval::simulate {

struct ProjectionTimings {
  double assemble_seconds = 0;  ///< linearising the rows and filling the velocity matrix
  double velocity_seconds = 0;  ///< predictor solve
  double pressure_seconds = 0;  ///< pressure-correction solve
  /// Krylov iterations; a direct pressure solve counts 1 per solve.
  long long velocity_iterations = 0, pressure_iterations = 0;
  double setup_seconds = 0;     ///< the pressure matrix and its factorisation or multigrid hierarchy
};

class ProjectionStep {
 public:
  /// `op` must be the operator the steps use; its transient term is changed here (set to the
  /// mass of the rows and back to none) and the caller sets it again afterwards.
  /// velocity_rtol, pressure_rtol: relative tolerances of the two iterative solves.
  /// rotational: the pressure update p = p^n + dp - mu div u' (see above); false (the default, and
  /// UnsteadyFlowSolver's): p = p^n + dp.
  ProjectionStep(FlowOperator& op, MPI_Comm comm, double velocity_rtol, double pressure_rtol, bool rotational = false);
  ~ProjectionStep();
  ProjectionStep(const ProjectionStep&) = delete;
  ProjectionStep& operator=(const ProjectionStep&) = delete;

  /// One step with the transient term coef = rho a0 / dt and `history` (rho times the history
  /// terms / dt per unknown, as FlowOperator::setTransient takes them). `state` holds the
  /// advecting (extrapolated) velocity and the last pressure on entry and the new velocity and
  /// pressure on return. Throws FlowFailure when a solve fails.
  /// sweeps > 1: repeats predictor and correction with the corrected pressure (the matrix
  /// stays) until max |dp| <= sweep_tolerance max |p| or `sweeps` sweeps; each sweep shrinks the
  /// splitting error by about |A - M| / |M|, and the limit is the coupled solve's answer. The
  /// first step from an initial velocity without its pressure needs them: its increment is the
  /// whole pressure, not O(dt). Returns the sweeps taken.
  int step(const FlowOperator& op, double coef, const std::vector<double>& history, std::vector<double>& state, FlowStats& stats, int sweeps = 1,
           double sweep_tolerance = 0);
  /// Re-reads the velocity rows' constant parts (after FlowOperator::setBodyForce); the
  /// operator's transient term must be off.
  void refreshRows(const FlowOperator& op);

  const ProjectionTimings& timings() const;
  /// The last step's pressure change p^{n+1} - p^n (zero on pinned and merged cells), the next
  /// step's initial guess for an iterative pressure solve (the direct one needs none); part of a
  /// restart state (empty before the first step and after a start-up step swept to a tolerance).
  const std::vector<double>& lastIncrement() const;
  void setLastIncrement(std::vector<double> dp);

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace mmval::simulate
