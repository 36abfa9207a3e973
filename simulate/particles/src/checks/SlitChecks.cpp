#include "PhysicsChecks.hpp"

namespace mmval::particles::checks {

void registerSlitChecks(CaseKindRegistry& /*registry*/) {}

}  // namespace mmval::particles::checks
