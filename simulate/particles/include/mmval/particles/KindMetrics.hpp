// The metrics each particle kind reports, with their display units (hence
// dimensions) and meanings: the one declaration that `mmval case-doc` prints
// and `mmval case-check` checks [[acceptance]] entries against.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::particles {

/// Declares the metrics of particles-channel, particles-micromodel and
/// particles-resolved; the kinds must be registered already (throws
/// std::logic_error otherwise).
void declareParticleMetrics(CaseKindRegistry& registry);

}  // namespace mmval::particles
