// Internal: the stages of a particles-resolved run (Resolved.cpp), each with
// its inputs and outputs in view:
//   setUpResolved       case -> scene at t = 0, grid and flow problem (all input checks)
//   cleanPressureDrop   the channel without particles -> dp0 (Pa)
//   transport           frames 1..n: move -> contacts and attachment -> re-solve,
//                       recording trajectories, retention and permeability rows
//                       (resumes from and writes checkpoint.json)
//   writeResolvedFiles  trajectories.csv, retention.csv, permeability.csv, speed.png, fields.vtr,
//                       particles.pvd with a particles/particles-NNNNN.vtp snapshot per frame
//   resolvedResult      metrics (deposition, k/k0, Faxen ratio) and details
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include "ResolvedScene.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/simulate/ResolvedStokes.hpp"

namespace mmval::particles::resolved {

/// The time stepping: frames every output_interval_s; a particle moves at most max_move_m per step
/// near a surface (up to 4 x that in open pores).
struct Stepping {
  double output_interval_s = 0;
  double max_move_m = 0;
};

/// What the case says, checked: the scene at t = 0 and the grid the fluid is solved on. SI.
struct Setup {
  Scene scene;
  simulate::FlowProblem problem;
  nlohmann::json geometry = nlohmann::json::object();  ///< details.geometry of a mask scene
  double viscosity_pa_s = 0;
  double radius_m = 0;          ///< particle radius
  int cells_per_diameter = 0;
  double cell_m = 0;            ///< grid spacing, diameter / cells_per_diameter
  Stepping stepping;
};

/// Reads and checks the case: channel or mask, particles, obstacles, contact and capture
/// distances, grid size. InputError naming the key for particles that overlap a surface,
/// mismatched lists, an output interval longer than the run, or a grid too large.
Setup setUpResolved(const Case& c);

/// Pressure drop (Pa) of the channel without particles: dp0 of k/k0. Leaves that flow in `fluid`.
double cleanPressureDrop(simulate::ResolvedStokes& fluid, const Scene& sc);

/// The run between frames: the outputs so far and the counters.
struct Transport {
  Tracks trajectories;
  std::string permeability_csv, retention_csv;  ///< CSV text, header included
  int solves = 0, steps = 0, contacts = 0, attached = 0;
  double t = 0;                                 ///< s
  std::int64_t frame = 0;                       ///< index of the next frame recorded
  std::vector<Eigen::Vector2d> velocities;      ///< of the disks at their current positions, m/s
  std::int64_t resumed_from = 0;                ///< frame of the checkpoint resumed from (0: a fresh run)
};

/// What a frame's permeability row needs besides the flow: mu U L (Darcy's k = mu U L / dp) and dp0.
struct FrameScales {
  double mu_u_l = 0;
  double dp0_pa = 0;
};

/// Appends the current frame (trajectory points, one retention and one permeability row) and
/// advances tr.frame.
void recordFrame(Transport& tr, const Scene& sc, const simulate::ResolvedStokes& fluid, const FrameScales& scales);

/// Moves the particles from tr.t to t_next by explicit midpoint steps (each particle at most
/// max_move_m, or a quarter of its gap when that is larger, at most 4 max_move_m), settling
/// contacts after each step; ends with tr.t = t_next and tr.velocities at the new positions.
void advanceTo(double t_next, const Stepping& stepping, Transport& tr, Scene& sc, simulate::ResolvedStokes& fluid);

/// Runs frames 1..outputFrames(c), starting afresh (frame 0 recorded) or, with ctx.resume, from
/// ctx.out_dir/checkpoint.json; writes checkpoints every run.checkpoint_every frames and throws
/// RunStopped after run.stop_after_frames.
Transport transport(const Case& c, const RunContext& ctx, const Stepping& stepping, Scene& sc, simulate::ResolvedStokes& fluid,
                    const FrameScales& scales);

/// Writes the run's files into `dir` (trajectories sorted by particle, then frame; the particles
/// as a .vtp series in the frame of fields.vtr) and removes the checkpoint. `pixel_size_m` > 0 adds
/// pixel columns to trajectories.csv. Returns the files for the result, relative to `dir`
/// (particles.pvd stands for its snapshots).
std::vector<std::string> writeResolvedFiles(const std::filesystem::path& dir, Transport& tr, const Scene& sc, const simulate::ResolvedStokes& fluid,
                        double pixel_size_m);

/// Metrics and details of the finished run.
RunOutput resolvedResult(const Setup& setup, const Transport& tr, const Scene& sc, const simulate::ResolvedStokes& fluid, double dp0_pa,
                         double wall_s);

}  // namespace mmval::particles::resolved
