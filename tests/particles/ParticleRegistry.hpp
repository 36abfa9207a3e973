// Test helper: one registry with every particle case kind, built on first use.
#pragma once
#include "mmval/core/CaseKind.hpp"
#include "mmval/particles/Kinds.hpp"

namespace mmval::particles::test_support {

inline CaseKindRegistry& particleRegistry() {
  static CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    registerParticleKinds(reg);
    return reg;
  }();
  return r;
}

}  // namespace mmval::particles::test_support
