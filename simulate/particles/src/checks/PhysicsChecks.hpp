// Checks of the particle physics against theory: each check is a case kind
// ("physics-...") whose runner sets up the smallest scene that isolates one
// mechanism, runs the engine and reports the measured value next to its
// analytic or tabulated reference. Cases in cases/physics-*.toml are tagged
// "physics" (`mmval validate --tag physics`). Each group of checks lives in its
// own file and registers its kinds (and their metrics) itself.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::particles::checks {

/// Sedimentation equilibrium, hindered diffusion near a wall, blocking (WallChecks.cpp).
void registerWallChecks(CaseKindRegistry& registry);
/// Settling and diffusion deposition in a slit (SlitChecks.cpp).
void registerSlitChecks(CaseKindRegistry& registry);
/// Single-collector efficiency of a post array (CollectorCheck.cpp).
void registerCollectorChecks(CaseKindRegistry& registry);
/// DLVO interaction profiles and attachment rates (DlvoChecks.cpp).
void registerDlvoChecks(CaseKindRegistry& registry);
/// Near-wall translation and rotation in shear (ShearCheck.cpp).
void registerShearChecks(CaseKindRegistry& registry);

/// All of the above.
void registerPhysicsChecks(CaseKindRegistry& registry);

}  // namespace mmval::particles::checks
