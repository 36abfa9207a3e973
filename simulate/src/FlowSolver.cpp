#include "mmval/simulate/FlowSolver.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

#include "CoupledSystem.hpp"
#include "FlowOperator.hpp"
#include "MemoryBudget.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/simulate/Petsc.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::simulate {

struct SteadyFlowSolver::Impl {
  FlowOperator op;
  SolverOptions opt;
  MPI_Comm comm;
  FlowStats stats;
  std::unique_ptr<CoupledSystem> sys;
  std::vector<double> state;
  Eigen::ArrayXXd u, v, p;

  /// fixed_pattern: the kept pattern (from the first problem), whether the current operator's rows
  /// fit in it, and the kept solver while a problem that does not fit has a new one.
  std::shared_ptr<const RowPattern> kept;
  bool fits = true;
  std::unique_ptr<CoupledSystem> parked;
  bool automatic = false;  ///< options.linear was "auto": opt.linear holds its choice
  LinearChoice choice;
  bool fell_back = false;

  Impl(FlowProblem prob, SolverOptions o, MPI_Comm c) : op(std::move(prob)), opt(std::move(o)), comm(c) {
    automatic = opt.linear == "auto";
    if (!automatic) choice = {opt.linear, "requested"};
  }

  /// "iterative" requested for depth-averaged Stokes (the friction split of CoupledSystem): a solve
  /// whose FGMRES does not converge is solved again by the direct LU (said on stderr), and the
  /// next solve tries the split again.
  bool frictionSplit() const { return !automatic && choice.solver == "iterative" && !op.problem().inertia && op.problem().depth > 0; }

  bool warm() const { return opt.keep_factorisation && opt.linear == "direct" && !op.problem().inertia; }
  bool fixed() const { return opt.fixed_pattern && opt.linear == "direct" && !op.problem().inertia; }

  /// "auto": picks the solver for the current problem (a new choice for each new linear solver).
  void choose() {
    if (!automatic) return;
    int ranks = 1;
    MPI_Comm_size(comm, &ranks);
    choice = chooseLinearSolver(op.problem(), op.unknowns(), ranks);
    fell_back = false;
    opt.linear = choice.solver;
    if (choice.solver == "iterative") opt.linear_max_iterations = std::min(opt.linear_max_iterations, kAutoIterativeMaxIterations);
    announce("");
  }

  /// The terminal line: a fallback every time, the iterative choice once per process (a ladder's levels repeat it).
  void announce(const std::string& what) const {
    static std::atomic<bool> told_iterative{false};
    if (!opt.announce_choice || (choice.solver != "iterative" && what.empty())) return;
    if (what.empty() && told_iterative.exchange(true)) return;
    int rank = 0;
    MPI_Comm_rank(comm, &rank);
    if (rank != 0) return;
    const std::string line = what.empty() ? fmt::format("mmval: linear solver: iterative (numerics.linear_solver = \"auto\": {})", choice.reason) : what;
    std::fprintf(stderr, "%s\n", line.c_str());
  }

  /// An "auto"-chosen iterative solve, or the friction split's, failed: the direct LU solves instead,
  /// once, when its measured memory per cell fits within the default memory limit. Returns whether it switched.
  bool fallBack(const FlowFailure& e) {
    if (const auto* lib = dynamic_cast<const LinearSolverFailure*>(&e); lib != nullptr && lib->direct()) return fallBackToIterative(*lib);
    const bool split = frictionSplit();
    if ((!automatic && !split) || fell_back || opt.linear != "iterative") return false;
    const double need = detail::steadyFlowBytes(static_cast<double>(op.nx()) * op.ny(), false);
    if (need > defaultMaxMemoryBytes()) return false;
    fell_back = true;
    opt.linear = "direct";
    choice.reason += fmt::format("; the iterative solve failed ({}), so the direct LU solved instead", e.cause());
    sys = std::make_unique<CoupledSystem>(op, opt, comm);
    if (split) {
      int rank = 0;
      MPI_Comm_rank(comm, &rank);
      if (rank == 0) std::fprintf(stderr, "mmval: fluid solve: the block-preconditioned FGMRES did not converge: %s; solved again with the direct LU\n", e.cause().c_str());
    } else {
      announce(fmt::format("mmval: linear solver: the auto-chosen iterative solve failed ({}); solved again with the direct LU", e.cause()));
    }
    return true;
  }

