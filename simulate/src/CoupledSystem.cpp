#include "CoupledSystem.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include <fmt/format.h>
#include <petscksp.h>

#include "ComponentSplit.hpp"
#include "SolverUtil.hpp"

namespace mmval::simulate {

using detail::check;
using detail::secondsSince;

/// Unknowns from which the serial LU orders by METIS (see solve()).
constexpr long long kMetisUnknowns = 100000;
/// The ordering of an analysis kept for a whole run (setKeptAnalysis), from kMetisUnknowns:
/// UMFPACK's BEST, the least fill of AMD, METIS and CHOLMOD's nested dissection, its search paid
/// once. Pore2Chip at 1 cell per pixel (~750k unknowns, the opt-in WarmResolve benchmark with
/// MMVAL_BENCH_FIXED, OpenBLAS with 1 thread, alternating on the shared 2-core machine): a re-solve
/// 4.57-4.79 s CPU against 4.82-5.03 s with METIS; k the same to 3e-12, the velocities to 1.1e-8
/// of the largest (METIS against another METIS-ordered LU of the same matrix: 1.6e-9).
constexpr const char* kKeptOrdering = "BEST";

/// Plane Stokes, iterative: GMRES with the pressure mass matrix for the Schur complement runs
/// kProbeIterations; if the residual has not fallen below kProbeDrop of the right-hand side's by
/// then, the solve continues from that iterate with selfp (see switchToSelfp). Measured
/// (docs/validation/linear-solver.md, 1 cell per pixel, rtol 1e-10): at 40 iterations the open
/// Pore2Chip mask was at 3.6e-5 (it converges in 70), the square array at 724^2 converged in 40,
/// and the narrow-throat chip was at 9.7e-4 (it needs 649 with the mass matrix alone).
/// PETSc option -fluidm_schur_switch_iterations N moves the probe to iteration N (0: never switch).
constexpr int kProbeIterations = 40;
constexpr double kProbeDrop = 2e-4;

/// The second stage's Krylov method (see switchToSelfp): LGMRES restarted after 30 iterations,
/// preconditioned on the right as the first stage. Its Krylov basis had been two thirds of the
/// switched solve's peak: GMRES(200) keeps one 6 MB vector per iteration at 751k unknowns, ~170
/// for the 164 iterations chip2 needs at 2 cells/px. LGMRES carries two error approximations
/// from one restart cycle into the next (PETSc's default augmentation), which recovers part of
/// what a short restart loses. Measured on chip2 at 2 cells/px (250k cells; iterations mass +
/// second stage, peak resident, user CPU of runs made back to back on the shared machine;
/// docs/validation/linear-solver.md, "A shorter second stage"):
///   GMRES(200) 204, 1.52 GB, 29.3 s; GMRES(50) 298, 0.81 GB, 27.5 s; GMRES(40) 340, 0.75 GB,
///   28.3 s; GMRES(30) 386, 0.69 GB, 32.8 s; LGMRES(30) 367, 0.72 GB, 25.6 s; BiCGStab 247,
///   0.69 GB, 27.6 s. k the same to 2e-7 in all (the LU's agrees with them to 3e-7). At 0.69 GB
///   the peak is the first stage's (GMRES(200) after 40 iterations), the floor below which the
///   second stage's method no longer counts. The constant-memory methods were not robust: IBiCGStab
///   diverged, and BiCGStab(L) and TFQMR stopped "converged" at a wrong answer (k -2e-8 and -1e15 D;
///   the true-residual check, kTrueResidualFactor, now rejects it).
/// The cost is iterations: Pore2Chip forced to selfp from iteration 1 needed 666 against 417 (in
/// 65 s against 155 s), beyond the 500 auto's fallback had, hence its 1000 (kAutoIterativeMaxIterations).
constexpr PetscInt kSelfpRestart = 30;
constexpr KSPType kSelfpKrylov = KSPLGMRES;

/// The iterative solver's answer (SolverOptions::linear "iterative") is accepted only when its
/// true residual ||b - A x|| / ||b|| (one MatMult with the assembled A) is at most
/// kTrueResidualFactor times the relative tolerance asked for (SolverOptions::linear_rtol; PETSc
/// options may change how the answer is reached, not how accurate it must be). PETSc's convergence
/// test reads the residual the Krylov method carries, the true one up to round-off for the
/// right-preconditioned GMRES and LGMRES used here, but not for every method PETSc options can
/// select: with the second stage set to BiCGStab(L) or TFQMR, chip2 at 2 cells/px stopped
/// "converged" at k = -2e-8 D and -1e15 D, true residuals 1.6e-3 and 9.5e10. Normal answers
/// measured 3.0e-11 to 1.07e-10 at rtol 1e-10 (chip2 9.9e-11; the inertia split's GMRES stops 7 %
/// above rtol), so the factor leaves two decades above them and five below the wrong ones
/// (docs/validation/linear-solver.md, "The true residual of every iterative answer").
/// Not checked: the GMRES of the lagged and warm-started LU (setLaggedFactorisation,
/// setWarmStart), whose test is on the LU-preconditioned residual, an error measure by design: their
/// true residuals reached 100 and 1000 times their rtol on correct answers.
constexpr double kTrueResidualFactor = 100;

/// The convergence test of the mass-matrix stage: PETSc's default test, and at kProbeIterations
/// a stop (KSP_DIVERGED_ITS, `tripped` set) when the residual is above kProbeDrop of the first.
struct ProbeTest {
  void* dflt = nullptr;  ///< KSPConvergedDefault's context
  int at = kProbeIterations;  ///< the iteration it looks at (0: never)
  bool tripped = false;
  PetscReal r0 = 0, r_at = 0;
  static PetscErrorCode test(KSP k, PetscInt n, PetscReal rnorm, KSPConvergedReason* reason, void* ctx) {
    auto* self = static_cast<ProbeTest*>(ctx);
    const PetscErrorCode ierr = KSPConvergedDefault(k, n, rnorm, reason, self->dflt);
    if (ierr != 0) return ierr;
    if (n == 0) self->r0 = rnorm;
    if (self->at > 0 && *reason == KSP_CONVERGED_ITERATING && n == self->at && rnorm > kProbeDrop * self->r0) {
      self->tripped = true;
      self->r_at = rnorm;
      *reason = KSP_DIVERGED_ITS;
    }
    return 0;
  }
};

struct CoupledSystem::Impl {
  SolverOptions opt;
  MPI_Comm comm;
  Mat A = nullptr;
  Vec b = nullptr, x = nullptr;
  KSP ksp = nullptr;
  MatSolverType solver = MATSOLVERMUMPS;
  bool factored_once = false;
  int lag_max_its = 0;     ///< > 0: lagged factorisation (see setLaggedFactorisation)
  bool refactor = true;
  int factorisations = 0;
  bool warm = false;        ///< warm-started steady re-solves (see setWarmStart)
  int warm_max_its = 0;     ///< GMRES budget of a warm solve (0: factorise every solve)
  double warm_rtol = 0;
  int warm_its = 0;         ///< GMRES iterations of the last warm-start solve
  bool warm_factorised = false;
  bool mass_schur = false;  ///< iterative Stokes: Schur complement preconditioned by the scaled pressure mass matrix
  bool friction_split = false;  ///< iterative depth-averaged Stokes: Schur complement by the LU of B diag(A)^-1 B^T (see createKsp)
  Mat Sp = nullptr;
  /// Plane Stokes, iterative: the mass matrix's progress after kProbeIterations (ProbeTest) and
  /// the second stage's KSP (selfp) it hands over to when that progress is too slow. Only one
  /// stage is held at a time (see switchToSelfp): after a switched solve both are null, and the
  /// next solve creates the first stage anew.
  ProbeTest probe;
  KSP ksp_selfp = nullptr;
  int switched_at = 0;  ///< the last solve's mass-matrix iterations before the switch to selfp (0: no switch)
  double switched_drop = 0;  ///< and the relative residual it had reached
  /// The last accepted iterative answer's ||b - A x|| / ||b|| (see requireTrueResidual); NaN when
  /// the last solve was not an iterative one (linear "direct") or failed.
  double true_residual = std::numeric_limits<double>::quiet_NaN();
  /// This rank's rows of the last assembly (CSR: row starts, columns, values; right-hand sides).
  std::vector<PetscInt> row_start, cols;
  std::vector<PetscScalar> vals, rhs;
  /// Warm start: the column pattern of A's rows (row_start, cols) as last assembled, and whether
  /// the KSP's LU (its ordering and symbolic analysis) was computed from a matrix of that pattern.
  std::vector<PetscInt> held_start, held_cols;
  bool pc_fits = true;
  bool csr_same = false;  ///< A's compressed rows are (held_start, held_cols) (see insert)
  bool kept_analysis = false;  ///< see setKeptAnalysis
  /// Rows of A on more than one rank. The operator numbers every u, then every v, then every
  /// pressure; PETSc gives each rank a contiguous range of rows, so in that numbering one rank
  /// held all of u and half of v and the other the rest of v and every pressure: the velocity
  /// block, where the iterative solve spends its time, sat 3:1 on the two ranks (square array at
  /// 1024^2 cells, 2 ranks: its preconditioner 8.5 s against 9.3 s on one rank). Here each rank
  /// owns a band of cell rows with its u, v and pressure unknowns (in the operator's order within
  /// the rank), and A, b and x are numbered rank by rank. One rank: the identity (arrays empty).
  std::vector<PetscInt> to_petsc, to_natural;
  PetscInt local_rows = PETSC_DECIDE;
  PetscInt row_lo = 0, row_hi = 0;  ///< this rank's rows of A (PETSc numbering)
  std::string velocity_pc;  ///< the last plane-Stokes iterative solve's velocity-block preconditioner (splitByComponent)
  PetscInt natural(PetscInt g) const { return to_natural.empty() ? g : to_natural[static_cast<std::size_t>(g)]; }
  PetscInt petsc(PetscInt n) const { return to_petsc.empty() ? n : to_petsc[static_cast<std::size_t>(n)]; }

