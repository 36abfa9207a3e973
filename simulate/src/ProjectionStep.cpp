#include "ProjectionStep.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <map>
#include <stdexcept>
#include <string>

#include <fmt/format.h>
#include <petscksp.h>

#include "SolverUtil.hpp"

namespace mmval::simulate {

using detail::check;
using detail::secondsSince;

namespace {
/// Sparse rows: row starts, (column, value) entries.
struct Rows {
  std::vector<std::size_t> start{0};
  std::vector<std::pair<int, double>> e;
  void push(const std::pair<int, double>& x) { e.push_back(x); }
  void close() { start.push_back(e.size()); }
  std::size_t rows() const { return start.size() - 1; }
};

/// An AIJ matrix of `n` rows on `comm` with this rank's rows of `rows` (columns unchanged).
Mat makeMatrix(MPI_Comm comm, PetscInt n, PetscInt nnz_row) {
  Mat A = nullptr;
  check(MatCreate(comm, &A), "MatCreate");
  check(MatSetSizes(A, PETSC_DECIDE, PETSC_DECIDE, n, n), "MatSetSizes");
  check(MatSetType(A, MATAIJ), "MatSetType");
  check(MatSeqAIJSetPreallocation(A, nnz_row, nullptr), "prealloc");
  check(MatMPIAIJSetPreallocation(A, nnz_row, nullptr, nnz_row, nullptr), "prealloc");
  check(MatSetOption(A, MAT_NEW_NONZERO_ALLOCATION_ERR, PETSC_FALSE), "MatSetOption");
  return A;
}
}  // namespace

/// A velocity row of this rank, split into what stays (its pattern, the linear terms, the
/// constant right-hand side) and what each step evaluates (the convective terms at the
/// advecting velocity, the transient term). Filling the matrix then needs no geometry.
struct CachedRows {
  /// c (a_k + a_c . state[a_i]) times the advected factor b_c . u[b] (its value slots) + k.
  /// Unused entries of a and b have coefficient 0 (and index 0, slot the first): always two of
  /// each, no branch per term, and the same sums as Lin::eval (adding 0 leaves a value as it is).
  struct Term {
    std::array<std::int32_t, 2> ai{};
    std::array<std::uint32_t, 2> bs{};
    std::array<double, 2> ac{}, bc{};
    double ak = 0, c = 0, k = 0;
  };
  std::vector<PetscInt> cols;          ///< velocity columns, row after row
  std::vector<double> base;            ///< linear values (no transient term), per column slot
  std::vector<std::size_t> start{0};   ///< slots of each row
  std::vector<std::size_t> diag;       ///< slot of each row's diagonal
  std::vector<double> rhs;             ///< constant right-hand side of each row
  std::vector<Term> terms;
  std::vector<std::size_t> term_start{0};
};

struct ProjectionStep::Impl {
  MPI_Comm comm;
  int P = 0, N = 0;              ///< pressure offset (velocity unknowns), all unknowns
  std::vector<double> inv_mass;  ///< 1 / (V k) per velocity row (0: a fixed node); M = coef V k
  Rows G;                        ///< pressure-gradient part of the velocity rows (columns: cell index)
  Rows D;                        ///< velocity part of the continuity rows
  Rows C;                        ///< pressure part of the continuity rows (pinned and merged cells)
  std::vector<double> g;         ///< right-hand sides of the continuity rows
  CachedRows rows;               ///< this rank's velocity rows
  PetscInt own_lo = 0, own_hi = 0;  ///< this rank's velocity rows
  std::vector<int> master;       ///< per cell: the cell whose increment it takes (-1: its own; -2: pinned, zero)
  /// Rotational form: mu / (fluid area) per cell with a continuity flux (0 elsewhere, and 0 in the
  /// standard form), so that mu_over_area * (outflow of u') = mu div u'.
  std::vector<double> mu_over_area;
  bool rotational = false;
  Mat Au = nullptr, K = nullptr;
  /// The pressure solve is a direct one (a KSP of type preonly: the LU factorisation of K, made
  /// once): no initial guess, one forward and one back substitution per solve.
  bool direct_pressure = false;
  /// The velocity matrix is a sequential AIJ whose pattern is exactly `rows` (checked after its
  /// first assembly): the step writes its values in place instead of through MatSetValues.
  bool values_in_place = false;
  Vec bu = nullptr, xu = nullptr, bp = nullptr, xp = nullptr;
  Vec rp = nullptr;  ///< scratch: the pressure system's residual (guessBeatsZero)
  KSP ku = nullptr, kp = nullptr;
  ProjectionTimings t;
  std::vector<double> last_dp;   ///< the last step's pressure increment (the next one's initial guess); empty: none
  // Scratch of the row loop.
  RowTerms row;
  std::vector<std::pair<int, double>> entries;
  /// Scratch of a step (kept: no allocation per step).
  struct Scratch {
    std::vector<double> vals, rhs, u, dp, r, chi, p_old;
  } scratch;