  /// An "auto"-chosen direct LU that its library could not factorise (UMFPACK out of memory:
  /// Pore2Chip at 2 cells per pixel, 3.0M unknowns, 2026-12-05): the iterative solver tries once,
  /// said on stderr and in the ladder's reason; if it does not converge either, the run stops
  /// naming both failures.
  bool fallBackToIterative(const LinearSolverFailure& e) {
    if (!automatic || fell_back || opt.linear != "direct") return false;
    fell_back = true;
    opt.linear = "iterative";
    opt.linear_max_iterations = std::min(opt.linear_max_iterations, kAutoIterativeMaxIterations);
    choice.solver = "iterative";
    choice.reason += fmt::format("; the direct LU failed ({}), so the iterative solver solved instead", e.cause());
    sys.reset();  // the failed LU's memory goes before the iterative solver's is taken
    sys = std::make_unique<CoupledSystem>(op, opt, comm);
    announce(fmt::format("mmval: linear solver: the auto-chosen direct LU failed ({}); solving with the iterative solver", e.cause()));
    return true;
  }

  void linearSolve(Linearisation mode) {
    try {
      try {
        sys->solve(op, mode, state, stats);  // on failure `state` is unchanged: a retry starts where this one did
      } catch (const FlowFailure& e) {
        if (!fallBack(e)) throw;
        sys->solve(op, mode, state, stats);
      }
    } catch (const LinearSolverFailure&) {
      throw;  // the solver's library failed (memory): its own advice names the solver to change, not the grid
    } catch (const FlowFailure& e) {  // not finite, or the linear solver diverged: say whether the grid resolves the flow path
      const std::string throat = throatDiagnosis();
      if (throat.empty() && !e.key().empty()) throw;  // a resolved flow path, and a failure naming its own key (a wrong Krylov answer)
      throw FlowFailure(e.cause() + throat, "refine the grid until every throat of the flow path is at least 2 cells wide");
    }
  }

  /// ": the narrowest throat ... is 0.73 cells wide" when the grid does not resolve the flow path (under 2 cells); else "".
  std::string throatDiagnosis() const {
    const FlowProblem& p = op.problem();
    if (!p.shape) return "";
    const double h = std::min(p.x.minWidth(), p.y.minWidth());
    const bool px = p.boundary[0].type == BoundaryType::periodic, py = p.boundary[2].type == BoundaryType::periodic;
    const Throat t = narrowestThroat(*p.shape, p.x.lo(), p.x.hi(), p.y.lo(), p.y.hi(), h / 8, px, py);
    if (!t.path) return ": no fluid path joins the inlet to the outlet";
    const double cells = t.width_m / h;
    return cells < 2 ? fmt::format(": the narrowest throat of the flow path, at x = {:.4g} m, y = {:.4g} m, is {:.2f} cells wide", t.x_m, t.y_m, cells) : "";
  }

  double velocityMax(const std::vector<double>& s) const {
    double m = 0;
    for (int k = 0; k < op.pressureOffset(); ++k) m = std::max(m, std::abs(s[static_cast<std::size_t>(k)]));
    return m;
  }

  /// Fixed pattern, rows beyond it: this problem gets a new solver; the kept one is parked and
  /// serves the next problem (solve hands it back).
  void parkKeptSolver() {
    parked = std::move(sys);
    sys = std::make_unique<CoupledSystem>(op, opt, comm);
  }

