// Runs the single-phase scene kinds through the OpenFOAM peer: flow around a
// cylinder in a channel, a periodic square array of cylinders, and chip
// permeability from a mask image. The kinds and their schemas are mmval's own
// fluid solver's (mmval::simulate, registerFluidKinds): they declare every key
// read here, so one case file drives both (`mmval run`, `mmval peer openfoam`,
// and cases tagged "peer" during validate).
#pragma once
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "mmval/core/CaseKind.hpp"
#include "mmval/openfoam/Peer.hpp"

namespace mmval::simulate {
struct CylinderScene;
struct PeriodicArrayScene;
}  // namespace mmval::simulate

namespace mmval::openfoam {

struct PeerRunOptions {
  int ranks = 1;
  std::optional<std::vector<int>> levels;  ///< overrides numerics.levels
  /// image-permeability: mesh with snappyHexMesh on the boundary's STL (the smooth boundary refined
  /// once at the grains; the pixel outlines) instead of mmval's direct mesher (the default:
  /// Scene::direct_mesh; for geometry.boundary = "pixels" at whole numbers of cells per pixel).
  bool snappy_image_mesh = false;
  /// Runs one level (scene, case folder, ranks); empty: openfoam::runCase. Tests give canned
  /// Results here to check the reporting without OpenFOAM.
  std::function<Result(const Scene&, const std::filesystem::path&, int)> runner;
};

/// The scene the peer solves for a case of one of these kinds (geometry, fluid, drive, numerics);
/// a case of another kind is an InputError naming case.kind.
Scene peerScene(const Case& c);

/// The peer's scene of a solver-neutral cylinder-channel scene (simulate::readCylinderScene's):
/// channel, cylinder, fluid, inflow, force scales and probes as given; numerics at Scene's
/// defaults (steady, 64 cells around). The one place the two structs' fields are matched.
Scene peerScene(const simulate::CylinderScene& scene);

/// The peer's scene of a solver-neutral periodic-array scene (simulate::readPeriodicArrayScene's)
/// at `cells_per_side` cells along the unit-cell side (the O-grid's cells around follow from it,
/// arrayCellsAround); the one-cell-thick mesh is L / 10 deep; other numerics at Scene's defaults.
Scene peerScene(const simulate::PeriodicArrayScene& scene, int cells_per_side);

/// The O-grid's cells around the cylinder of a periodic-array scene (Scene::cells_around) at
/// `cells_per_side` cells along its unit-cell side: the surface spacing of mmval's grid
/// h = L / cells_per_side, in cells around (cellsAroundForSpacing: a multiple of 4, at least 8).
int arrayCellsAround(const Scene& s, int cells_per_side);

/// The warning for a steady level that did not converge: case folder, iterations against the cap,
/// final residuals against the target, and the key to change.
std::string notConvergedText(const Scene& s, const Result& r, const std::string& case_dir);

/// Runs a case of one of these kinds through OpenFOAM into ctx.out_dir. A steady level whose
/// SIMPLE loop did not converge (Result::converged) is reported "not converged" with its
/// residuals in its ladder row, without a value; if it is the finest level, its metrics are null
/// and details.status is "not converged".
RunOutput runPeer(const Case& c, const RunContext& ctx, const PeerRunOptions& options);

}  // namespace mmval::openfoam