  ~Impl() {
    for (KSP* k : {&ku, &kp})
      if (*k != nullptr) KSPDestroy(k);
    for (Mat* a : {&Au, &K})
      if (*a != nullptr) MatDestroy(a);
    for (Vec* v : {&bu, &xu, &bp, &xp, &rp})
      if (*v != nullptr) VecDestroy(v);
  }

  /// The mass of every velocity row (its transient diagonal per unit coef), the split of the
  /// constant rows (G, D, C), and the pressure matrix with its multigrid hierarchy.
  void setup(FlowOperator& op, double velocity_rtol, double pressure_rtol) {
    const auto t0 = std::chrono::steady_clock::now();
    P = op.pressureOffset();
    N = op.unknowns();
    const std::vector<double> zeros(static_cast<std::size_t>(N), 0.0);
    // The transient term adds coef V k to the diagonal of a momentum row: read it as the
    // difference of the diagonals with a unit coef and without.
    inv_mass.assign(static_cast<std::size_t>(P), 0.0);
    std::vector<double> diag1(static_cast<std::size_t>(P), 0.0);
    op.setTransient(1.0, &zeros);
    for (int r = 0; r < P; ++r) {
      op.linearRow(r, Linearisation::stokes, zeros, row, entries);
      for (const auto& [c, v] : entries)
        if (c == r) diag1[static_cast<std::size_t>(r)] = v;
    }
    op.setTransient(0.0, nullptr);
    for (int r = 0; r < P; ++r) {
      op.linearRow(r, Linearisation::stokes, zeros, row, entries);
      double d0 = 0;
      for (const auto& [c, v] : entries) {
        if (c == r) d0 = v;
        if (c >= P) G.push({c - P, v});
      }
      G.close();
      const double mass = diag1[static_cast<std::size_t>(r)] - d0;
      // Fixed nodes (walls, inflow, solid) have no transient term and no pressure force.
      if (mass > 0) inv_mass[static_cast<std::size_t>(r)] = 1.0 / mass;
    }
    const int cells = N - P;
    master.assign(static_cast<std::size_t>(cells), -1);
    for (int i = 0; i < cells; ++i) {
      g.push_back(op.linearRow(P + i, Linearisation::stokes, zeros, row, entries));
      for (const auto& [c, v] : entries) (c < P ? D : C).push({c < P ? c : c - P, v});
      D.close();
      C.close();
    }
    buildPressureMatrix(pressure_rtol);
    cellAreas(op);
    createVelocitySolver(velocity_rtol);
    cacheRows(op);
    t.setup_seconds += secondsSince(t0);
  }