  void solve() {
    stats = {};
    stats.unknowns = op.unknowns();
    stats.cells = static_cast<long long>(op.nx()) * op.ny();
    if (parked) sys = std::move(parked);  // an earlier solve on a new solver threw before handing back
    if (fell_back && !automatic) {  // the friction split fell back last time: this solve tries it again
      opt.linear = "iterative";
      choice = {opt.linear, "requested"};
      fell_back = false;
      sys.reset();
    }
    const bool first = !sys;
    if (!sys) {
      choose();
      if (fixed()) {
        kept = std::make_shared<const RowPattern>(op.keptPattern());
        op.setPattern(kept);
        fits = true;
      }
      sys = std::make_unique<CoupledSystem>(op, opt, comm);
      if (warm() || fixed()) sys->setWarmStart(fixed() ? 0 : opt.warm_max_iterations, opt.warm_rtol);
      if (fixed()) sys->setKeptAnalysis();
    }
    if (fixed() && !fits) parkKeptSolver();
    int factorised_before = sys->factorisations();
    // Warm start: the last solution is the GMRES initial guess; otherwise start from rest.
    if (!warm() || opt.warm_max_iterations <= 0 || state.size() != static_cast<std::size_t>(op.unknowns())) state.assign(static_cast<std::size_t>(op.unknowns()), 0.0);
    try {
      linearSolve(Linearisation::stokes);
    } catch (const PatternMiss&) {  // the rows, as assembled, go beyond the kept pattern
      fits = false;
      op.setPattern(nullptr);
      parkKeptSolver();
      factorised_before = 0;
      linearSolve(Linearisation::stokes);
    }
    if (op.problem().inertia) {
      for (int k = 0; k < opt.max_newton; ++k) {
        const std::vector<double> old = state;
        linearSolve(k < 1 ? Linearisation::picard : Linearisation::newton);
        ++stats.newton_iterations;
        double d = 0;
        for (int i = 0; i < op.pressureOffset(); ++i) d = std::max(d, std::abs(state[static_cast<std::size_t>(i)] - old[static_cast<std::size_t>(i)]));
        const double umax = velocityMax(state);
        stats.update_norm = umax > 0 ? d / umax : d;
        if (stats.update_norm < opt.newton_tolerance) break;
      }
      stats.converged = stats.update_norm < std::max(opt.newton_tolerance, 1e-6);
    }
    stats.factorisations = fell_back ? sys->factorisations() : sys->factorisations() - factorised_before;
    stats.linear_solver = opt.linear;
    stats.linear_reason = choice.reason;
    if (sys->schurSwitchIterations() > 0)  // the iterative solve changed its Schur preconditioner (CoupledSystem)
      stats.linear_reason += fmt::format("; Schur preconditioner: the pressure mass matrix for {} iterations (residual {:.2g} of the first), then selfp",
                                         sys->schurSwitchIterations(), sys->schurSwitchResidual());
    stats.linear_fallback = fell_back;
    stats.linear_true_residual = sys->lastTrueResidual();
    stats.velocity_preconditioner = opt.linear == "iterative" ? sys->velocityPreconditioner() : std::string();
    stats.pattern_kept = fixed() && fits && !first;
    if (parked) sys = std::move(parked);  // the new solver's factors go; the kept pattern's solver serves the next problem
    op.unpack(state, u, v, p);
  }

  void update(FlowProblem problem) {
    const FlowProblem& old = op.problem();
    const auto same = [](const Axis& a, const Axis& b) {  // the same grid: identical faces, not close ones
      if (a.cells() != b.cells()) return false;
      for (int k = 0; k <= a.cells(); ++k)
        if (a.face(k) != b.face(k)) return false;
      return true;
    };
    bool ok = same(old.x, problem.x) && same(old.y, problem.y) && old.inertia == problem.inertia;
    for (std::size_t s = 0; s < old.boundary.size(); ++s) ok = ok && old.boundary[s].type == problem.boundary[s].type;
    if (!ok) throw std::invalid_argument("SteadyFlowSolver::update: the new problem must keep the grid, the boundary types and the inertia setting");
    op = FlowOperator(std::move(problem));
    if (fixed() && kept) {
      // Whether the rows fit in the kept pattern is found while the solve assembles them
      // (CoupledSystem throws PatternMiss before it changes anything; see solve).
      fits = kept->rows() == op.unknowns();
      if (fits) op.setPattern(kept);
      return;
    }
    if (!warm()) sys.reset();  // nothing of the old matrix is reused: the next solve is a new solver's
  }
};

