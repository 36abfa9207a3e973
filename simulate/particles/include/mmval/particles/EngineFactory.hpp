// Creating an engine by kind, whether or not LIGGGHTS was built in.
#pragma once
#include <memory>

#include "mmval/particles/Scene.hpp"
#include "mmval/particles/SceneSelection.hpp"

namespace mmval::particles {

/// True when this build has the LIGGGHTS engine (MMVAL_WITH_LIGGGHTS).
bool liggghtsAvailable();

/// The engine of `kind` on MPI_COMM_WORLD. Throws InputError (key "particles.engine")
/// when LIGGGHTS is asked for but not built in.
std::unique_ptr<ParticleEngine> makeEngine(EngineKind kind, std::shared_ptr<const FlowField> flow, const SceneConfig& config);

}  // namespace mmval::particles
