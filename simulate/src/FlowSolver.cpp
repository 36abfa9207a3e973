#include "mmval/simulate/FlowSolver.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>

#include <fmt/format.h>
#include <petscksp.h>

#include "FlowOperator.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::simulate {

namespace {

void check(PetscErrorCode ierr, const char* what) {
  if (ierr != 0) throw std::runtime_error(fmt::format("PETSc error {} in {}", static_cast<int>(ierr), what));
}

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

struct SteadyFlowSolver::Impl {
  FlowOperator op;
  SolverOptions opt;
  MPI_Comm comm;
  FlowStats stats;
  Mat A = nullptr;
  Vec b = nullptr, x = nullptr;
  KSP ksp = nullptr;
  MatSolverType m_solver = MATSOLVERMUMPS;
  std::vector<double> state;
  Eigen::ArrayXXd u, v, p;

  Impl(FlowProblem prob, SolverOptions o, MPI_Comm c) : op(std::move(prob)), opt(std::move(o)), comm(c) {}

  ~Impl() {
    if (ksp != nullptr) KSPDestroy(&ksp);
    if (A != nullptr) MatDestroy(&A);
    if (b != nullptr) VecDestroy(&b);
    if (x != nullptr) VecDestroy(&x);
  }

  void create() {
    const PetscInt n = op.unknowns();
    check(MatCreate(comm, &A), "MatCreate");
    check(MatSetSizes(A, PETSC_DECIDE, PETSC_DECIDE, n, n), "MatSetSizes");
    check(MatSetType(A, MATAIJ), "MatSetType");
    check(MatSeqAIJSetPreallocation(A, 24, nullptr), "prealloc");
    check(MatMPIAIJSetPreallocation(A, 24, nullptr, 24, nullptr), "prealloc");
    check(MatSetOption(A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE), "MatSetOption");
    check(MatCreateVecs(A, &x, &b), "MatCreateVecs");
    check(KSPCreate(comm, &ksp), "KSPCreate");
    check(KSPSetOptionsPrefix(ksp, "fluid_"), "prefix");
    PC pc;
    check(KSPGetPC(ksp, &pc), "KSPGetPC");
    if (opt.linear == "direct") {
      check(KSPSetType(ksp, KSPPREONLY), "KSPSetType");
      check(PCSetType(pc, PCLU), "PCSetType");
      // Serial: UMFPACK (measured 4x faster than MUMPS here on the 2D saddle-point
      // systems: Debian's MUMPS falls back to the PORD ordering). Parallel: MUMPS.
      int size = 1;
      MPI_Comm_size(comm, &size);
      m_solver = size == 1 ? MATSOLVERUMFPACK : MATSOLVERMUMPS;
      check(PCFactorSetMatSolverType(pc, m_solver), "factor solver");
    } else if (opt.linear == "iterative") {
      check(KSPSetType(ksp, KSPFGMRES), "KSPSetType");
      check(KSPGMRESSetRestart(ksp, 200), "restart");
      check(KSPSetTolerances(ksp, opt.linear_rtol, 1e-30, PETSC_DEFAULT, 5000), "tol");
      check(PCSetType(pc, PCFIELDSPLIT), "fieldsplit");
      PetscInt lo = 0, hi = 0;
      check(MatGetOwnershipRange(A, &lo, &hi), "ownership");
      std::vector<PetscInt> iu, ip;
      for (PetscInt r = lo; r < hi; ++r) (r < op.pressureOffset() ? iu : ip).push_back(r);
      IS isu, isp;
      check(ISCreateGeneral(comm, static_cast<PetscInt>(iu.size()), iu.data(), PETSC_COPY_VALUES, &isu), "IS");
      check(ISCreateGeneral(comm, static_cast<PetscInt>(ip.size()), ip.data(), PETSC_COPY_VALUES, &isp), "IS");
      check(PCFieldSplitSetIS(pc, "0", isu), "IS u");
      check(PCFieldSplitSetIS(pc, "1", isp), "IS p");
      ISDestroy(&isu);
      ISDestroy(&isp);
      check(PCFieldSplitSetType(pc, PC_COMPOSITE_SCHUR), "schur");
      check(PCFieldSplitSetSchurFactType(pc, PC_FIELDSPLIT_SCHUR_FACT_UPPER), "schur fact");
      check(PCFieldSplitSetSchurPre(pc, PC_FIELDSPLIT_SCHUR_PRE_SELFP, nullptr), "selfp");
      auto def = [](const char* k, const char* v) {
        PetscBool has = PETSC_FALSE;
        PetscOptionsHasName(nullptr, nullptr, k, &has);
        if (!has) PetscOptionsSetValue(nullptr, k, v);
      };
      def("-fluid_fieldsplit_0_ksp_type", "preonly");
      def("-fluid_fieldsplit_0_pc_type", "gamg");
      def("-fluid_fieldsplit_1_ksp_type", "preonly");
      def("-fluid_fieldsplit_1_pc_type", "gamg");
    } else {
      throw std::invalid_argument("linear solver must be 'direct' or 'iterative', got '" + opt.linear + "'");
    }
    check(KSPSetFromOptions(ksp), "KSPSetFromOptions");
  }

