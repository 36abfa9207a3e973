// Case kinds run by mmval's own Stokes solver.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::stokes {

/// "channel": plane Poiseuille / depth-averaged shallow duct. Also provides the
/// runner for "periodic-array" (whose schema the OpenFOAM peer kinds declare,
/// so one case file drives both solvers).
void registerStokesKinds(CaseKindRegistry& registry);

RunOutput runPeriodicArray(const Case& c, const RunContext& ctx);

}  // namespace mmval::stokes
