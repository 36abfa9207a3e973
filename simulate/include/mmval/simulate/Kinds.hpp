// Case kinds run by mmval's own fluid solver (issue 4):
//   channel            plane Poiseuille (periodic + body force, pressure inlet/outlet,
//                      or velocity inlet) and the depth-averaged shallow duct
//   periodic-array     Stokes flow through a square array of cylinders: F*, k / L^2
//   cylinder-channel   steady flow around a cylinder in a channel (Schaefer-Turek 2D-1,
//                      the paper's set-up): c_D, c_L, dp
//   image-permeability chip permeability and porosity from a binary mask, 2D and
//                      depth-averaged
// The schemas are supersets of the OpenFOAM peer's (mmval::openfoam) for the
// same kinds, so one case file drives both solvers; register these instead of
// the peer's kinds (the peer command calls openfoam::runPeer directly).
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::simulate {

void registerFluidKinds(CaseKindRegistry& registry);

/// The individual kinds (registerFluidKinds adds all four).
CaseKind channelKind();
CaseKind periodicArrayKind();
CaseKind cylinderChannelKind();
CaseKind imagePermeabilityKind();

}  // namespace mmval::simulate
