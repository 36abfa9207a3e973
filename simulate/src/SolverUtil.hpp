// Small pieces shared by the PETSc-based solvers and the case kinds: PETSc error
// codes as exceptions, default options the user may override, a distributed
// solution gathered on every rank, and wall-clock seconds since a time point.
#pragma once
#include <algorithm>
#include <chrono>
#include <cstddef>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <petscmat.h>
#include <petscvec.h>

#include "mmval/simulate/FlowSolver.hpp"

namespace mmval::simulate::detail {

/// Throws std::runtime_error naming the PETSc call when `ierr` is not 0.
inline void check(PetscErrorCode ierr, const char* what) {
  if (ierr != 0) throw std::runtime_error(fmt::format("PETSc error {} in {}", static_cast<int>(ierr), what));
}

/// Sets a PETSc option unless the user gave it (command line or PETSC_OPTIONS): the
/// solvers' defaults, overridable.
inline void defaultOption(const std::string& key, const char* value) {
  PetscBool has = PETSC_FALSE;
  PetscOptionsHasName(nullptr, nullptr, key.c_str(), &has);
  if (!has) PetscOptionsSetValue(nullptr, key.c_str(), value);
}

/// A default option that holds only while this object lives, for a setting that
/// suits some solves of a prefix and not others; a value the user gave stays.
class ScopedDefaultOption {
 public:
  ScopedDefaultOption(std::string key, const char* value, bool wanted) : m_key(std::move(key)) {
    PetscBool has = PETSC_FALSE;
    if (wanted) PetscOptionsHasName(nullptr, nullptr, m_key.c_str(), &has);
    m_set = wanted && !has && PetscOptionsSetValue(nullptr, m_key.c_str(), value) == 0;
  }
  ~ScopedDefaultOption() {
    if (m_set) PetscOptionsClearValue(nullptr, m_key.c_str());
  }
  ScopedDefaultOption(const ScopedDefaultOption&) = delete;
  ScopedDefaultOption& operator=(const ScopedDefaultOption&) = delete;

 private:
  std::string m_key;
  bool m_set = false;
};

/// The first `n` entries of the distributed vector `v`, on every rank, into `out`.
/// Throws FlowFailure (a NumericalFailure: the input is valid, the numerics failed) naming
/// `what` (and leaves `out` as it was) when any is not finite.
/// Throws FlowFailure naming `what` unless the n values are all finite.
inline void requireFinite(const double* a, long long n, const std::string& what) {
  for (long long k = 0; k < n; ++k)
    if (!std::isfinite(a[k])) throw FlowFailure(what + " is not finite (NaN or Inf)", "refine the grid");
}

inline void gatherToAll(Vec v, long long n, std::vector<double>& out, const std::string& what) {
  int ranks = 1;
  MPI_Comm_size(PetscObjectComm(reinterpret_cast<PetscObject>(v)), &ranks);
  VecScatter sc = nullptr;
  Vec all = v;  // one rank: v holds every entry already
  if (ranks > 1) {
    check(VecScatterCreateToAll(v, &sc, &all), "scatter");
    check(VecScatterBegin(sc, v, all, INSERT_VALUES, SCATTER_FORWARD), "scatter");
    check(VecScatterEnd(sc, v, all, INSERT_VALUES, SCATTER_FORWARD), "scatter");
  }
  const PetscScalar* a = nullptr;
  VecGetArrayRead(all, &a);
  bool finite = true;
  for (long long k = 0; k < n; ++k) finite = finite && std::isfinite(a[k]);
  if (finite) out.assign(a, a + n);
  VecRestoreArrayRead(all, &a);
  if (ranks > 1) {
    VecScatterDestroy(&sc);
    VecDestroy(&all);
  }
  if (!finite) throw FlowFailure(what + " is not finite (NaN or Inf)", "refine the grid");
}

inline double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Whether A is a sequential AIJ matrix whose compressed rows are exactly (start, cols) (row
/// offsets and column indices, in order): its value array then lines up with values laid out by
/// them, and a caller may write them in place (MatSeqAIJGetArray) instead of through MatSetValues.
template <typename Offset>
bool seqAijRowsAre(Mat A, const std::vector<Offset>& start, const std::vector<PetscInt>& cols) {
  PetscBool seq = PETSC_FALSE;
  check(PetscObjectTypeCompare(reinterpret_cast<PetscObject>(A), MATSEQAIJ, &seq), "type");
  if (!seq) return false;
  PetscInt n = 0;
  const PetscInt *ia = nullptr, *ja = nullptr;
  PetscBool done = PETSC_FALSE;
  check(MatGetRowIJ(A, 0, PETSC_FALSE, PETSC_FALSE, &n, &ia, &ja, &done), "MatGetRowIJ");
  bool same = done && static_cast<std::size_t>(n) + 1 == start.size();
  for (std::size_t q = 0; same && q < start.size(); ++q) same = static_cast<std::size_t>(ia[q]) == static_cast<std::size_t>(start[q]);
  same = same && static_cast<std::size_t>(ia[n]) == cols.size() && std::equal(cols.begin(), cols.end(), ja);
  check(MatRestoreRowIJ(A, 0, PETSC_FALSE, PETSC_FALSE, &n, &ia, &ja, &done), "MatRestoreRowIJ");
  return same;
}

}  // namespace mmval::simulate::detail