  /// Lays the rows out in bands of cell rows (see to_petsc).
  void layRows(const FlowOperator& op) {
    int size = 1, rank = 0;
    MPI_Comm_size(comm, &size);
    MPI_Comm_rank(comm, &rank);
    to_petsc.clear();
    to_natural.clear();
    local_rows = PETSC_DECIDE;
    row_lo = 0;
    row_hi = op.unknowns();
    if (size == 1) return;
    const long long ny = op.ny(), nx = op.nx();
    const long long u_end = static_cast<long long>(op.normalCount(0)) * ny, p_off = op.pressureOffset();
    const long long nv = op.normalCount(1);
    const auto rankOfRow = [&](long long j) { return static_cast<int>(std::min<long long>(size - 1, std::clamp(j, 0LL, ny - 1) * size / ny)); };
    const auto rankOf = [&](long long n) {
      if (n < u_end) return rankOfRow(n / op.normalCount(0));  // u: row-major by cell row
      if (n < p_off) return rankOfRow((n - u_end) % nv);        // v: column-major, its normal index is the row
      return rankOfRow((n - p_off) / nx);                        // pressure: row-major
    };
    const PetscInt n = op.unknowns();
    std::vector<PetscInt> count(static_cast<std::size_t>(size) + 1, 0);
    for (PetscInt k = 0; k < n; ++k) ++count[static_cast<std::size_t>(rankOf(k)) + 1];
    for (int r = 0; r < size; ++r) count[static_cast<std::size_t>(r) + 1] += count[static_cast<std::size_t>(r)];  // now each rank's first row
    row_lo = count[static_cast<std::size_t>(rank)];
    row_hi = count[static_cast<std::size_t>(rank) + 1];
    local_rows = row_hi - row_lo;
    to_petsc.resize(static_cast<std::size_t>(n));
    to_natural.resize(static_cast<std::size_t>(n));
    for (PetscInt k = 0; k < n; ++k) {
      const PetscInt g = count[static_cast<std::size_t>(rankOf(k))]++;
      to_petsc[static_cast<std::size_t>(k)] = g;
      to_natural[static_cast<std::size_t>(g)] = k;
    }
  }

  /// KSPSolve of the assembled system; a failure inside the solver's library (UMFPACK's or MUMPS's
  /// factorisation out of memory, an allocation) becomes a LinearSolverFailure naming the solver,
  /// the size and the keys to change; any other PETSc error stays an internal one.
  void kspSolve() {
    // PETSc's handler would print its traceback even for a failure recovered below (the direct
    // LU's fallback): errors come back as codes here, and an unrecovered one carries PETSc's text.
    PetscPushErrorHandler(PetscReturnErrorHandler, nullptr);
    const PetscErrorCode ierr = KSPSolve(ksp, b, x);
    PetscPopErrorHandler();
    const bool direct = opt.linear == "direct";
    PC pc = nullptr;
    if (ierr == 0) {
      // A factorisation that failed without a PETSc error (MUMPS: its workspace or memory limit)
      // leaves the KSP diverged with the PC failed; a zero pivot stays the caller's FlowFailure.
      KSPConvergedReason reason;
      KSPGetConvergedReason(ksp, &reason);
      if (!direct || reason != KSP_DIVERGED_PC_FAILED) return;
      PCFailedReason why = PC_NOERROR;
      if (KSPGetPC(ksp, &pc) != 0 || PCGetFailedReason(pc, &why) != 0 || (why != PC_FACTOR_OUTMEMORY && why != PC_FACTOR_OTHER)) return;
    } else if (ierr != PETSC_ERR_LIB && ierr != PETSC_ERR_MEM) {
      const char* text = nullptr;
      char* specific = nullptr;
      PetscErrorMessage(static_cast<int>(ierr), &text, &specific);
      throw std::runtime_error(fmt::format("PETSc error {} in KSPSolve: {}{}{}", static_cast<int>(ierr), text != nullptr ? text : "",
                                           specific != nullptr && *specific != 0 ? ": " : "", specific != nullptr ? specific : ""));
    }
    PetscInt n = 0;
    MatGetSize(A, &n, nullptr);
    MatSolverType used = solver;  // the one a PETSc option chose, if any
    if (direct && (pc != nullptr || KSPGetPC(ksp, &pc) == 0)) PCFactorGetMatSolverType(pc, &used);
    const std::string what = direct ? fmt::format("the direct LU ({}) could not factorise the {} unknowns", used != nullptr ? used : solver, static_cast<long long>(n))
                                    : fmt::format("the iterative solver's preconditioner failed on the {} unknowns", static_cast<long long>(n));
    const std::string how = ierr == 0 ? "the factorisation failed inside the solver's library, typically out of memory or workspace"
                            : fmt::format("PETSc error {}: {} inside the solver's library", static_cast<int>(ierr),
                                          ierr == PETSC_ERR_MEM ? "out of memory" : "a failure, typically out of memory,");
    throw LinearSolverFailure(fmt::format("{} ({})", what, how),
                              direct ? "numerics.linear_solver = \"iterative\" (or \"auto\", which then tries it), or fewer cells (numerics.cells_per_pixel)"
                                     : "numerics.linear_solver = \"direct\", or fewer cells",
                              direct);
  }

