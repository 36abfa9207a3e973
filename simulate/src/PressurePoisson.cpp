#include "mmval/simulate/PressurePoisson.hpp"

#include <chrono>
#include <stdexcept>
#include <vector>

#include <fmt/format.h>
#include <petscksp.h>

#include "mmval/core/Error.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::simulate {

struct PressurePoisson::Impl {
  Axis x, y;
  int nx = 0, ny = 0;
  Mat A = nullptr;
  Vec b = nullptr, s = nullptr;
  KSP ksp = nullptr;
  MatNullSpace ns = nullptr;
  PoissonStats stats;
  ~Impl() {
    if (ns != nullptr) MatNullSpaceDestroy(&ns);
    if (ksp != nullptr) KSPDestroy(&ksp);
    if (A != nullptr) MatDestroy(&A);
    if (b != nullptr) VecDestroy(&b);
    if (s != nullptr) VecDestroy(&s);
  }
};

PressurePoisson::PressurePoisson(Axis x, Axis y, bool px, bool py, double rtol, MPI_Comm comm) : m(std::make_unique<Impl>()) {
  PetscSession::ensure();
  const auto t0 = std::chrono::steady_clock::now();
  m->x = std::move(x);
  m->y = std::move(y);
  const int nx = m->nx = m->x.cells(), ny = m->ny = m->y.cells();
  const PetscInt n = static_cast<PetscInt>(nx) * ny;
  MatCreate(comm, &m->A);
  MatSetSizes(m->A, PETSC_DECIDE, PETSC_DECIDE, n, n);
  MatSetType(m->A, MATAIJ);
  MatSeqAIJSetPreallocation(m->A, 5, nullptr);
  MatMPIAIJSetPreallocation(m->A, 5, nullptr, 4, nullptr);
  PetscInt lo = 0, hi = 0;
  MatGetOwnershipRange(m->A, &lo, &hi);
  auto dist = [](const Axis& a, int i, int k, bool per) {  // centre distance between cells i and k = i +- 1
    const int N = a.cells();
    const int kk = (k + N) % N;
    (void)per;
    return 0.5 * (a.width(i) + a.width(kk));
  };
  for (PetscInt r = lo; r < hi; ++r) {
    const int i = static_cast<int>(r % nx), j = static_cast<int>(r / nx);
    // Negative Laplacian (SPD) times the cell area: sum over faces A/d (p_P - p_Q).
    PetscInt cols[5];
    PetscScalar vals[5];
    int c = 0;
    double diag = 0;
    auto nb = [&](int ii, int jj, double coef) {
      cols[c] = static_cast<PetscInt>(jj) * nx + ii;
      vals[c] = -coef;
      ++c;
      diag += coef;
    };
    const double dx = m->x.width(i), dy = m->y.width(j);
    if (i > 0 || px) nb((i - 1 + nx) % nx, j, dy / dist(m->x, i, i - 1, px));
    if (i < nx - 1 || px) nb((i + 1) % nx, j, dy / dist(m->x, i, i + 1, px));
    if (j > 0 || py) nb(i, (j - 1 + ny) % ny, dx / dist(m->y, j, j - 1, py));
    if (j < ny - 1 || py) nb(i, (j + 1) % ny, dx / dist(m->y, j, j + 1, py));
    cols[c] = r;
    vals[c] = diag;
    ++c;
    MatSetValues(m->A, 1, &r, c, cols, vals, ADD_VALUES);
  }
  MatAssemblyBegin(m->A, MAT_FINAL_ASSEMBLY);
  MatAssemblyEnd(m->A, MAT_FINAL_ASSEMBLY);
  MatSetOption(m->A, MAT_SPD, PETSC_TRUE);
  MatNullSpaceCreate(comm, PETSC_TRUE, 0, nullptr, &m->ns);
  MatSetNullSpace(m->A, m->ns);
  MatCreateVecs(m->A, &m->s, &m->b);
  KSPCreate(comm, &m->ksp);
  KSPSetOptionsPrefix(m->ksp, "poisson_");
  KSPSetOperators(m->ksp, m->A, m->A);
  KSPSetType(m->ksp, KSPCG);
  PC pc;
  KSPGetPC(m->ksp, &pc);
  PCSetType(pc, PCGAMG);
  KSPSetTolerances(m->ksp, rtol, 1e-300, PETSC_DEFAULT, 1000);
  KSPSetFromOptions(m->ksp);
  KSPSetUp(m->ksp);
  m->stats.unknowns = n;
  m->stats.setup_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

PressurePoisson::~PressurePoisson() = default;

Eigen::ArrayXXd PressurePoisson::solve(const Eigen::ArrayXXd& f) {
  if (f.rows() != m->ny || f.cols() != m->nx) throw std::invalid_argument("PressurePoisson::solve: source has the wrong shape");
  const auto t0 = std::chrono::steady_clock::now();
  PetscInt lo = 0, hi = 0;
  VecGetOwnershipRange(m->b, &lo, &hi);
  for (PetscInt r = lo; r < hi; ++r) {
    const int i = static_cast<int>(r % m->nx), j = static_cast<int>(r / m->nx);
    VecSetValue(m->b, r, -f(j, i) * m->x.width(i) * m->y.width(j), INSERT_VALUES);
  }
  VecAssemblyBegin(m->b);
  VecAssemblyEnd(m->b);
  MatNullSpaceRemove(m->ns, m->b);
  KSPSolve(m->ksp, m->b, m->s);
  KSPConvergedReason reason;
  KSPGetConvergedReason(m->ksp, &reason);
  if (reason < 0) throw NumericalFailure(fmt::format("the pressure Poisson solve did not converge ({})", KSPConvergedReasons[reason]), "", "a finer or smoother source, or a looser tolerance");
  PetscInt its = 0;
  KSPGetIterationNumber(m->ksp, &its);
  m->stats.iterations = static_cast<int>(its);
  PetscReal rn = 0, bn = 0;
  KSPGetResidualNorm(m->ksp, &rn);
  VecNorm(m->b, NORM_2, &bn);
  m->stats.residual = bn > 0 ? rn / bn : rn;
  VecScatter sc;
  Vec all;
  VecScatterCreateToAll(m->s, &sc, &all);
  VecScatterBegin(sc, m->s, all, INSERT_VALUES, SCATTER_FORWARD);
  VecScatterEnd(sc, m->s, all, INSERT_VALUES, SCATTER_FORWARD);
  const PetscScalar* a = nullptr;
  VecGetArrayRead(all, &a);
  Eigen::ArrayXXd p(m->ny, m->nx);
  for (int j = 0; j < m->ny; ++j)
    for (int i = 0; i < m->nx; ++i) p(j, i) = a[static_cast<std::size_t>(j) * m->nx + i];
  VecRestoreArrayRead(all, &a);
  VecScatterDestroy(&sc);
  VecDestroy(&all);
  m->stats.solve_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return p;
}

const PoissonStats& PressurePoisson::stats() const { return m->stats; }

}  // namespace mmval::simulate
