// The metrics the comparator reports (Compare.cpp, Scene.cpp), with their
// display units (hence dimensions) and meanings: the one declaration that
// `mmval case-doc` prints and `mmval case-check` checks [[acceptance]] entries against.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::compare {

/// Declares the metrics of compare-tracks; the kind must be registered
/// already (throws std::logic_error otherwise).
void declareCompareMetrics(CaseKindRegistry& registry);

}  // namespace mmval::compare
