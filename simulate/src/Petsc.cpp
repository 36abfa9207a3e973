#include "mmval/simulate/Petsc.hpp"

#include <stdexcept>

#include <petscsys.h>

namespace mmval::simulate {

namespace {

struct Guard {
  bool we_started = false;
  Guard() {
    PetscBool up = PETSC_FALSE;
    PetscInitialized(&up);
    if (up) return;
    // No PETSc error handler printing to stderr for recoverable errors; we check codes.
    if (PetscInitializeNoArguments() != 0) throw std::runtime_error("PetscInitialize failed");
    we_started = true;
  }
  ~Guard() {
    PetscBool up = PETSC_FALSE, down = PETSC_FALSE;
    PetscInitialized(&up);
    PetscFinalized(&down);
    if (we_started && up && !down) PetscFinalize();
  }
};

}  // namespace

void PetscSession::ensure() { static Guard guard; }

int PetscSession::rank() {
  ensure();
  int r = 0;
  MPI_Comm_rank(PETSC_COMM_WORLD, &r);
  return r;
}

int PetscSession::size() {
  ensure();
  int s = 1;
  MPI_Comm_size(PETSC_COMM_WORLD, &s);
  return s;
}

}  // namespace mmval::simulate
