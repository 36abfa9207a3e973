// The metrics each fluid kind reports, with their display units (hence
// dimensions) and meanings: the one declaration that `mmval case-doc` prints
// and `mmval case-check` checks [[acceptance]] entries against. It covers the
// metrics of both solvers that run these kinds: mmval's own (Kinds*.cpp) and
// the OpenFOAM peer (simulate/openfoam/src/Kinds.cpp, addMetrics).
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::simulate {

/// Declares the metrics of channel, periodic-array, cylinder-channel and
/// image-permeability; the kinds must be registered already (throws
/// std::logic_error otherwise).
void declareFluidMetrics(CaseKindRegistry& registry);

}  // namespace mmval::simulate
