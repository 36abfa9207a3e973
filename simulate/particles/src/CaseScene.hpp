// Scene settings every particle kind reads alike from its case file.
#pragma once
#include "mmval/core/Case.hpp"
#include "mmval/core/Schema.hpp"
#include "mmval/particles/Scene.hpp"
#include "mmval/particles/SceneSelection.hpp"

namespace mmval::particles {

/// Declares physics.gravity, physics.brownian, physics.wall_hindrance,
/// physics.faxen_curvature and the deposition.* keys read below.
void declarePhysicsAndDeposition(Schema& s, double hamaker_default);

/// [physics] (Brownian motion from the engine choice when "auto", wall
/// hindrance, Faxen curvature) and [deposition] (capture distance, sticky
/// surfaces, Hamaker constant, attraction range) into `s`.
void physicsAndDepositionFromCase(const Case& c, const EngineChoice& choice, SceneConfig& s);

}  // namespace mmval::particles
