// The metrics each tracking kind reports, with their display units (hence
// dimensions) and meanings: the one declaration that `mmval case-doc` prints
// and `mmval case-check` checks [[acceptance]] entries against.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::tracking {

/// Declares the metrics of tracking-video, tracking-synthetic and
/// tracking-rendered; the kinds must be registered already (throws
/// std::logic_error otherwise).
void declareTrackingMetrics(CaseKindRegistry& registry);

}  // namespace mmval::tracking
