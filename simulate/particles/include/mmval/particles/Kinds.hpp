// Case kinds of the particle engines.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::particles {

/// "particles-channel": particles injected into an analytic Hele-Shaw channel,
/// moved by the engine the scene's numbers pick (or the case forces), with
/// deposition; writes trajectories.csv (shared tracks schema), retention.csv.
/// "particles-micromodel": the coupled validation scene on a pore image
/// (Micromodel.hpp): trajectories.csv, retention.csv, permeability.csv.
/// "particles-resolved": particles spanning many cells, moved by the resolved
/// immersed boundary (Resolved.cpp): trajectories.csv, retention.csv,
/// permeability.csv (with flow through the channel).
/// retention.csv and permeability.csv have one schema for every kind, written
/// by mmval/core/OutputTables.hpp and listed in docs/outputs.md ("Tables").
void registerParticleKinds(CaseKindRegistry& registry);
CaseKind resolvedKind();

}  // namespace mmval::particles
