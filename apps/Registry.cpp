#include "Registry.hpp"

#include "mmval/compare/Kinds.hpp"

namespace mmval::app {

void registerAllKinds(CaseKindRegistry& registry) {
  compare::registerCompareKinds(registry);
}

}  // namespace mmval::app
