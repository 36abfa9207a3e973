#include "PhysicsChecks.hpp"

namespace mmval::particles::checks {

void registerDlvoChecks(CaseKindRegistry& /*registry*/) {}

}  // namespace mmval::particles::checks
