// Scene settings every particle kind reads alike from its case file.
#pragma once
#include <cstdint>

#include "mmval/core/Case.hpp"
#include "mmval/core/Schema.hpp"
#include "mmval/particles/Dlvo.hpp"
#include "mmval/particles/Scene.hpp"
#include "mmval/particles/SceneSelection.hpp"

namespace mmval::particles {

/// Declares physics.gravity, physics.brownian, physics.wall_hindrance,
/// physics.faxen_curvature and the deposition.* keys read below.
void declarePhysicsAndDeposition(Schema& s, double hamaker_default);
/// numerics.threads (OverdampedEngine's per-particle loops), numerics.substeps (its per-particle
/// steps) and numerics.drift_integrator, for every kind that runs the overdamped engine.
void declareEngineNumerics(Schema& s);
/// numerics.drift_integrator ("euler" or "heun": SceneConfig::heun_drift), declared by
/// declareEngineNumerics and by the kinds that set the engine's numerics themselves.
void declareDriftIntegrator(Schema& s);
bool heunDriftFromCase(const Case& c);
/// Those three keys into `s`; InputError naming numerics.substeps when it is not a power of 2.
void engineNumericsFromCase(const Case& c, SceneConfig& s);

/// [physics] (Brownian motion from the engine choice when "auto", wall
/// hindrance, Faxen curvature) and [deposition] (capture distance, sticky
/// surfaces, Hamaker constant, attraction range) into `s`.
void physicsAndDepositionFromCase(const Case& c, const EngineChoice& choice, SceneConfig& s);

/// Declares the chemistry.* keys of a DLVO interaction (surface potentials, electrolyte,
/// Hamaker constant, double-layer model, Born term), with defaults from DlvoParameters;
/// chemistry.temperature only when `with_temperature` (particle scenes use fluid.temperature).
void declareChemistry(Schema& s, bool with_temperature);
/// Those keys into DlvoParameters (radii left at their defaults for the caller to set);
/// temperature from `temperature_key`. InputError (key "chemistry") when they define no interaction.
DlvoParameters chemistryFromCase(const Case& c, const char* temperature_key);

/// Output frames of the run, run.duration / run.output_interval (rounded), after checking
/// that what every frame keeps in memory until the end fits in run.max_memory: a
/// picosecond output interval or a run of 1e9 s is refused at once (InputError naming the
/// key) instead of growing until the allocation fails.
std::int64_t outputFrames(const Case& c);

}  // namespace mmval::particles