  ~Impl() {
    if (ksp != nullptr) KSPDestroy(&ksp);
    if (ksp_selfp != nullptr) KSPDestroy(&ksp_selfp);
    if (probe.dflt != nullptr) KSPConvergedDefaultDestroy(probe.dflt);
    if (Sp != nullptr) MatDestroy(&Sp);
    if (A != nullptr) MatDestroy(&A);
    if (b != nullptr) VecDestroy(&b);
    if (x != nullptr) VecDestroy(&x);
  }

  /// The direct paths create A at once (24 entries per row: room for patterns that change between
  /// solves); the iterative path creates it at its first assembly, with the rows' own counts (the
  /// pattern is the state's for every state there): on the square array at 724^2 cells the 24 per
  /// row had kept ~0.6 kB per cell allocated and unused.
  void create(const FlowOperator& op) {
    layRows(op);
    if (opt.linear != "iterative") ensureMatrix(op);
    createKsp(op);
  }

  void ensureMatrix(const FlowOperator& op) {
    if (A != nullptr) return;
    createMatrix(op);
    if (x == nullptr) check(MatCreateVecs(A, &x, &b), "MatCreateVecs");
  }

  void createMatrix(const FlowOperator& op) {
    const PetscInt n = op.unknowns();
    check(MatCreate(comm, &A), "MatCreate");
    check(MatSetSizes(A, local_rows, local_rows, n, n), "MatSetSizes");
    check(MatSetType(A, MATAIJ), "MatSetType");
    const PetscInt rows = row_hi - row_lo;
    if (opt.linear == "iterative" && static_cast<PetscInt>(row_start.size()) == rows + 1) {
      // Counts from the linearised rows (a column given twice is counted twice: a little spare).
      std::vector<PetscInt> on(static_cast<std::size_t>(rows)), off(static_cast<std::size_t>(rows));
      for (PetscInt k = 0; k < rows; ++k) {
        for (PetscInt e = row_start[static_cast<std::size_t>(k)]; e < row_start[static_cast<std::size_t>(k) + 1]; ++e) {
          const PetscInt c = cols[static_cast<std::size_t>(e)];
          ++(c >= row_lo && c < row_hi ? on : off)[static_cast<std::size_t>(k)];
        }
      }
      check(MatSeqAIJSetPreallocation(A, 0, on.data()), "prealloc");
      check(MatMPIAIJSetPreallocation(A, 0, on.data(), 0, off.data()), "prealloc");
    } else {
      check(MatSeqAIJSetPreallocation(A, 24, nullptr), "prealloc");
      check(MatMPIAIJSetPreallocation(A, 24, nullptr, 24, nullptr), "prealloc");
    }
    check(MatSetOption(A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE), "MatSetOption");
  }

  /// `k` as the iterative path's Krylov method: GMRES preconditioned on the right, restarted after
  /// `restart` iterations. Classical Gram-Schmidt without refinement loses orthogonality on these
  /// badly scaled saddle-point systems: at 128^2 cells the square array stalled at a relative
  /// residual of 1.7e-8 for 160 iterations (bench_simulate_stokes_scaling); a second pass when
  /// needed restores it (converged in 47, like its neighbours in N).
  static void rightGmres(KSP k, PetscInt restart, KSPType type = KSPGMRES) {
    check(KSPSetType(k, type), "KSPSetType");
    check(KSPSetPCSide(k, PC_RIGHT), "PC side");
    check(KSPGMRESSetRestart(k, restart), "restart");
    check(KSPGMRESSetCGSRefinementType(k, KSP_GMRES_CGS_REFINE_IFNEEDED), "CGS refinement");
  }

  /// `k`'s preconditioner: the Schur fieldsplit over (u, v) and p, upper factorisation; selfp: the
  /// Schur complement preconditioned from B diag(A)^-1 B^T (else the caller sets it).
  void splitFields(const FlowOperator& op, KSP k, bool selfp) {
    PC pc;
    check(KSPGetPC(k, &pc), "KSPGetPC");
    check(PCSetType(pc, PCFIELDSPLIT), "fieldsplit");
    std::vector<PetscInt> iu, ip;
    for (PetscInt r = row_lo; r < row_hi; ++r) (natural(r) < op.pressureOffset() ? iu : ip).push_back(r);
    IS isu, isp;
    check(ISCreateGeneral(comm, static_cast<PetscInt>(iu.size()), iu.data(), PETSC_COPY_VALUES, &isu), "IS");
    check(ISCreateGeneral(comm, static_cast<PetscInt>(ip.size()), ip.data(), PETSC_COPY_VALUES, &isp), "IS");
    check(PCFieldSplitSetIS(pc, "0", isu), "IS u");
    check(PCFieldSplitSetIS(pc, "1", isp), "IS p");
    ISDestroy(&isu);
    ISDestroy(&isp);
    check(PCFieldSplitSetType(pc, PC_COMPOSITE_SCHUR), "schur");
    check(PCFieldSplitSetSchurFactType(pc, PC_FIELDSPLIT_SCHUR_FACT_UPPER), "schur fact");
    if (selfp) check(PCFieldSplitSetSchurPre(pc, PC_FIELDSPLIT_SCHUR_PRE_SELFP, nullptr), "selfp");
  }