  /// K = -D M^-1 G per unit coef on the rows with continuity fluxes; identity on the others.
  void buildPressureMatrix(double rtol) {
    const int cells = N - P;
    K = makeMatrix(comm, cells, 16);
    PetscInt lo = 0, hi = 0;
    check(MatGetOwnershipRange(K, &lo, &hi), "ownership");
    std::map<int, double> acc;
    for (int i = 0; i < cells; ++i) {
      acc.clear();
      const auto ui = static_cast<std::size_t>(i);
      for (std::size_t a = D.start[ui]; a < D.start[ui + 1]; ++a) {
        const auto [k, dik] = D.e[a];
        const double w = inv_mass[static_cast<std::size_t>(k)];
        if (w == 0 || dik == 0) continue;
        for (std::size_t b = G.start[static_cast<std::size_t>(k)]; b < G.start[static_cast<std::size_t>(k) + 1]; ++b)
          acc[G.e[b].first] -= dik * w * G.e[b].second;
      }
      bool flux = false;
      for (const auto& [c, v] : acc) flux = flux || (c == i && v != 0);
      if (!flux) {
        // Pinned (one entry) or merged (own and master): no flux of its own. Its increment is
        // zero, or its master's (set after the solve).
        acc.clear();
        acc[i] = 1.0;
        int other = -2;
        for (std::size_t a = C.start[ui]; a < C.start[ui + 1]; ++a)
          if (C.e[a].first != i && C.e[a].second != 0) other = C.e[a].first;
        master[ui] = other;
      }
      if (i < lo || i >= hi) continue;
      const PetscInt r = i;
      for (const auto& [c, v] : acc) {
        const PetscInt cc = c;
        check(MatSetValues(K, 1, &r, 1, &cc, &v, INSERT_VALUES), "MatSetValues");
      }
    }
    check(MatAssemblyBegin(K, MAT_FINAL_ASSEMBLY), "assembly");
    check(MatAssemblyEnd(K, MAT_FINAL_ASSEMBLY), "assembly");
    check(MatCreateVecs(K, &xp, &bp), "vecs");
    check(VecDuplicate(bp, &rp), "VecDuplicate");
    int ranks = 1;
    MPI_Comm_size(comm, &ranks);
    // A KSP or PC type given in the options (-projp_ksp_type, -projp_pc_type) goes over the
    // iterative solver's defaults (CG, BoomerAMG, the tolerance, the initial guess).
    PetscBool chosen_ksp = PETSC_FALSE, chosen_pc = PETSC_FALSE;
    check(PetscOptionsHasName(nullptr, nullptr, "-projp_ksp_type", &chosen_ksp), "options");
    check(PetscOptionsHasName(nullptr, nullptr, "-projp_pc_type", &chosen_pc), "options");
    if (ranks == 1 && !chosen_ksp && !chosen_pc && createDirectPressureSolver()) return;
    createMultigridPressureSolver(rtol);
  }

  /// kp: a new KSP on K with the pressure solve's options prefix ("projp_").
  void newPressureKsp() {
    check(KSPCreate(comm, &kp), "KSPCreate");
    check(KSPSetOptionsPrefix(kp, "projp_"), "prefix");
    check(KSPSetOperators(kp, K, K), "operators");
  }

  /// One rank: K's LU factorisation (PETSc's own, nested-dissection ordering), made once. K is the
  /// same at every step (the factor coef is applied to the right-hand side), so a solve is one
  /// forward and one back substitution, exact to rounding (no initial guess, no tolerance). On 2D-2
  /// (121,212 cells; docs/validation/cylinder-unsteady.md, 2026-12-05) the factorisation takes ~0.2 s
  /// and ~50 MB, and the pressure phase of a step fell from ~0.3 s to ~0.03 s of wall time against CG
  /// with BoomerAMG (6.9 iterations); UMFPACK's LU of the same matrix was slower (its solves), PETSc's
  /// Cholesky no faster, CHOLMOD stopped on a pivot it judged not positive.
  /// Returns false (the multigrid solver takes over) when the factorisation fails.
  bool createDirectPressureSolver() {
    newPressureKsp();
    check(KSPSetType(kp, KSPPREONLY), "preonly");
    PC pc;
    check(KSPGetPC(kp, &pc), "pc");
    check(PCSetType(pc, PCLU), "lu");
    check(PCFactorSetMatSolverType(pc, MATSOLVERPETSC), "factor solver");
    check(PCFactorSetMatOrderingType(pc, MATORDERINGND), "ordering");
    check(KSPSetFromOptions(kp), "options");  // e.g. -projp_pc_factor_mat_ordering_type
    PCFailedReason failed = PC_NOERROR;
    direct_pressure = KSPSetUp(kp) == 0 && PCGetFailedReason(pc, &failed) == 0 && failed == PC_NOERROR;
    if (!direct_pressure) check(KSPDestroy(&kp), "KSPDestroy");
    return direct_pressure;
  }

