// Incompressible flow on a staggered (MAC) Cartesian grid with immersed solids.
//
// Discretisation. Pressure lives at cell centres, u on x-faces, v on
// y-faces (Harlow & Welch 1965). The discrete divergence of the face
// velocities is exactly the continuity constraint, so the solution is
// divergence-free to solver tolerance and there is no pressure checkerboard;
// a collocated grid would need Rhie-Chow interpolation to get the same.
// Momentum is a conservative finite-volume balance on each face's control
// volume (viscous fluxes from neighbouring face values, convective fluxes
// U * u with linearly interpolated advecting and advected velocities:
// central, energy-conserving on uniform grids). Axes may be stretched.
//
// Solids (a Shape), two treatments:
//  - penalized: the paper's marker-function method u = M u* + (1 - M) v
//    (Shirgaonkar et al. 2009), M = 1 - chi with chi the face control
//    volume's solid fraction from s x s supersampling. In the steady implicit
//    form each face's equation is (1 - chi) [momentum] + chi a_P (u - v) = 0,
//    a_P the equation's diagonal: a Brinkman-type penalty a_P chi / (1 - chi)
//    that blends smoothly through cut cells (a plain mu / eta penalty with
//    tiny eta would block every face that a body merely touches). First order
//    in h at the surface.
//  - sharp: faces whose node lies inside a body are set to the body velocity;
//    a fluid face next to the surface takes its viscous flux from the exact
//    wall distance theta * h along the grid line (a Shortley-Weller-type cut
//    of the stencil, Shortley & Weller 1938; the finite-volume form as in
//    Kirkpatrick, Armfield & Kent 2003). Second order in the velocity.
//    Continuity counts the fluid part of faces the surface crosses. A cell
//    whose centre lies inside a body is merged into the neighbour across its
//    most open fluid face (cell merging, as in Ye, Mittal, Udaykumar & Shyy
//    1999): the pair shares one pressure and one mass balance. Unmerged, such
//    a cell's balance sees only its fluid faces (the slivers of its faces
//    whose nodes are solid carry no flux), so it held those faces' flow near
//    zero and moved the wall by a fraction of a cell: a first-order error
//    (FlowProblem::merge_cut_cells).
// Cells that exchange pressure (through fluid velocity nodes and merges) but
// reach no pressure boundary, e.g. a pocket enclosed by a body, have no
// pressure level: one cell of each such component is pinned to p = 0 (its
// continuity row depends on the others), so the system is never singular.
// Force on a body: the sum, over every face whose equation the immersed
// boundary changed, of the residual of the unchanged momentum balance
// (-sum R). Because the balance is conservative this equals the momentum
// control-volume integral around the body, for both treatments.
//
// Quasi-2D chips: a depth h adds the depth-averaged Hele-Shaw friction
// -12 mu u / h^2 (plane Poiseuille profile across the depth), making the 2D
// equations the Brinkman-Hele-Shaw model. The depth may vary per cell
// (FlowProblem::depth_field): then continuity is div(h u) = 0.
//
// Solution. The coupled (u, v, p) system is assembled into one PETSc matrix.
// Stokes is one linear solve; steady Navier-Stokes is Newton's method on the
// quadratic convective term starting from the Stokes solution. Linear
// solves: "direct" (UMFPACK LU serial, MUMPS parallel) or "iterative" (FGMRES
// with a Schur fieldsplit: for Stokes without friction, BoomerAMG on the
// velocity block and the pressure mass matrix / mu for the Schur complement,
// iteration counts ~independent of N, continued with the selfp approximation
// when the residual has not fallen 5000-fold in 40 iterations (dense narrow
// throats); with Hele-Shaw friction or inertia, GAMG and selfp). Time stepping: UnsteadyFlowSolver. Every
// rank assembles its rows of a replicated grid and receives the whole
// solution: simple and exact under MPI for 2D sizes (the grid, not the
// factorisation, is replicated).
#pragma once
#include <array>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <mpi.h>

#include "mmval/core/Error.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"

namespace mmval::simulate {

/// The flow solve failed on a valid problem: the solution is not finite, a linear solve diverged,
/// an unsteady flow blew up. A NumericalFailure (exit 5) that names no case key (solvers do not
/// know them; one place, the kind, knows the option names): the case kind that chose the resolution rethrows withKey(its key).
class FlowFailure : public NumericalFailure {
 public:
  /// `key`: the case key the advice is about, when the failure knows it better than its caller
  /// (the linear solver's own failures: numerics.linear_solver); withKey then keeps it.
  FlowFailure(std::string cause, std::string advice, std::string key = "")
      : NumericalFailure(cause, key, advice), m_cause(std::move(cause)), m_advice(std::move(advice)), m_key(std::move(key)) {}
  const std::string& cause() const noexcept { return m_cause; }
  const std::string& advice() const noexcept { return m_advice; }
  /// The same failure naming the case key to change ("cause; change 'key': advice"): its own key
  /// when it was thrown with one, else `key`.
  NumericalFailure withKey(const std::string& key) const { return NumericalFailure(m_cause, m_key.empty() ? key : m_key, m_advice); }