  /// Plane Stokes on exactly two ranks (both stages): the velocity block preconditioned one
  /// component per rank (ComponentSplit.hpp; off with -<prefix>fieldsplit_0_by_component 0).
  /// Sets `k` up (its fieldsplit's blocks) first: the velocity block's KSP exists only then.
  void splitByComponent(const FlowOperator& op, KSP k, const char* prefix) {
    const std::string user = detail::userVelocityPcType(prefix);
    velocity_pc = user.empty() ? std::string("BoomerAMG on the velocity block") : "-" + std::string(prefix) + "fieldsplit_0_pc_type " + user + " (the user's)";
    if (!detail::componentSplitWanted(comm, prefix, user)) return;
    velocity_pc = "by component: rank 0 u, rank 1 v, a serial BoomerAMG each";
    check(KSPSetUp(k), "KSPSetUp");
    PC vpc = detail::velocityBlockToSplit(k);
    if (vpc == nullptr) return;  // split at an earlier solve of this KSP
    const PetscInt u_end = static_cast<PetscInt>(op.normalCount(0)) * op.ny(), off = op.pressureOffset();
    std::vector<char> is_u;
    for (PetscInt r = row_lo; r < row_hi; ++r)
      if (natural(r) < off) is_u.push_back(natural(r) < u_end ? 1 : 0);
    detail::installComponentSplit(vpc, std::move(is_u));
  }

  /// Plane Stokes, the second stage (see switchToSelfp): GMRES with the Schur complement
  /// preconditioned by BoomerAMG on B diag(A)^-1 B^T ("selfp"), prefix "fluidp_"; created at
  /// the first switch, its options from the database as the first stage's.
  void ensureSelfpKsp(const FlowOperator& op) {
    if (ksp_selfp != nullptr) return;
    check(KSPCreate(comm, &ksp_selfp), "KSPCreate");
    check(KSPSetOptionsPrefix(ksp_selfp, "fluidp_"), "prefix");
    rightGmres(ksp_selfp, kSelfpRestart, kSelfpKrylov);
    splitFields(op, ksp_selfp, true);
    check(KSPSetFromOptions(ksp_selfp), "KSPSetFromOptions");
  }

  /// The KSP and its preconditioner as a new solver sets them up (no factorisation yet).
  void createKsp(const FlowOperator& op) {
    check(KSPCreate(comm, &ksp), "KSPCreate");
    // Stokes without friction or inertia: the Schur complement -B A^-1 B^T is spectrally
    // equivalent to the pressure mass matrix / mu (Silvester & Wathen 1994), which gives
    // grid-independent iteration counts; with friction or inertia the velocity block is
    // mass-like and the diagonal ("selfp") approximation B diag(A)^-1 B^T fits instead.
    //
    // Depth-averaged Stokes (Hele-Shaw friction 12 mu / h^2, no inertia): the velocity block
    // A = mu(-lap) + 12 mu / h^2 is diagonally dominant (10 um cells, 20 um deep: friction 0.03
    // against the Laplacian's 0.04 per um^2, its neighbours summing to 0.04), so diag(A) stands in
    // for A: the Schur complement is preconditioned by the LU of Sp = C - B diag(A)^-1 B^T ("selfp",
    // a variable-coefficient 5-point pressure operator) and A by one symmetric Gauss-Seidel sweep.
    // Pore2Chip at 1 cell per pixel (~750k unknowns, WarmResolve benchmark): 19-20 FGMRES
    // iterations to 1e-12 whether A is solved by one sweep, three, or its own LU (the count is
    // Sp's against the true Schur complement), ~2.7 s CPU per solve against ~5 s for the
    // saddle-point LU, 1.1 GB peak against 2.2 GB. Prefix "fluidh_".
    const FlowProblem& pr = op.problem();
    mass_schur = opt.linear == "iterative" && !pr.inertia && pr.depth == 0;
    friction_split = opt.linear == "iterative" && !pr.inertia && pr.depth > 0;
    check(KSPSetOptionsPrefix(ksp, mass_schur ? "fluidm_" : friction_split ? "fluidh_" : "fluid_"), "prefix");
    PC pc;
    check(KSPGetPC(ksp, &pc), "KSPGetPC");
    if (opt.linear == "direct") {
      check(KSPSetType(ksp, KSPPREONLY), "KSPSetType");
      check(PCSetType(pc, PCLU), "PCSetType");
      // Serial: UMFPACK (measured 4x faster than MUMPS here on the 2D saddle-point
      // systems: Debian's MUMPS falls back to the PORD ordering). Parallel: MUMPS.
      int size = 1;
      MPI_Comm_size(comm, &size);
      solver = size == 1 ? MATSOLVERUMFPACK : MATSOLVERMUMPS;
      check(PCFactorSetMatSolverType(pc, solver), "factor solver");
    } else if (opt.linear == "iterative") {
      // GMRES preconditioned on the right: every preconditioner below (one AMG V-cycle or one
      // Gauss-Seidel sweep per block, a diagonal or an LU for the Schur complement, preonly) is
      // the same linear operator at every iteration, so the flexible variant's second vector per
      // iteration (the preconditioned one) buys nothing. Square array at 724^2 cells (1.57M
      // unknowns): 40 iterations and F* the same to 10 digits as FGMRES, peak 3.6 kB per cell
      // against 4.7 kB.
      // The friction split converges in ~20: a restart at its iteration budget (when smaller)
      // keeps its Krylov vectors (one per iteration, 6 MB each at 750k unknowns) to that budget.
      rightGmres(ksp, friction_split ? std::min(200, std::max(1, opt.linear_max_iterations)) : 200);
      check(KSPSetTolerances(ksp, opt.linear_rtol, 1e-30, PETSC_DEFAULT, opt.linear_max_iterations), "tol");
      splitFields(op, ksp, !mass_schur);
      if (mass_schur) {  // the probe of the mass matrix's progress (see ProbeTest)
        if (probe.dflt == nullptr) check(KSPConvergedDefaultCreate(&probe.dflt), "convergence test");
        check(KSPSetConvergenceTest(ksp, &ProbeTest::test, &probe, nullptr), "convergence test");
      }
      const auto def = detail::defaultOption;
      def("-fluid_fieldsplit_0_ksp_type", "preonly");
      def("-fluid_fieldsplit_0_pc_type", "gamg");
      def("-fluid_fieldsplit_1_ksp_type", "preonly");
      def("-fluid_fieldsplit_1_pc_type", "gamg");
      def("-fluidm_fieldsplit_0_ksp_type", "preonly");
      def("-fluidm_fieldsplit_0_pc_type", detail::kVelocityBlockPcDefault);  // BoomerAMG: steadier than GAMG on the cut-cell velocity block (bench)
      def("-fluidm_fieldsplit_1_ksp_type", "preonly");
      def("-fluidm_fieldsplit_1_pc_type", "jacobi");
      def("-fluidp_fieldsplit_0_ksp_type", "preonly");
      def("-fluidp_fieldsplit_0_pc_type", detail::kVelocityBlockPcDefault);
      def("-fluidp_fieldsplit_1_ksp_type", "preonly");
      def("-fluidp_fieldsplit_1_pc_type", "hypre");  // BoomerAMG on B diag(A)^-1 B^T, a variable-coefficient pressure Laplacian
      def("-fluidh_fieldsplit_0_ksp_type", "preonly");
      def("-fluidh_fieldsplit_0_pc_type", "sor");  // PETSc's default: one local symmetric sweep, omega 1
      def("-fluidh_fieldsplit_1_ksp_type", "preonly");
      def("-fluidh_fieldsplit_1_pc_type", "lu");
      // Serial: UMFPACK with its default ordering (AMD; METIS took 4x longer to analyse Sp and
      // factorised it no faster). Parallel: MUMPS.
      int size = 1;
      MPI_Comm_size(comm, &size);
      def("-fluidh_fieldsplit_1_pc_factor_mat_solver_type", size == 1 ? MATSOLVERUMFPACK : MATSOLVERMUMPS);
    } else {
      throw std::invalid_argument("linear solver must be 'direct' or 'iterative', got '" + opt.linear + "'");
    }
    check(KSPSetFromOptions(ksp), "KSPSetFromOptions");
  }

