// The registry of the fluid case kinds, built once per test binary.
#pragma once

#include "mmval/core/Run.hpp"
#include "mmval/simulate/Kinds.hpp"

namespace mmval::test_support {

inline const CaseKindRegistry& fluidRegistry() {
  static const CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    simulate::registerFluidKinds(reg);
    return reg;
  }();
  return r;
}

}  // namespace mmval::test_support
