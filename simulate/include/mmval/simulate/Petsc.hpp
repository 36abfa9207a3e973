// PETSc lifetime for the fluid solver: initialised once per process on first
// use, finalised at process exit (after main returns). If MPI is already
// running (another library or the test main started it), PETSc uses it and
// leaves finalising MPI to whoever started it.
#pragma once
#include <mpi.h>

namespace mmval::simulate {

class PetscSession {
 public:
  /// Initialises PETSc if needed (thread-unsafe: call from the main thread).
  /// Throws std::runtime_error if PETSc cannot start.
  static void ensure();
  /// Rank and size of MPI_COMM_WORLD (ensure() first).
  static int rank();
  static int size();
};

}  // namespace mmval::simulate