  /// Assembles A and b linearised at `state` (the matrix pattern is the same for every state).
  void assemble(const FlowOperator& op, Linearisation mode, const std::vector<double>& state) {
    linearise(op, mode, state);
    ensureMatrix(op);
    insert();
    if (opt.linear == "iterative") {  // A holds the rows now; the copy would stay beside the solver's memory
      std::vector<PetscInt>().swap(cols);
      std::vector<PetscScalar>().swap(vals);
    }
  }

  /// This rank's rows of the system linearised at `state` into row_start, cols, vals and rhs.
  void linearise(const FlowOperator& op, Linearisation mode, const std::vector<double>& state) {
    const PetscInt lo = row_lo, hi = row_hi;
    RowTerms row;
    std::vector<std::pair<int, double>> entries;
    bool miss = false;  // a row beyond the operator's kept pattern
    row_start.assign(1, 0);
    cols.clear();
    vals.clear();
    rhs.clear();
    for (PetscInt r = lo; r < hi; ++r) {
      const int nr = static_cast<int>(natural(r));
      rhs.push_back(op.linearRow(nr, mode, state, row, entries));
      miss = miss || !op.rowFitsPattern(nr, entries.size());
      for (const auto& [c, v] : entries) {
        cols.push_back(petsc(c));
        vals.push_back(v);
      }
      row_start.push_back(static_cast<PetscInt>(cols.size()));
    }
    if (op.pattern() != nullptr) {  // every rank throws, or none
      int mine = miss ? 1 : 0, any = 0;
      MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, comm);
      if (any != 0) throw PatternMiss("a row has entries beyond the kept matrix pattern");
    }
  }

