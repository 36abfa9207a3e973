#include "Registry.hpp"

#include "mmval/compare/Kinds.hpp"
#include "mmval/particles/Kinds.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/tracking/Kinds.hpp"

namespace mmval::app {

void registerAllKinds(CaseKindRegistry& registry) {
  compare::registerCompareKinds(registry);
  // mmval's fluid solver runs the single-phase kinds, steady and unsteady; their schemas
  // cover every key the OpenFOAM peer reads, so `mmval peer openfoam` takes the same case
  // files, and cases tagged "peer" also run through OpenFOAM during validate.
  simulate::registerFluidKinds(registry);
  tracking::registerTrackingKinds(registry);
  particles::registerParticleKinds(registry);
}

}  // namespace mmval::app
