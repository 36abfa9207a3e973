#include "mmval/particles/EngineFactory.hpp"

#include "mmval/core/Error.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
#ifdef MMVAL_WITH_LIGGGHTS
#include "mmval/particles/LiggghtsEngine.hpp"
#endif

namespace mmval::particles {

bool liggghtsAvailable() {
#ifdef MMVAL_WITH_LIGGGHTS
  return true;
#else
  return false;
#endif
}

std::unique_ptr<ParticleEngine> makeEngine(EngineKind kind, std::shared_ptr<const FlowField> flow, const SceneConfig& config) {
  if (kind == EngineKind::overdamped) return std::make_unique<OverdampedEngine>(std::move(flow), config);
#ifdef MMVAL_WITH_LIGGGHTS
  return std::make_unique<LiggghtsEngine>(std::move(flow), config);
#else
  throw InputError(keyLocation("particles.engine"), "this build has no LIGGGHTS engine", "liggghts",
                   "\"overdamped\", or rebuild with libliggghts-dev installed and -DMMVAL_WITH_LIGGGHTS=ON");
#endif
}

}  // namespace mmval::particles
