#include "Registry.hpp"

#include "mmval/compare/Kinds.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/particles/Kinds.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/tracking/Kinds.hpp"

namespace mmval::app {

void registerAllKinds(CaseKindRegistry& registry) {
  compare::registerCompareKinds(registry);
  // mmval's fluid solver runs the single-phase kinds; their schemas cover every key the
  // OpenFOAM peer reads, so `mmval peer openfoam` takes the same case files. Unsteady
  // cylinder flow is not in our solver yet: those cases go to the peer, and result.json
  // says so (details.solver).
  simulate::registerFluidKinds(registry);
  {
    const auto steady = registry.find("cylinder-channel")->run;
    registry.replaceRunner("cylinder-channel", [steady](const Case& c, const RunContext& ctx) {
      if (c.text("numerics.mode") == "unsteady") return openfoam::runPeer(c, ctx, {});
      return steady(c, ctx);
    });
  }
  tracking::registerTrackingKinds(registry);
  particles::registerParticleKinds(registry);
}

}  // namespace mmval::app