 private:
  std::string m_cause, m_advice, m_key;
};

/// Thrown by the coupled solves (CoupledSystem) when the linear solver's library fails inside PETSc (PETSc
/// errors PETSC_ERR_LIB or PETSC_ERR_MEM: UMFPACK's or MUMPS's factorisation out of memory, a
/// failed allocation), instead of an unnamed PETSc error: the run says which solver failed on
/// how many unknowns and what to change (exit 5), and "auto" can try the other solver.
class LinearSolverFailure : public FlowFailure {
 public:
  LinearSolverFailure(std::string cause, std::string advice, bool direct) : FlowFailure(std::move(cause), std::move(advice)), m_direct(direct) {}
  bool direct() const noexcept { return m_direct; }

 private:
  bool m_direct;
};

enum class Side { west = 0, east = 1, south = 2, north = 3 };

enum class BoundaryType {
  no_slip,   ///< wall: zero velocity
  slip,      ///< symmetry: zero normal velocity, zero tangential stress
  velocity,  ///< given normal velocity (inflow profile), zero tangential velocity
  pressure,  ///< given pressure, zero normal gradient of velocity (open inflow/outflow)
  periodic,  ///< both sides of the axis must be periodic
};

struct Boundary {
  BoundaryType type = BoundaryType::no_slip;
  /// velocity: velocity component along the axis normal to this side (+x on
  /// west/east, +y on south/north), m/s, as a function of the coordinate along the side.
  std::function<double(double)> velocity;
  double pressure = 0;  ///< pressure: value, Pa
};

enum class ImmersedMethod { penalized, sharp };

/// Rigid motion of one body: velocity of its reference point (Shape::centre) and spin about it.
struct RigidMotion {
  Eigen::Vector2d velocity{0, 0};  ///< m/s
  double spin = 0;                 ///< rad/s, counter-clockwise
};

struct FlowProblem {
  Axis x, y;
  std::array<Boundary, 4> boundary;  ///< indexed by Side
  double density = 1000;             ///< kg/m3
  double viscosity = 1e-3;           ///< Pa s
  double depth = 0;                  ///< chip depth for the Hele-Shaw friction, m; 0: plane 2D
  /// Optional local depth (aperture) h(x, y) per cell, m, ny x nx (row j = y cell, column i = x cell);
  /// empty: `depth` everywhere. Needs depth > 0, which becomes the reference depth h_ref. Variable
  /// aperture (Reynolds lubrication / Hele-Shaw, e.g. Zimmerman & Bodvarsson 1996): each face gets
  /// the friction -12 mu u / h_f^2 of its own depth h_f, and continuity conserves the flux h u,
  /// sum(h_f u_f A_f) = 0, so the friction-dominated limit is the Reynolds equation
  /// div(h^3 grad p) = 0. h_f between two cells is the harmonic mean of h^3 (exact for a step in
  /// depth at the face, in that limit); the Brinkman term stays mu lap(u). flowRate and
  /// superficialVelocity then weight each face by h_f / h_ref (flux per unit reference depth).
  Eigen::ArrayXXd depth_field;
  Eigen::Vector2d body_force{0, 0};  ///< N/m3 (a mean pressure gradient -dp/dx for periodic flow)
  std::shared_ptr<const Shape> shape;  ///< solids; null: all fluid
  /// Rigid motion per body of `shape` (empty: all at rest). The no-slip condition on a body is then
  /// u = U + spin x (x - centre): sharp nodes inside the body take it, and a cut viscous flux takes
  /// it at the surface point; the penalized forcing drives towards it. Creeping-flow use (the mobility
  /// problems of ResolvedStokes); an unsteady run keeps its bodies at rest.
  std::vector<RigidMotion> body_motion;
  ImmersedMethod method = ImmersedMethod::sharp;
  int supersample = 6;               ///< penalized: samples per face control volume and direction
  double penalty = 1e-8;             ///< penalized: floor of 1 - chi (caps the penalty in fully solid faces)
  bool inertia = false;              ///< steady Navier-Stokes (true) or Stokes (false)
  /// Sharp: merge each cell whose centre is inside a body (and that has a fluid face) into a
  /// neighbour's pressure and mass balance (see the header). false: every cell keeps its own.
  bool merge_cut_cells = true;
};

struct SolverOptions {
  /// "direct" (UMFPACK / MUMPS LU), "iterative" (FGMRES + Schur fieldsplit) or "auto": the steady
  /// solver picks by chooseLinearSolver and, if an iterative solve it chose does not converge,
  /// solves again with the direct LU once (when that fits in memory). The unsteady solver and
  /// ResolvedStokes keep their LU: "auto" is "direct" there.
  std::string linear = "direct";
  int max_newton = 30;
  double newton_tolerance = 1e-8;  ///< max |du| / max |u|
  double linear_rtol = 1e-10;      ///< iterative only
  int linear_max_iterations = 5000;  ///< iterative only: FGMRES iterations before the solve counts as failed
  /// "auto" only: one line on stderr (rank 0) when the choice is iterative or the direct fallback ran.
  bool announce_choice = false;
  /// Direct solver, Stokes: re-solves after SteadyFlowSolver::update keep the linear solver.
  /// A factorisation of a matrix with the pattern of the last one is numeric only (the ordering
  /// and symbolic analysis are kept); a matrix of another pattern (the sharp method's solid
  /// nodes, cut stencils and merged cells follow the geometry) is assembled, ordered and
  /// analysed as a new solver does it. Either way the answer is a new solver's, bit for bit.
  /// warm_max_iterations > 0: the LU factors of an earlier geometry first precondition
  /// GMRES on the changed one, from the last solution; when GMRES has not converged within that
  /// many iterations the solve factorises the current matrix and keeps those factors.
  bool keep_factorisation = false;
  int warm_max_iterations = 0;
  /// Warm start: GMRES tolerance, relative to the preconditioned right-hand side (the LU-
  /// preconditioned residual estimates the error against the direct answer).
  double warm_rtol = 1e-12;
  /// Direct solver, Stokes: re-solves keep the first problem's matrix pattern for the solver's
  /// life, so that a geometry that only closes faces and cells (deposits) or changes depths is a
  /// numeric factorisation with the first problem's ordering and symbolic analysis. The kept
  /// pattern is the first problem's, plus the entries a cell that closes (pinned) or a merged cell
  /// that changes master needs (FlowOperator::keptPattern); a later problem's rows are assembled
  /// into it with explicit zeros (a closed face: the identity row u = 0 inside its old stencil).
  /// A problem whose rows do not fit (a face that opens, a merge beyond the neighbours) is solved
  /// once by a new solver (ordering, symbolic analysis), and the kept one serves the next problem.
  /// The answer is a new solver's to rounding (not bit for bit: the ordering is the first
  /// problem's), and it depends only on the first problem and the current one.
  bool fixed_pattern = false;
};

struct BodyLoad {
  Eigen::Vector2d force{0, 0};  ///< force of the fluid on the body per unit depth, N/m
  double torque = 0;            ///< about the body's centre, per unit depth, N
};

struct FlowStats {
  long long unknowns = 0;
  long long cells = 0;
  int newton_iterations = 0;
  int linear_iterations = 0;     ///< summed over the solves (1 per direct solve)
  double assemble_seconds = 0, solve_seconds = 0;
  double update_norm = 0;        ///< last Newton update, relative
  bool converged = true;
  int factorisations = 0;        ///< LU factorisations in this solve (direct solver)
  std::string linear_solver;     ///< the linear solver that produced the solution: "direct" or "iterative"
  std::string linear_reason;     ///< why (numerics.linear_solver = "auto": the rule that chose it; else "requested")
  bool linear_fallback = false;  ///< "auto"'s choice failed and the other solver solved instead (iterative -> direct, or direct -> iterative)
  /// The iterative solver's accepted answer: its true relative residual ||b - A x|| / ||b||
  /// (CoupledSystem::lastTrueResidual, checked against 100 x the tolerance); NaN after a direct solve.
  double linear_true_residual = std::numeric_limits<double>::quiet_NaN();
  /// Plane Stokes solved iteratively: the velocity block's preconditioner (CoupledSystem::velocityPreconditioner); else empty.
  std::string velocity_preconditioner;
  /// fixed_pattern: the solve factorised into the kept pattern, numerically only (not the first
  /// solve, nor one whose rows did not fit and took a new solver).
  bool pattern_kept = false;
};

/// What numerics.linear_solver = "auto" picks for a steady problem, and why.
struct LinearChoice {
  std::string solver;  ///< "direct" or "iterative"
  std::string reason;
};

/// Unknowns from which "auto" picks the iterative solver on one rank (plane Stokes, analytic
/// solids, periodic on every side): 64^2 cells of the square array (12288 unknowns), where it was
/// 3.3x faster than UMFPACK (0.056 s against 0.182 s) with the same F*; below it both take under
/// 0.1 s and the direct solve cannot fail to converge (docs/validation/linear-solver.md).
inline constexpr long long kAutoIterativeUnknowns = 12000;
/// FGMRES budget of an "auto"-chosen iterative solve: the square array converges in ~50
/// iterations at every measured size, so a solve that needs 10x that has stalled and falls back
/// (SolverOptions::linear_max_iterations caps it further). 1000 since the switched Schur
/// solve's second stage runs LGMRES(30) (CoupledSystem.cpp kSelfpRestart): memory no longer grows
/// with iterations, and a mask needing ~420 GMRES(200) iterations there needs ~670 (Pore2Chip
/// forced to selfp), which a fallback after an LU out of memory must still reach.
inline constexpr int kAutoIterativeMaxIterations = 1000;

/// The "auto" rule: "iterative" only where it was measured to converge and win (plane Stokes, no
/// depth friction, analytic circles or no solid, periodic on every side, at least
/// kAutoIterativeUnknowns unknowns or more than one rank); "direct" otherwise (masks: FGMRES stalled on
/// narrow throats; depth-averaged: it stalled on the micromodel; inertia: not measured).
LinearChoice chooseLinearSolver(const FlowProblem& problem, long long unknowns, int ranks);

/// Creeping flow through a periodic square array of cylinders (Sangani & Acrivos):
/// one cell of side L on an n x n grid, periodic on all sides, one cylinder of
/// solid fraction phi at the centre, driven by the mean pressure gradient G (Pa/m).
FlowProblem squareArrayProblem(double L, int n, double phi, double viscosity, double G);

class SteadyFlowSolver {
 public:
  /// Checks the problem (periodic sides pairwise, velocity profiles present);
  /// throws std::invalid_argument. PETSc is initialised on first use.
  explicit SteadyFlowSolver(FlowProblem problem, SolverOptions options = {}, MPI_Comm comm = MPI_COMM_WORLD);
  ~SteadyFlowSolver();
  SteadyFlowSolver(const SteadyFlowSolver&) = delete;
  SteadyFlowSolver& operator=(const SteadyFlowSolver&) = delete;

