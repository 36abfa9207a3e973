#include "PhysicsChecks.hpp"

namespace mmval::particles::checks {

void registerWallChecks(CaseKindRegistry& /*registry*/) {}

}  // namespace mmval::particles::checks
