// Starts PETSc before the first test of a binary (1 MPI rank); the library's
// session guard finalises it at process exit.
#include <gtest/gtest.h>

#include "mmval/simulate/Petsc.hpp"

namespace {
class PetscEnvironment : public ::testing::Environment {
 public:
  void SetUp() override { mmval::simulate::PetscSession::ensure(); }
};
const auto* const kEnv = ::testing::AddGlobalTestEnvironment(new PetscEnvironment);
}  // namespace
