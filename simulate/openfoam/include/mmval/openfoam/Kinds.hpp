// Single-phase scene kinds run through the OpenFOAM peer: flow around a
// cylinder in a channel, a periodic square array of cylinders, and chip
// permeability from a mask image. The same case files are meant for
// mmval's own fluid solver (issue 4); until it lands, `mmval run` on these
// kinds runs the peer, and result.json says so (details.solver).
#pragma once
#include <optional>
#include <vector>

#include "mmval/core/CaseKind.hpp"

namespace mmval::openfoam {

struct PeerRunOptions {
  int ranks = 1;
  std::optional<std::vector<int>> levels;  ///< overrides numerics.levels
};

void registerPeerKinds(CaseKindRegistry& registry);

/// Runs a case of one of these kinds through OpenFOAM into ctx.out_dir.
RunOutput runPeer(const Case& c, const RunContext& ctx, const PeerRunOptions& options);

}  // namespace mmval::openfoam