SteadyFlowSolver::SteadyFlowSolver(FlowProblem problem, SolverOptions options, MPI_Comm comm) {
  PetscSession::ensure();
  m = std::make_unique<Impl>(std::move(problem), std::move(options), comm);
}

SteadyFlowSolver::~SteadyFlowSolver() = default;

void SteadyFlowSolver::update(FlowProblem problem) { m->update(std::move(problem)); }

const FlowStats& SteadyFlowSolver::solve() {
  m->solve();
  return m->stats;
}

const FlowProblem& SteadyFlowSolver::problem() const { return m->op.problem(); }
const FlowStats& SteadyFlowSolver::stats() const { return m->stats; }
int SteadyFlowSolver::nx() const { return m->op.nx(); }
int SteadyFlowSolver::ny() const { return m->op.ny(); }
const Eigen::ArrayXXd& SteadyFlowSolver::u() const { return m->u; }
const Eigen::ArrayXXd& SteadyFlowSolver::v() const { return m->v; }
const Eigen::ArrayXXd& SteadyFlowSolver::p() const { return m->p; }
std::vector<BodyLoad> SteadyFlowSolver::bodyLoads() const { return m->op.bodyLoads(m->state); }
double SteadyFlowSolver::pressureAt(double x, double y) const { return m->op.pressureAt(m->state, x, y); }
double SteadyFlowSolver::flowRate(Side side) const { return m->op.flowRate(m->state, side); }
double SteadyFlowSolver::superficialVelocity() const { return m->op.superficialVelocity(m->state); }
double SteadyFlowSolver::maxRelativeDivergence() const { return m->op.maxRelativeDivergence(m->state); }
Eigen::ArrayXXd SteadyFlowSolver::cellVelocity(int component) const { return m->op.cellVelocity(m->state, component); }
Eigen::ArrayXXd SteadyFlowSolver::cellSolidFraction() const { return m->op.cellSolidFraction(); }

LinearChoice chooseLinearSolver(const FlowProblem& p, long long unknowns, int ranks) {
  if (p.inertia) return {"direct", "Navier-Stokes (inertia): the iterative solver is not measured there"};
  if (p.depth > 0 || p.depth_field.size() > 0)
    return {"direct", "depth-averaged (Hele-Shaw friction): the Schur fieldsplit stalled on the micromodel"};
  if (p.shape && dynamic_cast<const Circles*>(p.shape.get()) == nullptr)
    return {"direct", "solids from a mask: FGMRES did not converge on narrow throats"};
  for (const Boundary& b : p.boundary)
    if (b.type != BoundaryType::periodic) return {"direct", "not periodic on every side: the iterative solver is measured on periodic arrays only"};
  if (ranks > 1) return {"iterative", fmt::format("plane Stokes, analytic solids, periodic, {} ranks (MUMPS on 2 ranks was 5.4x slower than on 1)", ranks)};
  if (unknowns < kAutoIterativeUnknowns)
    return {"direct", fmt::format("plane Stokes, analytic solids, periodic, {} unknowns < {}: both solvers take under 0.1 s", unknowns, kAutoIterativeUnknowns)};
  return {"iterative", fmt::format("plane Stokes, analytic solids, periodic, {} unknowns >= {}: 3-10x faster than the direct LU (measured)", unknowns,
                                   kAutoIterativeUnknowns)};
}

FlowProblem squareArrayProblem(double L, int n, double phi, double viscosity, double G) {
  FlowProblem p;
  p.x = uniformAxis(0, L, n);
  p.y = uniformAxis(0, L, n);
  for (auto& b : p.boundary) b.type = BoundaryType::periodic;
  p.viscosity = viscosity;
  p.body_force = {G, 0};
  p.shape = std::make_shared<Circles>(std::vector<Circle>{{0.5 * L, 0.5 * L, L * std::sqrt(phi / M_PI)}}, L, L);
  return p;
}

}  // namespace mmval::simulate
