// Case kinds run by mmval's own fluid solver:
//   channel            plane Poiseuille (periodic + body force, pressure inlet/outlet,
//                      or velocity inlet) and the depth-averaged shallow duct
//   periodic-array     Stokes flow through a square array of cylinders: F*, k / L^2
//   cylinder-channel   steady or unsteady flow around a cylinder in a channel
//                      (Schaefer-Turek 2D-1 and 2D-2, the paper's set-up): c_D, c_L,
//                      dp; c_D max, c_L max, St
//   image-permeability chip permeability and porosity from a binary mask: 2D,
//                      depth-averaged and coarse 3D
// The schemas of the last three also declare every key the OpenFOAM peer reads
// (mmval::openfoam::runPeer, which has no schemas of its own), so one case file
// drives both solvers.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::simulate {

void registerFluidKinds(CaseKindRegistry& registry);

/// The individual kinds (registerFluidKinds adds all four).
CaseKind channelKind();
CaseKind periodicArrayKind();
CaseKind cylinderChannelKind();
CaseKind imagePermeabilityKind();
/// The micromodel generator as a case kind (KindsChip.cpp): `mmval chip` run from a case file.
CaseKind chipGeneratorKind();

}  // namespace mmval::simulate
