// The registry of every case kind mmval ships (apps/Registry.cpp), built once
// per test binary, for the contract tests that go over all kinds.
#pragma once
#include "../../apps/Registry.hpp"
#include "mmval/core/CaseKind.hpp"

namespace mmval::test {

inline const CaseKindRegistry& allKinds() {
  static const CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    app::registerAllKinds(reg);
    return reg;
  }();
  return r;
}

}  // namespace mmval::test