  /// Replaces the problem by one on the same grid (axes, boundary types and inertia setting;
  /// e.g. other solids or depths). With SolverOptions::keep_factorisation the linear solver is
  /// kept (its ordering and symbolic analysis while the matrix pattern stays; with
  /// warm_max_iterations > 0 also its factors and the last solution as GMRES's start);
  /// otherwise the next solve() is a new solver's.
  /// Throws std::invalid_argument when the grid differs.
  void update(FlowProblem problem);

  /// Solves; throws FlowFailure (a NumericalFailure, exit 5) if a linear solve fails or the
  /// solution is not finite, naming the narrowest throat when the grid does not resolve it
  /// (Newton non-convergence is reported in the stats).
  const FlowStats& solve();

  const FlowProblem& problem() const;
  const FlowStats& stats() const;
  int nx() const;
  int ny() const;
  /// Face velocities and cell pressures (after solve). u: ny x (nx+1) (periodic x: last column repeats the first),
  /// v: (ny+1) x nx, p: ny x nx.
  const Eigen::ArrayXXd& u() const;
  const Eigen::ArrayXXd& v() const;
  const Eigen::ArrayXXd& p() const;
  /// Loads on every body of the shape.
  std::vector<BodyLoad> bodyLoads() const;
  /// Pressure at a point by bilinear interpolation of fluid cell centres; at a
  /// solid surface (e.g. a stagnation point) it is extrapolated quadratically
  /// from the fluid side along x.
  double pressureAt(double x, double y) const;
  /// Volume flux through a side per unit depth, m2/s, positive along +x / +y.
  double flowRate(Side side) const;
  /// Domain average of u over all cells (solids count as zero): the Darcy velocity, m/s.
  double superficialVelocity() const;
  /// max |div u| * h / max |u| over cells.
  double maxRelativeDivergence() const;
  /// Cell-centred velocity (averaged from faces), components ny x nx.
  Eigen::ArrayXXd cellVelocity(int component) const;
  /// Cell solid fraction used by the solver (penalized: supersampled; sharp: centre inside).
  Eigen::ArrayXXd cellSolidFraction() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace mmval::simulate