  /// Several ranks (or a failed factorisation): CG with BoomerAMG, its hierarchy built once.
  void createMultigridPressureSolver(double rtol) {
    newPressureKsp();
    check(KSPSetType(kp, KSPCG), "cg");
    PC pc;
    check(KSPGetPC(kp, &pc), "pc");
    check(PCSetType(pc, PCHYPRE), "hypre");
    // HMIS coarsening with extended+i interpolation (hypre's advice for 2D/3D Poisson problems):
    // 516 CG iterations against 600 with the defaults over the first 46 steps of the 2D-2 case.
    detail::defaultOption("-projp_pc_hypre_boomeramg_coarsen_type", "HMIS");
    detail::defaultOption("-projp_pc_hypre_boomeramg_interp_type", "ext+i");
    detail::defaultOption("-projp_pc_hypre_boomeramg_P_max", "4");
    // No divergence test (dtol 1e30): with an initial guess PETSc measures divergence against the
    // preconditioned norm of the right-hand side, which BoomerAMG makes small when the right-hand
    // side is rough (local continuity defects) and large when the guess's error is smooth. At the
    // start-up of the unconfined Re 100 cylinder at Courant <= 1 (cells_around 32) that ratio
    // passed 1e5 at step 4 and stopped a convergent solve (DIVERGED_DTOL at iteration 0). A solve
    // that fails still stops at 500 iterations or on a NaN.
    check(KSPSetTolerances(kp, rtol, 1e-300, 1e30, 500), "tol");
    check(KSPSetInitialGuessNonzero(kp, PETSC_TRUE), "guess");
    check(KSPSetFromOptions(kp), "options");
    check(KSPSetUp(kp), "setup");
  }

