#include "Registry.hpp"

namespace mmval::app {

void registerAllKinds(CaseKindRegistry& registry) {
  (void)registry;
}

}  // namespace mmval::app
