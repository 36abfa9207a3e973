// Scene settings every particle kind reads alike from its case file.
#pragma once
#include "mmval/core/Case.hpp"
#include "mmval/particles/Scene.hpp"
#include "mmval/particles/SceneSelection.hpp"

namespace mmval::particles {

/// [physics] (Brownian motion from the engine choice when "auto", wall
/// hindrance, Faxen curvature) and [deposition] (capture distance, sticky
/// surfaces, Hamaker constant, attraction range) into `s`.
void physicsAndDepositionFromCase(const Case& c, const EngineChoice& choice, SceneConfig& s);

}  // namespace mmval::particles