  /// mu / A_i for the rotational pressure update: A_i the cell's area plus its merged cells'
  /// fluid parts (m_cellChi is the solid indicator of the sharp boundary: merged cells are solid,
  /// so A_i is the master's own area). Depth-weighted fluxes (Hele-Shaw) are divided the same way.
  void cellAreas(const FlowOperator& op) {
    const int nx = op.nx(), ny = op.ny();
    const Eigen::ArrayXXd chi = op.cellSolidFraction();
    std::vector<double> area(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny), 0.0);
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const std::size_t c = static_cast<std::size_t>(j) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(i);
        const double a = op.problem().x.width(i) * op.problem().y.width(j) * std::max(0.0, 1.0 - chi(j, i));
        const int m = master[c];
        if (m >= 0) area[static_cast<std::size_t>(m)] += a;
        else if (m == -1) area[c] += a;
      }
    mu_over_area.assign(area.size(), 0.0);
    for (std::size_t c = 0; c < area.size(); ++c)
      if (master[c] == -1 && area[c] > 0) mu_over_area[c] = op.problem().viscosity / area[c];
  }

  void createVelocitySolver(double rtol) {
    Au = makeMatrix(comm, P, 12);
    check(MatCreateVecs(Au, &xu, &bu), "vecs");
    check(KSPCreate(comm, &ku), "KSPCreate");
    check(KSPSetOptionsPrefix(ku, "proju_"), "prefix");
    check(KSPSetType(ku, KSPGMRES), "gmres");
    check(KSPSetInitialGuessNonzero(ku, PETSC_TRUE), "guess");
    check(KSPSetTolerances(ku, rtol, 1e-300, PETSC_DEFAULT, 500), "tol");
    check(KSPSetFromOptions(ku), "options");  // PC: PETSc's default (ILU(0) on one rank, block Jacobi-ILU on several)
  }

  /// Splits this rank's velocity rows (the operator without its transient term) into CachedRows.
  void cacheRows(const FlowOperator& op) {
    CachedRows c;
    const std::vector<double> zeros(static_cast<std::size_t>(N), 0.0);
    check(MatGetOwnershipRange(Au, &own_lo, &own_hi), "ownership");
    for (PetscInt r = own_lo; r < own_hi; ++r) {
      // Stokes mode: the pattern holds the convective terms' columns with value 0; `row` keeps the terms.
      c.rhs.push_back(op.linearRow(static_cast<int>(r), Linearisation::stokes, zeros, row, entries));
      const std::size_t first = c.cols.size();
      c.diag.push_back(first);
      for (const auto& [col, v] : entries) {
        if (col >= P) continue;  // the pressure gradient: G
        if (col == r) c.diag.back() = c.cols.size();
        c.cols.push_back(col);
        c.base.push_back(v);
      }
      c.start.push_back(c.cols.size());
      const auto slotOf = [&](int col) {
        const auto it = std::lower_bound(c.cols.begin() + static_cast<std::ptrdiff_t>(first), c.cols.end(), static_cast<PetscInt>(col));
        if (it == c.cols.end() || *it != col) throw std::logic_error("ProjectionStep: a convective column outside the row's pattern");
        return static_cast<std::size_t>(it - c.cols.begin());
      };
      for (const auto& bt : row.bil) {
        CachedRows::Term t;
        t.c = bt.c;
        t.k = bt.b.k;
        t.ak = bt.a.k;
        for (std::size_t q = 0; q < static_cast<std::size_t>(bt.a.n); ++q) {
          t.ai[q] = bt.a.idx[q];
          t.ac[q] = bt.a.c[q];
        }
        t.bs.fill(static_cast<std::uint32_t>(first));
        for (std::size_t q = 0; q < static_cast<std::size_t>(bt.b.n); ++q) {
          const std::size_t slot = slotOf(bt.b.idx[q]);
          if (slot > UINT32_MAX) throw std::length_error("ProjectionStep: more matrix entries than a 32-bit slot holds");
          t.bs[q] = static_cast<std::uint32_t>(slot);
          t.bc[q] = bt.b.c[q];
        }
        c.terms.push_back(t);
      }
      c.term_start.push_back(c.terms.size());
    }
    rows = std::move(c);
    values_in_place = false;  // the next fill goes through MatSetValues and checks the pattern again
  }

  /// This rank's velocity rows at the advecting velocity `state` with the transient term
  /// (coef, history) into Au, and their right-hand side with the pressure gradient of `state`.
  void fillVelocityRows(double coef, const std::vector<double>& history, const std::vector<double>& state, std::vector<double>& rhs) {
    PetscScalar* in_place = nullptr;
    if (values_in_place) check(MatSeqAIJGetArray(Au, &in_place), "MatSeqAIJGetArray");
    double* v = in_place;
    std::vector<double>& vals = scratch.vals;
    if (v == nullptr) {
      vals.resize(rows.base.size());
      v = vals.data();
    }
    std::copy(rows.base.begin(), rows.base.end(), v);
    for (PetscInt r = own_lo; r < own_hi; ++r) {
      const auto k = static_cast<std::size_t>(r - own_lo), ur = static_cast<std::size_t>(r);
      double b = rows.rhs[k];
      if (inv_mass[ur] > 0) {
        const double mass = 1.0 / inv_mass[ur];
        v[rows.diag[k]] += coef * mass;
        b += mass * history[ur];
      }
      for (std::size_t q = rows.term_start[k]; q < rows.term_start[k + 1]; ++q) {
        const CachedRows::Term& t = rows.terms[q];
        double a = t.ak + t.ac[0] * state[static_cast<std::size_t>(t.ai[0])];
        a += t.ac[1] * state[static_cast<std::size_t>(t.ai[1])];
        const double a0 = t.c * a;
        v[t.bs[0]] += a0 * t.bc[0];
        v[t.bs[1]] += a0 * t.bc[1];
        b -= a0 * t.k;
      }
      for (std::size_t a = G.start[ur]; a < G.start[ur + 1]; ++a) b -= G.e[a].second * state[static_cast<std::size_t>(P + G.e[a].first)];
      rhs[ur] = b;
    }
    if (in_place != nullptr) {
      check(MatSeqAIJRestoreArray(Au, &in_place), "MatSeqAIJRestoreArray");  // marks the matrix changed
      return;
    }
    for (PetscInt r = own_lo; r < own_hi; ++r) {
      const auto k = static_cast<std::size_t>(r - own_lo);
      const PetscInt rr = r;
      const std::size_t s0 = rows.start[k];
      check(MatSetValues(Au, 1, &rr, static_cast<PetscInt>(rows.start[k + 1] - s0), rows.cols.data() + s0, vals.data() + s0, INSERT_VALUES), "MatSetValues");
    }
    check(MatAssemblyBegin(Au, MAT_FINAL_ASSEMBLY), "assembly");
    check(MatAssemblyEnd(Au, MAT_FINAL_ASSEMBLY), "assembly");
    values_in_place = patternIsRows();
  }

  /// Whether Au is a sequential AIJ matrix whose rows hold exactly the columns of `rows`, in
  /// order, so that its value array lines up with `rows.base` (a velocity row's columns are
  /// sorted and distinct: cacheRows looks the convective columns up by bisection).
  bool patternIsRows() { return detail::seqAijRowsAre(Au, rows.start, rows.cols); }

  void fill(Vec v, const std::vector<double>& x, std::size_t off) {
    PetscInt lo = 0, hi = 0;
    check(VecGetOwnershipRange(v, &lo, &hi), "ownership");
    PetscScalar* a = nullptr;
    check(VecGetArray(v, &a), "array");
    for (PetscInt r = lo; r < hi; ++r) a[r - lo] = x[off + static_cast<std::size_t>(r)];
    check(VecRestoreArray(v, &a), "array");
  }

  /// Whether the guess in xp leaves a smaller residual than zero does: |bp - K xp| < |bp|. Early
  /// in a start-up the pressure settles within a few steps and the last increment can be many
  /// times the next (50x at step 4 of the unconfined Re 100 cylinder at Courant 1).
  bool guessBeatsZero() {
    check(MatMult(K, xp, rp), "MatMult");
    check(VecAYPX(rp, -1.0, bp), "VecAYPX");  // rp = bp - K xp
    PetscReal rn = 0, bn = 0;
    check(VecNorm(rp, NORM_2, &rn), "VecNorm");
    check(VecNorm(bp, NORM_2, &bn), "VecNorm");
    return rn < bn;
  }

  void solve(KSP k, Vec b, Vec x, const char* what, long long& its_sum) {
    check(KSPSolve(k, b, x), "KSPSolve");
    KSPConvergedReason reason;
    check(KSPGetConvergedReason(k, &reason), "reason");
    if (reason < 0) throw FlowFailure(fmt::format("the {} solve of the projection step failed ({})", what, KSPConvergedReasons[reason]), "lower the Courant limit");
    PetscInt its = 0;
    check(KSPGetIterationNumber(k, &its), "iterations");
    its_sum += its;
  }

  int step(const FlowOperator& op, double coef, const std::vector<double>& history, std::vector<double>& state, FlowStats& stats, int sweeps,
           double sweep_tolerance) {
    if (op.unknowns() != N) throw std::logic_error("ProjectionStep: the operator's grid changed");
    const auto t0 = std::chrono::steady_clock::now();
    const int cells = N - P;
    std::vector<double>&p_old = scratch.p_old, &rhs = scratch.rhs, &u = scratch.u, &dp = scratch.dp, &r = scratch.r, &chi = scratch.chi;
    p_old.assign(state.begin() + P, state.end());
    // 1. The velocity rows at the advecting velocity: A u' = f - G p^n.
    rhs.assign(static_cast<std::size_t>(P), 0.0);
    fillVelocityRows(coef, history, state, rhs);
    t.assemble_seconds += secondsSince(t0);
    stats.assemble_seconds += secondsSince(t0);
    const auto t1 = std::chrono::steady_clock::now();
    check(KSPSetOperators(ku, Au, Au), "operators");
    r.assign(static_cast<std::size_t>(cells), 0.0);
    chi.assign(static_cast<std::size_t>(cells), 0.0);
    int sweep = 0;
    while (true) {
      const auto ts = std::chrono::steady_clock::now();
      fill(bu, rhs, 0);
      fill(xu, state, 0);  // initial guess: the extrapolated velocity (a later sweep: the last one's)
      long long its_u = 0, its_p = 0;
      solve(ku, bu, xu, "velocity", its_u);
      detail::gatherToAll(xu, P, u, "the predicted velocity");
      const auto t2 = std::chrono::steady_clock::now();
      t.velocity_seconds += secondsSince(ts);
      // 2. The pressure increment: K dp = coef (g - D u' - C p) on the flux rows, 0 on the others.
      for (int i = 0; i < cells; ++i) {
        const auto ui = static_cast<std::size_t>(i);
        if (master[ui] != -1) continue;
        double s = g[ui];
        for (std::size_t a = D.start[ui]; a < D.start[ui + 1]; ++a) s -= D.e[a].second * u[static_cast<std::size_t>(D.e[a].first)];
        for (std::size_t a = C.start[ui]; a < C.start[ui + 1]; ++a) s -= C.e[a].second * state[static_cast<std::size_t>(P + C.e[a].first)];
        r[ui] = coef * s;
      }
      fill(bp, r, 0);
      // Initial guess (an iterative solve): the last step's pressure change (the pressure changes
      // smoothly from step to step); zero in a correction sweep (small increments).
      if (direct_pressure) {
        // The factorisation needs no guess.
      } else if (sweep == 0 && !last_dp.empty()) {
        fill(xp, last_dp, 0);
        if (!guessBeatsZero()) check(VecSet(xp, 0.0), "VecSet");
      } else {
        check(VecSet(xp, 0.0), "VecSet");
      }
      solve(kp, bp, xp, "pressure", its_p);
      detail::gatherToAll(xp, cells, dp, "the pressure increment");
      for (int i = 0; i < cells; ++i) {
        const int m = master[static_cast<std::size_t>(i)];
        if (m >= 0) dp[static_cast<std::size_t>(i)] = dp[static_cast<std::size_t>(m)];
        else if (m == -2) dp[static_cast<std::size_t>(i)] = 0;
      }
      // Rotational form: the pressure takes -mu div u' besides the increment (r / coef is the
      // outflow of u' per cell); merged cells take their master's, pinned cells nothing.
      if (rotational) {
        for (int i = 0; i < cells; ++i)
          if (master[static_cast<std::size_t>(i)] == -1) chi[static_cast<std::size_t>(i)] = -mu_over_area[static_cast<std::size_t>(i)] * r[static_cast<std::size_t>(i)] / coef;
        for (int i = 0; i < cells; ++i) {
          const int m = master[static_cast<std::size_t>(i)];
          if (m >= 0) chi[static_cast<std::size_t>(i)] = chi[static_cast<std::size_t>(m)];
        }
      }
      // 3. Correction: u = u' - M^-1 G dp, p = p + dp (+ chi, rotational).
      for (int k = 0; k < P; ++k) {
        const auto uk = static_cast<std::size_t>(k);
        double grad = 0;
        for (std::size_t a = G.start[uk]; a < G.start[uk + 1]; ++a) grad += G.e[a].second * dp[static_cast<std::size_t>(G.e[a].first)];
        state[uk] = u[uk] - inv_mass[uk] / coef * grad;
      }
      double dp_max = 0, p_max = 0;
      for (int i = 0; i < cells; ++i) {
        double& p = state[static_cast<std::size_t>(P + i)];
        const double change = dp[static_cast<std::size_t>(i)] + chi[static_cast<std::size_t>(i)];
        p += change;
        dp_max = std::max(dp_max, std::abs(change));
        p_max = std::max(p_max, std::abs(p));
      }
      t.pressure_seconds += secondsSince(t2);
      t.velocity_iterations += its_u;
      t.pressure_iterations += its_p;
      stats.linear_iterations += static_cast<int>(its_u + its_p);
      ++sweep;
      if (sweep >= sweeps || dp_max <= sweep_tolerance * p_max) break;
      // Another sweep: the predictor with the corrected pressure, f - G p.
      for (PetscInt q = own_lo; q < own_hi; ++q) {
        const auto uq = static_cast<std::size_t>(q);
        for (std::size_t a = G.start[uq]; a < G.start[uq + 1]; ++a) {
          const auto c = static_cast<std::size_t>(G.e[a].first);
          rhs[uq] -= G.e[a].second * (dp[c] + chi[c]);
        }
      }
    }
    // The step's pressure change: the next step's initial guess. A start-up step (swept to a
    // tolerance) changes the pressure from nothing to all of it: no guess for the next.
    if (sweeps > 1 && sweep_tolerance > 0) {
      last_dp.clear();
    } else {
      // (Zero on the identity rows of pinned and merged cells: the pressure solve's initial guess.)
      last_dp.assign(static_cast<std::size_t>(cells), 0.0);
      for (int i = 0; i < cells; ++i)
        if (master[static_cast<std::size_t>(i)] == -1) last_dp[static_cast<std::size_t>(i)] = state[static_cast<std::size_t>(P + i)] - p_old[static_cast<std::size_t>(i)];
    }
    stats.solve_seconds += secondsSince(t1);
    return sweep;
  }
};