  /// Writes the linearised rows into A and b (A keeps its earlier entries' pattern, zeroed).
  /// in_place: the rows have the pattern of A's last assembly (warm start, patternChanged() false);
  /// when A's compressed rows are known to be exactly (row_start, cols), the values are written
  /// into them directly: the bytes MatZeroEntries and MatSetValues(ADD_VALUES) leave (0 + v).
  void insert(bool in_place = false) {
    if (in_place && csr_same) {
      PetscScalar* a = nullptr;
      check(MatSeqAIJGetArrayWrite(A, &a), "MatSeqAIJGetArrayWrite");
      for (std::size_t k = 0; k < vals.size(); ++k) a[k] = 0.0 + vals[k];
      check(MatSeqAIJRestoreArrayWrite(A, &a), "MatSeqAIJRestoreArrayWrite");
      check(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY), "assembly");  // new values: the next PCSetUp factorises
      check(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY), "assembly");
      PetscScalar* bb = nullptr;
      check(VecGetArrayWrite(b, &bb), "VecGetArrayWrite");
      std::copy(rhs.begin(), rhs.end(), bb);
      check(VecRestoreArrayWrite(b, &bb), "VecRestoreArrayWrite");
      return;
    }
    check(MatZeroEntries(A), "MatZeroEntries");
    check(VecSet(b, 0.0), "VecSet");
    PetscInt lo = 0, hi = 0;
    check(MatGetOwnershipRange(A, &lo, &hi), "ownership");
    for (PetscInt r = lo; r < hi; ++r) {
      const std::size_t k = static_cast<std::size_t>(r - lo);
      const PetscInt rr = r, first = row_start[k];
      check(MatSetValues(A, 1, &rr, row_start[k + 1] - first, cols.data() + first, vals.data() + first, ADD_VALUES), "MatSetValues");
      check(VecSetValue(b, r, rhs[k], INSERT_VALUES), "VecSetValue");
    }
    check(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY), "assembly");
    check(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY), "assembly");
    check(VecAssemblyBegin(b), "vec assembly");
    check(VecAssemblyEnd(b), "vec assembly");
    csr_same = warm && csrIsRows();  // warm start only: a plain solve never writes in place
  }

  /// Whether A is a serial AIJ matrix whose compressed rows are exactly (row_start, cols).
  bool csrIsRows() const { return detail::seqAijRowsAre(A, row_start, cols); }

  /// Hands A to the KSP and sets up what the first factorisation needs (MUMPS workspace, the Schur preconditioner).
  void setOperators(const FlowOperator& op) {
    check(KSPSetOperators(ksp, A, A), "KSPSetOperators");
    PetscInt lo = 0, hi = 0;
    check(MatGetOwnershipRange(A, &lo, &hi), "ownership");
    if (mass_schur && Sp == nullptr) buildMassSchur(op, lo, hi);
    if (opt.linear == "direct" && !factored_once && std::string(solver) == MATSOLVERMUMPS) {
      PC pc;
      KSPGetPC(ksp, &pc);
      check(PCFactorSetUpMatSolverType(pc), "mumps setup");
      Mat F;
      check(PCFactorGetMatrix(pc, &F), "factor matrix");
      check(MatMumpsSetIcntl(F, 14, 200), "mumps icntl 14");  // workspace headroom for saddle-point pivoting
    }
    factored_once = true;
  }

  /// UMFPACK's default ordering against METIS nested dissection, steady Stokes LU on the
  /// square array (bench_simulate_stokes_scaling, back to back): 49k unknowns 0.71 s against
  /// 0.99 s, 197k 8.3 s against 6.9 s (and 6.6 against 6.1 with other runs on the cores);
  /// the 2D-2 cylinder at 294k unknowns (57 lagged-LU steps): 45 s and 1.72 GB against 36 s
  /// and 1.12 GB, c_D and c_L the same to 2e-9. So METIS for the large systems only.
  bool wantsMetis(const FlowOperator& op) const { return std::string(solver) == MATSOLVERUMFPACK && op.unknowns() >= kMetisUnknowns; }

  void factorise(const FlowOperator& op, Linearisation mode, const std::vector<double>& state) {
    assemble(op, mode, state);
    const detail::ScopedDefaultOption ordering("-fluid_mat_umfpack_ordering", "METIS", wantsMetis(op));
    setOperators(op);
    check(KSPSetReusePreconditioner(ksp, PETSC_FALSE), "reuse pc");
    check(KSPSetUp(ksp), "KSPSetUp");  // PCSetUp: the LU of this matrix (symbolic on the first call, numeric after)
    ++factorisations;
  }

  /// The initial guess of an iterative solve: this rank's rows of `state`.
  void setGuess(const std::vector<double>& state, PetscInt lo, PetscInt hi) {
    for (PetscInt r = lo; r < hi; ++r) check(VecSetValue(x, r, state[static_cast<std::size_t>(natural(r))], INSERT_VALUES), "VecSetValue");
    check(VecAssemblyBegin(x), "vec assembly");
    check(VecAssemblyEnd(x), "vec assembly");
  }

  /// Assembles the system at `state` (its time counted as assembly); returns this rank's rows.
  std::pair<PetscInt, PetscInt> assembleTimed(const FlowOperator& op, Linearisation mode, const std::vector<double>& state, FlowStats& stats) {
    const auto t0 = std::chrono::steady_clock::now();
    assemble(op, mode, state);
    PetscInt lo = 0, hi = 0;
    check(MatGetOwnershipRange(A, &lo, &hi), "ownership");
    stats.assemble_seconds += secondsSince(t0);
    return {lo, hi};
  }

  void solve(const FlowOperator& op, Linearisation mode, std::vector<double>& state, FlowStats& stats) {
    const auto [lo, hi] = assembleTimed(op, mode, state, stats);
    const auto t0 = std::chrono::steady_clock::now();
    if (ksp == nullptr) {  // released by the last solve's switch: the first stage as createKsp made it
      createKsp(op);
      attachMassSchur();
    }
    const detail::ScopedDefaultOption ordering("-fluid_mat_umfpack_ordering", "METIS", wantsMetis(op));
    setOperators(op);
    if (lag_max_its > 0) {
      // Initial guess: the incoming state (an extrapolation of the solution).
      setGuess(state, lo, hi);
      check(KSPSetReusePreconditioner(ksp, refactor ? PETSC_FALSE : PETSC_TRUE), "reuse pc");
    }
    if (opt.linear == "direct" && (lag_max_its == 0 || refactor)) ++factorisations;
    probe.tripped = false;
    switched_at = 0;
    true_residual = std::numeric_limits<double>::quiet_NaN();
    if (mass_schur) {
      PetscInt at = kProbeIterations;
      check(PetscOptionsGetInt(nullptr, "fluidm_", "-schur_switch_iterations", &at, nullptr), "option");
      probe.at = static_cast<int>(std::max<PetscInt>(0, at));
    }
    if (mass_schur) splitByComponent(op, ksp, "fluidm_");
    kspSolve();
    KSPConvergedReason reason;
    KSPGetConvergedReason(ksp, &reason);
    if (mass_schur && probe.tripped) {
      PetscInt its = 0;
      KSPGetIterationNumber(ksp, &its);
      stats.linear_iterations += static_cast<int>(its);
      switchToSelfp(op);
      KSPGetConvergedReason(ksp_selfp, &reason);
      KSPGetIterationNumber(ksp_selfp, &its);
      stats.linear_iterations += static_cast<int>(its);
      if (reason < 0) {
        releaseSelfp();
        throw FlowFailure(fmt::format("the fluid linear solve failed ({}, after the switch to selfp)", KSPConvergedReasons[reason]), "refine the grid");
      }
      requireTrueResidual(ksp_selfp, reason, ", after the switch to selfp,");  // releases the second stage, as it throws too
      stats.solve_seconds += secondsSince(t0);
      gather(op, state);
      return;
    }
    if (reason < 0 && lag_max_its > 0 && !refactor) {
      // The lagged factorisation is too far from the current matrix: refactorise and retry.
      refactor = true;
      ++factorisations;
      setGuess(state, lo, hi);
      check(KSPSetReusePreconditioner(ksp, PETSC_FALSE), "reuse pc");
      kspSolve();
      KSPGetConvergedReason(ksp, &reason);
    }
    PetscInt its = 0;
    KSPGetIterationNumber(ksp, &its);
    stats.linear_iterations += std::max<PetscInt>(its, 1);  // a failed solve's too (a fallback's cost shows)
    if (reason < 0) throw FlowFailure(fmt::format("the fluid linear solve failed ({})", KSPConvergedReasons[reason]), "refine the grid");
    if (opt.linear == "iterative") requireTrueResidual(ksp, reason, "");
    if (lag_max_its > 0) refactor = its > lag_max_its;
    stats.solve_seconds += secondsSince(t0);
    gather(op, state);
  }

  /// Plane Stokes, iterative, the probe tripped (the mass matrix's GMRES stopped at kProbeIterations
  /// with x its iterate): GMRES with selfp continues from x to the solve's tolerance within the
  /// iterations left of the budget. With a nonzero initial guess PETSc's default test measures the
  /// residual against the right-hand side's norm, the first stage's initial residual (it started
  /// from zero): the same tolerance as a solve without a switch.
  /// The first stage's KSP is destroyed before the second is set up (x, A, b and Sp are this
  /// object's), and the second after its solve: the first stage's Krylov basis (~45 vectors of
  /// 6 MB at 751k unknowns), its BoomerAMG hierarchy on the velocity block and its copies of the
  /// blocks are no longer held beside the second stage's. A later solve sets its stages up anew
  /// either way (A changes, the first stage runs first), so the iterates are those of held KSPs:
  /// chip2 at 2 cells/px the same 204 iterations and k to the last digit, peak resident 1.52 GB
  /// against 1.99 GB (docs/validation/linear-solver.md, "Memory at the switch"); 0.72 GB since
  /// the second stage restarts after kSelfpRestart iterations.
  void switchToSelfp(const FlowOperator& op) {
    switched_at = probe.at;
    switched_drop = probe.r0 > 0 ? probe.r_at / probe.r0 : 0;
    check(KSPDestroy(&ksp), "KSPDestroy");
    ensureSelfpKsp(op);
    check(KSPSetOperators(ksp_selfp, A, A), "KSPSetOperators");
    check(KSPSetTolerances(ksp_selfp, opt.linear_rtol, 1e-30, PETSC_DEFAULT, std::max(1, opt.linear_max_iterations - probe.at)), "tol");
    check(KSPSetInitialGuessNonzero(ksp_selfp, PETSC_TRUE), "initial guess");
    splitByComponent(op, ksp_selfp, "fluidp_");
    std::swap(ksp, ksp_selfp);  // kspSolve's error handling serves the second stage as the first
    try {
      kspSolve();
    } catch (...) {
      std::swap(ksp, ksp_selfp);
      throw;
    }
    std::swap(ksp, ksp_selfp);
  }

  /// ||b - A x|| / ||b|| of the current x (2-norms; ||b - A x|| itself when b = 0): one MatMult
  /// and a vector for the residual, released after.
  double trueResidual() const {
    struct Held {
      Vec v = nullptr;
      ~Held() {
        if (v != nullptr) VecDestroy(&v);
      }
    } r;
    check(VecDuplicate(b, &r.v), "VecDuplicate");
    check(MatMult(A, x, r.v), "MatMult");
    check(VecAYPX(r.v, -1.0, b), "VecAYPX");  // r = b - A x
    PetscReal rn = 0, bn = 0;
    check(VecNorm(r.v, NORM_2, &rn), "VecNorm");
    check(VecNorm(b, NORM_2, &bn), "VecNorm");
    return bn > 0 ? static_cast<double>(rn / bn) : static_cast<double>(rn);
  }

  /// An iterative solve `k` that PETSc reports converged (`reason` > 0): its answer x is kept only
  /// when the true residual is at most kTrueResidualFactor times the tolerance asked for
  /// (true_residual records it); otherwise a FlowFailure, as a solve that did not converge (the
  /// steady solver's fallback to the LU, where it has one), naming the Krylov method, the true
  /// residual and the bound. `stage`: said after the method in the message. Releases the
  /// second stage's KSP (releaseSelfp) before it returns or throws.
  void requireTrueResidual(KSP k, KSPConvergedReason reason, const char* stage) {
    KSPType type = nullptr;
    const char* prefix = nullptr;
    KSPGetType(k, &type);
    KSPGetOptionsPrefix(k, &prefix);
    const std::string method = fmt::format("the Krylov method {} (PETSc prefix {})", type != nullptr ? type : "?", prefix != nullptr ? prefix : "none");
    releaseSelfp();
    const double rel = trueResidual();
    const double bound = kTrueResidualFactor * opt.linear_rtol;
    PetscInfo(A, "true residual %g of the iterative answer, bound %g (%s)\n", rel, bound, method.c_str());
    if (rel <= bound) {  // NaN fails too
      true_residual = rel;
      return;
    }
    PetscInt n = 0;
    MatGetSize(A, &n, nullptr);
    throw FlowFailure(fmt::format("the fluid linear solve failed: {} on the {} unknowns{} stopped {}, but its answer's true residual ||b - Ax|| / ||b|| "
                                  "is not within {} times the relative tolerance {:.3g}: true residual {:.3g} above {:.3g}",
                                  method, static_cast<long long>(n), stage, KSPConvergedReasons[reason], kTrueResidualFactor, opt.linear_rtol, rel, bound),
                      "set it to \"direct\" (no Krylov method), or drop the PETSc options that chose this one", "numerics.linear_solver");
  }

  /// After a switched solve (its reason and iterations read): the second stage's KSP released.
  void releaseSelfp() {
    if (ksp_selfp != nullptr) check(KSPDestroy(&ksp_selfp), "KSPDestroy");
  }

  /// Warm start (setWarmStart): GMRES preconditioned by the kept factors from `state`; the plain
  /// LU solve (preonly, as the direct path) on the first solve and when GMRES runs out of iterations.
  void solveWarm(const FlowOperator& op, Linearisation mode, std::vector<double>& state, FlowStats& stats) {
    const auto ta = std::chrono::steady_clock::now();
    linearise(op, mode, state);
    // A matrix of another pattern (the sharp method's solid nodes, cut stencils and merged cells
    // follow the geometry) is a new matrix, assembled as a new solver assembles it: zeroed
    // entries of the old pattern would stay in A and change the LU's ordering.
    const bool changed = held_start.empty() || patternChanged();
    if (changed && !held_start.empty()) {
      check(MatDestroy(&A), "MatDestroy");
      createMatrix(op);
      pc_fits = false;
      csr_same = false;
    }
    if (changed) {
      held_start = row_start;
      held_cols = cols;
    }
    insert(!changed);
    PetscInt lo = 0, hi = 0;
    check(MatGetOwnershipRange(A, &lo, &hi), "ownership");
    stats.assemble_seconds += secondsSince(ta);
    const auto t0 = std::chrono::steady_clock::now();
    const detail::ScopedDefaultOption ordering("-fluid_mat_umfpack_ordering", kept_analysis ? kKeptOrdering : "METIS", wantsMetis(op));
    warm_its = 0;
    warm_factorised = refactor || warm_max_its == 0;
    setOperators(op);
    if (!warm_factorised) {
      check(KSPSetType(ksp, KSPGMRES), "KSPSetType");
      check(KSPGMRESSetRestart(ksp, warm_max_its), "restart");  // no restart within the budget
      check(KSPGMRESSetCGSRefinementType(ksp, KSP_GMRES_CGS_REFINE_IFNEEDED), "CGS refinement");
      // No divergence test: the last field's residual in the rows of newly closed faces (penalty
      // ~1e8 times the diagonal) exceeds PETSc's default 1e5 times the preconditioned right-hand
      // side, which stopped GMRES before its first iteration on the Pore2Chip scene.
      check(KSPSetTolerances(ksp, warm_rtol, 1e-300, 1e300, warm_max_its), "tol");
      check(KSPSetInitialGuessNonzero(ksp, PETSC_TRUE), "initial guess");
      check(KSPSetReusePreconditioner(ksp, PETSC_TRUE), "reuse pc");
      setGuess(state, lo, hi);
      kspSolve();
      KSPConvergedReason reason;
      KSPGetConvergedReason(ksp, &reason);
      PetscInt its = 0;
      KSPGetIterationNumber(ksp, &its);
      warm_its = static_cast<int>(its);
      stats.linear_iterations += warm_its;
      warm_factorised = reason <= 0;  // not converged within the budget (or broke down): factorise
    }
    if (warm_factorised) {
      if (!pc_fits) {  // the kept analysis is of another pattern: factorise as a new solver
        renewKsp(op);
        setOperators(op);
      }
      check(KSPSetType(ksp, KSPPREONLY), "KSPSetType");
      check(KSPSetInitialGuessNonzero(ksp, PETSC_FALSE), "initial guess");
      check(KSPSetReusePreconditioner(ksp, PETSC_FALSE), "reuse pc");
      ++factorisations;
      kspSolve();
      KSPConvergedReason reason;
      KSPGetConvergedReason(ksp, &reason);
      if (reason < 0) throw FlowFailure(fmt::format("the fluid linear solve failed ({})", KSPConvergedReasons[reason]), "refine the grid");
      stats.linear_iterations += 1;
      refactor = false;
      pc_fits = true;
    }
    stats.solve_seconds += secondsSince(t0);
    gather(op, state);
  }

  /// Warm start: whether the linearised rows' column pattern differs from A's, on any rank.
  bool patternChanged() const {
    int mine = (held_start != row_start || held_cols != cols) ? 1 : 0, any = 0;
    MPI_Allreduce(&mine, &any, 1, MPI_INT, MPI_MAX, comm);
    return any != 0;
  }

  /// Replaces the KSP by a new solver's (its next setup orders and analyses A afresh).
  void renewKsp(const FlowOperator& op) {
    check(KSPDestroy(&ksp), "KSPDestroy");
    factored_once = false;
    createKsp(op);
  }

  /// Diagonal Schur preconditioner -vol / mu per cell (pinned cells: their own diagonal).
  void buildMassSchur(const FlowOperator& op, PetscInt lo, PetscInt hi) {
    Vec d;
    check(MatCreateVecs(A, nullptr, &d), "vec");
    check(MatGetDiagonal(A, d), "diagonal");
    const PetscScalar* dv = nullptr;
    check(VecGetArrayRead(d, &dv), "array");
    // This rank's pressure rows are the last of its rows, in the operator's order: Sp's row k is
    // the pressure of cell k (operator numbering minus the offset), ranks in ascending bands.
    const PetscInt off = op.pressureOffset();
    PetscInt first_p = hi;
    while (first_p > lo && natural(first_p - 1) >= off) --first_p;
    const PetscInt plo = first_p < hi ? natural(first_p) - off : 0, phi = plo + (hi - first_p);
    check(MatCreateAIJ(comm, phi - plo, phi - plo, PETSC_DETERMINE, PETSC_DETERMINE, 1, nullptr, 0, nullptr, &Sp), "Sp");
    const Axis& X = op.problem().x;
    const Axis& Y = op.problem().y;
    const double mu = op.problem().viscosity;
    for (PetscInt k = plo; k < phi; ++k) {
      const double own = dv[petsc(k + off) - lo];
      const int i = static_cast<int>(k % op.nx()), j = static_cast<int>(k / op.nx());
      const PetscScalar v = own != 0 ? own : -X.width(i) * Y.width(j) / mu;
      check(MatSetValue(Sp, k, k, v, INSERT_VALUES), "Sp value");
    }
    check(VecRestoreArrayRead(d, &dv), "array");
    VecDestroy(&d);
    check(MatAssemblyBegin(Sp, MAT_FINAL_ASSEMBLY), "Sp assembly");
    check(MatAssemblyEnd(Sp, MAT_FINAL_ASSEMBLY), "Sp assembly");
    attachMassSchur();
  }

  /// Sp as the Schur preconditioner of the first stage's KSP.
  void attachMassSchur() {
    if (!mass_schur || Sp == nullptr) return;
    PC pc;
    check(KSPGetPC(ksp, &pc), "KSPGetPC");
    check(PCFieldSplitSetSchurPre(pc, PC_FIELDSPLIT_SCHUR_PRE_USER, Sp), "schur pre user");
  }

  void gather(const FlowOperator& op, std::vector<double>& state) {
    if (to_natural.empty()) {
      detail::gatherToAll(x, op.unknowns(), state, "the fluid solution");
      return;
    }
    // Every rank's rows to every rank (one MPI_Allgatherv of the local arrays: a scatter context
    // built per solve indexed all 6.3M unknowns on each rank), then into the operator's order.
    int size = 1;
    MPI_Comm_size(comm, &size);
    std::vector<int> counts(static_cast<std::size_t>(size)), starts(static_cast<std::size_t>(size));
    const int mine = static_cast<int>(row_hi - row_lo);
    MPI_Allgather(&mine, 1, MPI_INT, counts.data(), 1, MPI_INT, comm);
    for (int r = 1; r < size; ++r) starts[static_cast<std::size_t>(r)] = starts[static_cast<std::size_t>(r) - 1] + counts[static_cast<std::size_t>(r) - 1];
    std::vector<double> all(static_cast<std::size_t>(op.unknowns()));
    const PetscScalar* a = nullptr;
    check(VecGetArrayRead(x, &a), "VecGetArrayRead");
    MPI_Allgatherv(a, mine, MPI_DOUBLE, all.data(), counts.data(), starts.data(), MPI_DOUBLE, comm);
    check(VecRestoreArrayRead(x, &a), "VecRestoreArrayRead");
    detail::requireFinite(all.data(), static_cast<long long>(all.size()), "the fluid solution");
    state.resize(all.size());
    for (std::size_t g = 0; g < all.size(); ++g) state[static_cast<std::size_t>(to_natural[g])] = all[g];
  }
};