  /// Assembles the system linearised at `state` (mode: Stokes/Picard/Newton) and solves it into `state`.
  void linearSolve(Linearisation mode) {
    auto t0 = std::chrono::steady_clock::now();
    check(MatZeroEntries(A), "MatZeroEntries");
    check(VecSet(b, 0.0), "VecSet");
    PetscInt lo = 0, hi = 0;
    check(MatGetOwnershipRange(A, &lo, &hi), "ownership");
    RowTerms row;
    std::vector<std::pair<int, double>> entries;
    std::vector<PetscInt> cols;
    std::vector<PetscScalar> vals;
    for (PetscInt r = lo; r < hi; ++r) {
      const double rhs = op.linearRow(static_cast<int>(r), mode, state, row, entries);
      cols.clear();
      vals.clear();
      for (const auto& [c, v] : entries) {
        cols.push_back(c);
        vals.push_back(v);
      }
      const PetscInt rr = r;
      check(MatSetValues(A, 1, &rr, static_cast<PetscInt>(cols.size()), cols.data(), vals.data(), ADD_VALUES), "MatSetValues");
      check(VecSetValue(b, r, rhs, INSERT_VALUES), "VecSetValue");
    }
    check(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY), "assembly");
    check(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY), "assembly");
    check(VecAssemblyBegin(b), "vec assembly");
    check(VecAssemblyEnd(b), "vec assembly");
    stats.assemble_seconds += seconds(t0);
    t0 = std::chrono::steady_clock::now();
    check(KSPSetOperators(ksp, A, A), "KSPSetOperators");
    if (opt.linear == "direct" && stats.linear_iterations == 0 && std::string(m_solver) == MATSOLVERMUMPS) {
      PC pc;
      KSPGetPC(ksp, &pc);
      check(PCFactorSetUpMatSolverType(pc), "mumps setup");
      Mat F;
      check(PCFactorGetMatrix(pc, &F), "factor matrix");
      check(MatMumpsSetIcntl(F, 14, 200), "mumps icntl 14");  // workspace headroom for saddle-point pivoting
    }
    check(KSPSolve(ksp, b, x), "KSPSolve");
    KSPConvergedReason reason;
    KSPGetConvergedReason(ksp, &reason);
    if (reason < 0) throw std::runtime_error(fmt::format("the fluid linear solve failed ({})", KSPConvergedReasons[reason]));
    PetscInt its = 0;
    KSPGetIterationNumber(ksp, &its);
    stats.linear_iterations += std::max<PetscInt>(its, 1);
    stats.solve_seconds += seconds(t0);
    gather();
  }

  void gather() {
    VecScatter sc;
    Vec all;
    check(VecScatterCreateToAll(x, &sc, &all), "scatter");
    check(VecScatterBegin(sc, x, all, INSERT_VALUES, SCATTER_FORWARD), "scatter");
    check(VecScatterEnd(sc, x, all, INSERT_VALUES, SCATTER_FORWARD), "scatter");
    const PetscScalar* a = nullptr;
    VecGetArrayRead(all, &a);
    state.assign(a, a + op.unknowns());
    VecRestoreArrayRead(all, &a);
    VecScatterDestroy(&sc);
    VecDestroy(&all);
    for (double s : state)
      if (!std::isfinite(s)) throw std::runtime_error("the fluid solution is not finite (NaN or Inf)");
  }

  double velocityMax(const std::vector<double>& s) const {
    double m = 0;
    for (int k = 0; k < op.pressureOffset(); ++k) m = std::max(m, std::abs(s[static_cast<std::size_t>(k)]));
    return m;
  }

  void solve() {
    stats = {};
    stats.unknowns = op.unknowns();
    stats.cells = static_cast<long long>(op.nx()) * op.ny();
    if (ksp == nullptr) create();
    state.assign(static_cast<std::size_t>(op.unknowns()), 0.0);
    linearSolve(Linearisation::stokes);
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
    op.unpack(state, u, v, p);
  }
};

SteadyFlowSolver::SteadyFlowSolver(FlowProblem problem, SolverOptions options, MPI_Comm comm) {
  PetscSession::ensure();
  m = std::make_unique<Impl>(std::move(problem), std::move(options), comm);
}

SteadyFlowSolver::~SteadyFlowSolver() = default;

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

}  // namespace mmval::simulate
