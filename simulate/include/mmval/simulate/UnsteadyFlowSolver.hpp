// Unsteady incompressible Navier-Stokes on the MAC grid of SteadyFlowSolver,
// with the same immersed boundaries, boundary conditions and linear solvers.
//
// Time discretisation: second-order backward differences (BDF2) with variable
// step, rho (a0 u^{n+1} - a1 u^n + a2 u^{n-1}) / dt, omega = dt_n / dt_{n-1},
// a0 = (1 + 2 omega) / (1 + omega), a1 = 1 + omega, a2 = omega^2 / (1 + omega)
// (the first step is backward Euler, omega = 0). The convective term is
// linearised about the second-order extrapolation u* = (1 + omega) u^n -
// omega u^{n-1}: div(u* u^{n+1}), viscous and pressure terms implicit, the
// incompressibility constraint exact at every step. One coupled linear solve
// per step, second order in time (a linearly implicit BDF2 scheme; e.g.
// Varoglu & Finn's extrapolated Picard form, analysed by Baker, Dougalis &
// Karakashian 1982). No pressure splitting error, and the sharp immersed
// boundary and the pressure outlet are treated exactly as in the steady solver.
//
// Time step: adaptive, dt = C_max / max over cells of (|u|/dx + |v|/dy) with the
// current velocity (the boundary velocity before the flow starts), growing by
// at most `max_growth` per step (variable-step BDF2 is zero-stable for
// omega < 1 + sqrt 2). The implicit viscous term puts no diffusive limit on dt;
// the Courant limit keeps the explicit extrapolation of the advecting velocity
// accurate and the scheme stable.
//
// Coupling: a coupling loop calls advance(dt) (sub-stepped to the Courant
// limit), may change the solids between steps (setShape) or the drive
// (setBodyForce), and reads bodyLoads(). Divergence (non-finite values, or a
// velocity beyond `blowup_factor` x the velocity scale) throws FlowFailure with
// the time, step and a remedy, and leaves the last good state in place: never NaN.
#pragma once
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <mpi.h>

#include "mmval/core/Checkpoint.hpp"
#include "mmval/simulate/FlowSolver.hpp"

namespace mmval::simulate {

/// How a step solves for velocity and pressure: one coupled solve (lagged LU + GMRES; the
/// continuity and momentum exact to 1e-10), or incremental pressure correction (a velocity
/// predictor, a pressure Poisson solve by algebraic multigrid, a velocity correction; the
/// continuity exact to the Poisson tolerance, the momentum up to the O(dt^2) splitting error;
/// no factorisation: memory and time per step ~ linear in the cells).
enum class UnsteadyMethod { coupled, projection };

struct UnsteadyOptions {
  UnsteadyMethod method = UnsteadyMethod::coupled;
  double projection_rtol = 1e-8;  ///< projection: relative tolerance of its velocity and pressure solves
  /// projection: predictor-correction sweeps per step (1: the standard scheme; more approach the
  /// coupled solve). The first step sweeps until the pressure settles (its increment is the whole
  /// initial pressure, not O(dt)).
  int projection_sweeps = 1;
  /// projection: the rotational pressure update p = p^n + dp - mu div u' (Timmermans, Minev &
  /// Van de Vosse 1996) instead of p = p^n + dp (ProjectionStep.hpp).
  bool projection_rotational = false;
  double max_courant = 1.0;     ///< Courant limit (dimensionless), in (0, 4]
  double max_growth = 1.25;     ///< largest dt_n / dt_{n-1}, in (1, 2.4]
  double blowup_factor = 20;    ///< max |u| above this x the velocity scale counts as divergence
  double velocity_scale = 0;    ///< m/s; 0: the largest prescribed boundary velocity
};

struct StepStats {
  long long steps = 0;          ///< time steps taken so far
  long long reduced_steps = 0;  ///< advance() calls whose dt was cut to the Courant limit
  double last_dt = 0;           ///< s
  double last_courant = 0;      ///< Courant number of the last step
  double max_courant = 0;       ///< largest Courant number of any step
  std::string warning;          ///< the last dt reduction, empty if none
  /// Projection method: wall time and iterations of the velocity predictor and of the pressure
  /// correction (with the correction of the velocity), summed over the steps.
  double velocity_seconds = 0, pressure_seconds = 0;
  long long velocity_iterations = 0, pressure_iterations = 0;
};

class UnsteadyFlowSolver {
 public:
  /// Starts at t = 0 from rest (or setVelocity). `problem.inertia` is ignored
  /// (always Navier-Stokes). Throws std::invalid_argument on a bad problem or options.
  UnsteadyFlowSolver(FlowProblem problem, SolverOptions options = {}, UnsteadyOptions unsteady = {}, MPI_Comm comm = MPI_COMM_WORLD);
  ~UnsteadyFlowSolver();
  UnsteadyFlowSolver(const UnsteadyFlowSolver&) = delete;
  UnsteadyFlowSolver& operator=(const UnsteadyFlowSolver&) = delete;

