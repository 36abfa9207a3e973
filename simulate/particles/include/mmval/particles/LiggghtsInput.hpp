// The LIGGGHTS input we generate, validated before a single command is sent
// (every LIGGGHTS 3.8 input error calls exit(1) or MPI_Abort: there is no error
// API to recover from). Pure
// functions, built and tested without LIGGGHTS.
#pragma once
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "mmval/particles/FlowField.hpp"
#include "mmval/particles/Scene.hpp"

namespace mmval::particles {

struct LiggghtsSetup {
  double x0 = 0, x1 = 0, y0 = 0, y1 = 0, z0 = 0, z1 = 0;  ///< simulation box, m
  double depth = 0;                ///< plates at z = 0 and z = depth, m
  bool side_walls = false;         ///< plane walls at y = wall_y0 and y = wall_y1
  double wall_y0 = 0, wall_y1 = 0;
  /// Grains as a LIGGGHTS mesh wall: an ASCII STL (empty path: no grains), its triangles.
  std::filesystem::path grain_stl;
  long grain_triangles = 0;
  ParticleMaterial particle;
  double cohesion_energy_density = 0;  ///< J/m3, sjkr; 0: no cohesion
  double dt = 0;                   ///< DEM step, s
  double skin = 0;                 ///< neighbour skin, m
  std::filesystem::path log_file, screen_file;
};

/// DEM step: `rayleigh_fraction` of the Rayleigh time, and no more than a
/// twentieth of the Hertz contact time (paper Eq. 14) at `impact_speed`.
double liggghtsTimeStep(const ParticleMaterial& p, double rayleigh_fraction, double impact_speed);

/// The solid region of a gridded field as LIGGGHTS sees it: the vertical faces
/// between solid and fluid nodes' squares (GriddedFlow::isSolid is the nearest
/// node, so its grains are unions of squares of one node spacing around solid
/// nodes), extruded from z0 to z1, as an ASCII STL. Collinear faces are merged
/// into runs of at most `max_run` node spacings, so triangles stay well shaped
/// (LIGGGHTS rejects slivers); both engines see the same grain surfaces.
/// `triangles` receives the count. Faces toward the outside of the grid are not walls.
std::string grainWallStl(const GriddedFlow& flow, double z0, double z1, int max_run, long& triangles);

/// Box, walls and step for a scene: a UniformFlow (plates only), a HeleShawChannel
/// (plates + side walls) or a GriddedFlow (plates + its solid nodes as an STL mesh
/// wall written to cfg.work_dir/grains.stl), of constant depth.
LiggghtsSetup liggghtsSetupFor(const FlowField& flow, const SceneConfig& cfg, double outlet_x);

/// The setup commands, from `units si` to the wall fixes (not the integrator
/// and coupling fixes, which the engine adds). Throws InputError naming the bad
/// value; nothing is generated from unvalidated numbers.
std::vector<std::string> liggghtsSetupCommands(const LiggghtsSetup& s);

/// The version in the first line LIGGGHTS writes to its log and screen,
/// "LIGGGHTS (Version LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown)",
/// or in the text between its parentheses (what the library holds): the text
/// after "Version ", e.g. "LIGGGHTS-PUBLIC 3.8.0, compiled ...". Only the first
/// line of `text` is read; nullopt when it is not such a line (it must name
/// LIGGGHTS and carry a version number).
std::optional<std::string> liggghtsVersionFromHeader(std::string_view text);

/// `create_atoms` + `set` commands for particles `first_id ..` at `positions`;
/// each position must be strictly inside the box (InputError otherwise).
std::vector<std::string> liggghtsInsertCommands(const LiggghtsSetup& s, const std::vector<Vec3>& positions, long first_id);

}  // namespace mmval::particles
