#include "PhysicsChecks.hpp"

namespace mmval::particles::checks {

void registerCollectorChecks(CaseKindRegistry& /*registry*/) {}

}  // namespace mmval::particles::checks
