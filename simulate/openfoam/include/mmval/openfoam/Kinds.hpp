// Runs the single-phase scene kinds through the OpenFOAM peer: flow around a
// cylinder in a channel, a periodic square array of cylinders, and chip
// permeability from a mask image. The kinds and their schemas are mmval's own
// fluid solver's (mmval::simulate, registerFluidKinds): they declare every key
// read here, so one case file drives both (`mmval run`, `mmval peer openfoam`,
// and cases tagged "peer" during validate).
#pragma once
#include <optional>
#include <vector>

#include "mmval/core/CaseKind.hpp"
#include "mmval/openfoam/Peer.hpp"

namespace mmval::openfoam {

struct PeerRunOptions {
  int ranks = 1;
  std::optional<std::vector<int>> levels;  ///< overrides numerics.levels
};

/// The scene the peer solves for a case of one of these kinds (geometry, fluid, drive, numerics);
/// a case of another kind is an InputError naming case.kind.
Scene peerScene(const Case& c);

/// Runs a case of one of these kinds through OpenFOAM into ctx.out_dir.
RunOutput runPeer(const Case& c, const RunContext& ctx, const PeerRunOptions& options);

}  // namespace mmval::openfoam
