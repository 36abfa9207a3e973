#include "Registry.hpp"

#include "mmval/compare/Kinds.hpp"
#include "mmval/openfoam/Kinds.hpp"

namespace mmval::app {

void registerAllKinds(CaseKindRegistry& registry) {
  compare::registerCompareKinds(registry);
  openfoam::registerPeerKinds(registry);
}

}  // namespace mmval::app