ProjectionStep::ProjectionStep(FlowOperator& op, MPI_Comm comm, double velocity_rtol, double pressure_rtol, bool rotational) : m(std::make_unique<Impl>()) {
  if (!(velocity_rtol > 0 && velocity_rtol < 1) || !(pressure_rtol > 0 && pressure_rtol < 1))
    throw std::invalid_argument("ProjectionStep: tolerances must be in (0, 1)");
  m->comm = comm;
  m->rotational = rotational;
  m->setup(op, velocity_rtol, pressure_rtol);
}

ProjectionStep::~ProjectionStep() = default;

int ProjectionStep::step(const FlowOperator& op, double coef, const std::vector<double>& history, std::vector<double>& state, FlowStats& stats,
                         int sweeps, double sweep_tolerance) {
  return m->step(op, coef, history, state, stats, std::max(1, sweeps), sweep_tolerance);
}

void ProjectionStep::refreshRows(const FlowOperator& op) { m->cacheRows(op); }

const ProjectionTimings& ProjectionStep::timings() const { return m->t; }

const std::vector<double>& ProjectionStep::lastIncrement() const { return m->last_dp; }

void ProjectionStep::setLastIncrement(std::vector<double> dp) {
  if (!dp.empty() && static_cast<int>(dp.size()) != m->N - m->P) throw std::invalid_argument("ProjectionStep: a pressure increment of another grid");
  m->last_dp = std::move(dp);
}

}  // namespace mmval::simulate
