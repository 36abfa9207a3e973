#include "PhysicsChecks.hpp"

namespace mmval::particles::checks {

void registerShearChecks(CaseKindRegistry& /*registry*/) {}

}  // namespace mmval::particles::checks