CoupledSystem::CoupledSystem(const FlowOperator& op, const SolverOptions& options, MPI_Comm comm) : m(std::make_unique<Impl>()) {
  m->opt = options;
  if (m->opt.linear == "auto") m->opt.linear = "direct";  // the caller did not choose (time stepping keeps its LU)
  m->comm = comm;
  m->create(op);
}

CoupledSystem::~CoupledSystem() = default;

void CoupledSystem::setLaggedFactorisation(int max_iterations, double rtol) {
  if (m->opt.linear != "direct") return;
  m->lag_max_its = std::max(1, max_iterations);
  m->refactor = true;
  check(KSPSetType(m->ksp, KSPGMRES), "KSPSetType");
  check(KSPGMRESSetRestart(m->ksp, 4 * m->lag_max_its), "restart");
  check(KSPSetInitialGuessNonzero(m->ksp, PETSC_TRUE), "initial guess");
  check(KSPSetTolerances(m->ksp, rtol, 1e-300, PETSC_DEFAULT, 8 * m->lag_max_its), "tol");
  check(KSPSetFromOptions(m->ksp), "KSPSetFromOptions");
}

void CoupledSystem::invalidate() { m->refactor = true; }

bool CoupledSystem::refactorPending() const { return m->refactor; }

void CoupledSystem::setRefactorPending(bool pending) { m->refactor = pending; }

