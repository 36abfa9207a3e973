#include "Registry.hpp"

#include "mmval/compare/Kinds.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/particles/Kinds.hpp"
#include "mmval/stokes/Kinds.hpp"
#include "mmval/tracking/Kinds.hpp"

namespace mmval::app {

void registerAllKinds(CaseKindRegistry& registry) {
  compare::registerCompareKinds(registry);
  openfoam::registerPeerKinds(registry);
  // Our own solver runs what it can; the peer keeps the rest until ours covers them.
  stokes::registerStokesKinds(registry);
  registry.replaceRunner("periodic-array", stokes::runPeriodicArray);
  tracking::registerTrackingKinds(registry);
  particles::registerParticleKinds(registry);
}

}  // namespace mmval::app
