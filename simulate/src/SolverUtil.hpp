// Small pieces shared by the PETSc-based solvers and the case kinds: PETSc error
// codes as exceptions, and wall-clock seconds since a time point.
#pragma once
#include <chrono>
#include <stdexcept>

#include <fmt/format.h>
#include <petscsys.h>

namespace mmval::simulate::detail {

/// Throws std::runtime_error naming the PETSc call when `ierr` is not 0.
inline void check(PetscErrorCode ierr, const char* what) {
  if (ierr != 0) throw std::runtime_error(fmt::format("PETSc error {} in {}", static_cast<int>(ierr), what));
}

inline double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace mmval::simulate::detail
