#include "Registry.hpp"

#include "mmval/compare/Kinds.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/tracking/Kinds.hpp"

namespace mmval::app {

void registerAllKinds(CaseKindRegistry& registry) {
  compare::registerCompareKinds(registry);
  openfoam::registerPeerKinds(registry);
  tracking::registerTrackingKinds(registry);
}

}  // namespace mmval::app
