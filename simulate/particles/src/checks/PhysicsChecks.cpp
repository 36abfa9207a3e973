#include "PhysicsChecks.hpp"

namespace mmval::particles::checks {

void registerPhysicsChecks(CaseKindRegistry& registry) {
  registerWallChecks(registry);
  registerSlitChecks(registry);
  registerCollectorChecks(registry);
  registerDlvoChecks(registry);
  registerShearChecks(registry);
}

}  // namespace mmval::particles::checks
