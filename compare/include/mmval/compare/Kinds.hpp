// Case kinds of the comparator.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::compare {

/// "compare-tracks": experiment tracks vs simulated trajectories, both files
/// named in the case, with the tolerances of each metric.
void registerCompareKinds(CaseKindRegistry& registry);

}  // namespace mmval::compare