  /// Advances the solution by exactly dt_s seconds (> 0) in as many steps as
  /// the Courant limit needs; if that is more than one, records a warning in
  /// stepStats() (and logs it once). Returns the number of steps taken.
  /// Throws FlowFailure (a NumericalFailure, exit 5) on divergence (state stays at the last good step).
  int advance(double dt_s);
  /// One step of min(dt_max_s, stableTimeStep()); returns the step taken, s.
  double step(double dt_max_s);
  /// Largest step the Courant limit allows now (current velocity), s.
  double stableTimeStep() const;

  /// Initial condition: face velocities from a function of position (m -> m/s).
  void setVelocity(const std::function<Eigen::Vector2d(double, double)>& velocity);
  /// Replaces the solids (resting bodies) between steps; the state is kept.
  void setShape(std::shared_ptr<const Shape> shape);
  /// Replaces the uniform body force, N/m3.
  void setBodyForce(const Eigen::Vector2d& force);

  double time() const;  ///< s
  const StepStats& stepStats() const;
  const FlowStats& stats() const;  ///< cells, unknowns, summed solve times and linear iterations
  const FlowProblem& problem() const;
  int nx() const;
  int ny() const;
  /// Loads on every body at the current time (per unit depth).
  std::vector<BodyLoad> bodyLoads() const;
  double pressureAt(double x, double y) const;
  double maxRelativeDivergence() const;
  /// Largest |face velocity|, m/s.
  double maxVelocity() const;
  Eigen::ArrayXXd cellVelocity(int component) const;
  /// Cell solid fraction used by the solver (as SteadyFlowSolver).
  Eigen::ArrayXXd cellSolidFraction() const;
  /// Face velocities and pressure as in SteadyFlowSolver.
  void fields(Eigen::ArrayXXd& u, Eigen::ArrayXXd& v, Eigen::ArrayXXd& p) const;

  /// Checkpoint and restart: everything the next step needs (time, step history, the two
  /// velocity levels and the pressure, the last step's history term, and where the lagged LU
  /// came from: the transient coefficient and linearised state of its first and its last
  /// factorisation, and whether the next step refactorises; for the projection method its last
  /// pressure increment, the next step's initial guess) and the summed statistics, all as
  /// binary doubles. loadState needs a solver built from the same problem and options; it refuses
  /// a state of another grid or format (std::runtime_error naming the checkpoint). It rebuilds
  /// the LU from the same matrices in the same order, so a resumed run continues bit for bit like
  /// an uninterrupted one (direct linear solver, same rank count, no setShape since the start;
  /// after setShape, to the GMRES tolerance 1e-10).
  void saveState(CheckpointWriter& w) const;
  void loadState(CheckpointReader& r);

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace mmval::simulate