void CoupledSystem::factorise(const FlowOperator& op, Linearisation mode, const std::vector<double>& state) {
  if (m->opt.linear != "direct" || m->lag_max_its == 0) return;  // nothing is kept between solves
  m->factorise(op, mode, state);
}

int CoupledSystem::factorisations() const { return m->factorisations; }

int CoupledSystem::schurSwitchIterations() const { return m->switched_at; }

double CoupledSystem::schurSwitchResidual() const { return m->switched_drop; }

double CoupledSystem::lastTrueResidual() const { return m->true_residual; }

const std::string& CoupledSystem::velocityPreconditioner() const { return m->velocity_pc; }

void CoupledSystem::solve(const FlowOperator& op, Linearisation mode, std::vector<double>& state, FlowStats& stats) {
  if (m->warm) m->solveWarm(op, mode, state, stats);
  else m->solve(op, mode, state, stats);
}

void CoupledSystem::setWarmStart(int max_iterations, double rtol) {
  if (m->opt.linear != "direct") return;
  m->warm = true;
  m->warm_max_its = std::max(0, max_iterations);
  m->warm_rtol = rtol;
  m->lag_max_its = 0;
  m->refactor = true;
}

void CoupledSystem::setKeptAnalysis() { m->kept_analysis = true; }

int CoupledSystem::lastWarmIterations() const { return m->warm_its; }

bool CoupledSystem::lastFactorised() const { return m->warm_factorised; }

}  // namespace mmval::simulate
