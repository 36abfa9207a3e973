// Internal: the PETSc side of the fluid solvers. Owns the coupled (u, v, p)
// matrix, its vectors and the KSP; assembles the system a FlowOperator
// linearises at a state and solves it into that state. Shared by
// SteadyFlowSolver (Stokes / Newton) and UnsteadyFlowSolver (one linearised
// solve per time step), so both use the same linear solvers and options.
#pragma once
#include <memory>
#include <stdexcept>
#include <vector>

#include <mpi.h>

#include "FlowOperator.hpp"
#include "mmval/simulate/FlowSolver.hpp"

namespace mmval::simulate {

/// Thrown by CoupledSystem::solve when a row's own entries do not lie within the operator's
/// kept pattern (FlowOperator::setPattern); nothing has been changed then (the system, `state`).
struct PatternMiss : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class CoupledSystem {
 public:
  /// options.linear: "direct" (UMFPACK serial, ordered by METIS from 1e5 unknowns; MUMPS parallel) or "iterative"
  /// (FGMRES + Schur fieldsplit, at most options.linear_max_iterations: depth-averaged Stokes by the LU of
  /// B diag(A)^-1 B^T and a Gauss-Seidel sweep on A, prefix "fluidh_"; plane Stokes by the scaled pressure
  /// mass matrix, prefix "fluidm_", switching to BoomerAMG on B diag(A)^-1 B^T, prefix "fluidp_", when the
  /// residual has not fallen 5000-fold in 40 iterations; inertia by GAMG, prefix "fluid_"); "auto" is "direct" here
  /// (SteadyFlowSolver resolves it before; time stepping keeps its LU); throws std::invalid_argument otherwise.
  CoupledSystem(const FlowOperator& op, const SolverOptions& options, MPI_Comm comm);
  ~CoupledSystem();
  CoupledSystem(const CoupledSystem&) = delete;
  CoupledSystem& operator=(const CoupledSystem&) = delete;

  /// Assembles the system linearised at `state` and overwrites `state` with
  /// its solution (on every rank). Adds timings and iterations to `stats`.
  /// Throws FlowFailure if the solve fails, an iterative answer's true residual is too large (see
  /// lastTrueResidual) or the result is not finite, std::runtime_error on
  /// a PETSc error (`state` is then left unchanged), PatternMiss when the operator has a kept
  /// pattern that a row does not fit (found while assembling, before anything changed).
  void solve(const FlowOperator& op, Linearisation mode, std::vector<double>& state, FlowStats& stats);

  /// Direct solver only: keep the LU factorisation of an earlier matrix and use
  /// it to precondition GMRES on the current one (state is the initial guess),
  /// refactorising when GMRES needs more than `max_iterations`. For time
  /// stepping, where the matrix changes by O(dt) per step: a few triangular
  /// solves per step instead of a factorisation; the answer is the same to the
  /// GMRES tolerance `rtol`.
  void setLaggedFactorisation(int max_iterations, double rtol);
  /// The next solve refactorises (the operator's geometry changed).
  void invalidate();
  /// Lagged factorisation: whether the next solve refactorises. Part of a time stepper's
  /// restart state, with the states the kept LU was computed at (see factorise).
  bool refactorPending() const;
  void setRefactorPending(bool pending);
  /// Lagged factorisation only (else nothing): factorises the system linearised at `state`
  /// without solving, as a solve that refactorises does. A restart calls it with the states of
  /// the first factorisation (PETSc computes the LU's ordering once, from the first matrix) and
  /// of the last, so the kept LU, and with it every later GMRES iterate, is bit for bit the one
  /// of the uninterrupted run.
  void factorise(const FlowOperator& op, Linearisation mode, const std::vector<double>& state);
  /// Factorisations so far (direct solver).
  int factorisations() const;
  /// Iterative plane Stokes: the last solve's GMRES iterations with the pressure mass matrix
  /// before it switched to selfp for the Schur complement (0: no switch), and the relative
  /// residual reached then.
  int schurSwitchIterations() const;
  double schurSwitchResidual() const;
  /// Iterative solver: the true relative residual ||b - A x|| / ||b|| of the last solve's answer
  /// (2-norms, the assembled A), checked against 100 times options.linear_rtol before the answer is
  /// kept: a solve PETSc reports converged above that bound throws FlowFailure ("true residual X
  /// above Y") as one that did not converge. NaN after a direct solve or a failed one.
  double lastTrueResidual() const;
  /// Plane Stokes solved iteratively: the velocity block's preconditioner of the last solve (one
  /// BoomerAMG over both components, or on two ranks one component per rank: ComponentSplit.hpp);
  /// empty for other solves.
  const std::string& velocityPreconditioner() const;

  /// Direct solver only (else nothing): solves of a steady system whose matrix changes between
  /// solves (SteadyFlowSolver::update). A factorisation of a matrix with the last one's pattern is
  /// numeric only: the ordering and symbolic analysis are kept (they depend on the pattern). A
  /// matrix of another pattern is assembled into a new matrix and factorised by a new KSP, as a
  /// new solver would (zeroed entries of the old pattern would change the LU's ordering). Either
  /// way the plain LU solve (preonly) gives the direct path's answer bit for bit.
  /// max_iterations > 0: a solve first runs GMRES on the current matrix from the incoming
  /// `state`, preconditioned by the kept LU factors, and factorises only when GMRES has not
  /// reached `rtol` (relative to the preconditioned right-hand side) within that budget.
  /// The first solve factorises.
  void setWarmStart(int max_iterations, double rtol);
  /// Warm start whose ordering and symbolic analysis serve a whole run (SolverOptions::fixed_pattern):
  /// large systems are ordered for the least fill, whatever the search costs (see kKeptOrdering).
  void setKeptAnalysis();
  /// Warm start: GMRES iterations of the last solve (0 when it went straight to the LU) and
  /// whether it factorised.
  int lastWarmIterations() const;
  bool lastFactorised() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace mmval::simulate
