// Field output of a solved flow: VTK XML rectilinear grid (.vtr, binary, opens
// in ParaView; stretched axes kept exactly) in the frame of docs/outputs.md
// (metres, x right, y up, origin at the domain's bottom-left corner), with cell
// arrays p (Pa), U (m/s, 3 components) and solid (solid fraction of the cell,
// 0 fluid to 1 solid; 2D and 3D alike), units as field data and, for unsteady
// solutions, the time as TimeValue; and a PNG of the velocity magnitude over
// the geometry (solid cells grey) for reports. Both are written atomically;
// callers write from one MPI rank only.
#pragma once
#include <filesystem>
#include <vector>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/ResolvedStokes.hpp"
#include "mmval/simulate/Stokes3D.hpp"
#include "mmval/simulate/UnsteadyFlowSolver.hpp"

namespace mmval::simulate {

/// Writes `file` (.vtr). Throws std::runtime_error on I/O failure.
void writeVtr(const SteadyFlowSolver& solver, const std::filesystem::path& file);
/// The current time level of an unsteady solution (TimeValue: its time, s).
void writeVtr(const UnsteadyFlowSolver& solver, const std::filesystem::path& file);

/// Writes `file` (.png), one pixel per cell resampled to at most max_pixels on
/// the long side (uniform in physical space, so stretched grids look right).
void writeSpeedPng(const SteadyFlowSolver& solver, const std::filesystem::path& file, int max_pixels = 1200);
void writeSpeedPng(const UnsteadyFlowSolver& solver, const std::filesystem::path& file, int max_pixels = 1200);
/// The flow of the last solve of moving bodies (the bodies drawn grey); `paths` (m) are drawn over it
/// in white, each start ringed and each end dotted.
void writeVtr(const ResolvedStokes& solver, const std::filesystem::path& file);
void writeSpeedPng(const ResolvedStokes& solver, const std::filesystem::path& file, int max_pixels = 1200,
                   const std::vector<std::vector<Eigen::Vector2d>>& paths = {});

/// A 3D Stokes solution as a .vtr over its nx x ny x nz cells: cell pressure,
/// cell-centred velocity (mean of the two faces per axis) and solid (0 or 1).
/// The solver's y cell j is image row j (top down); the file mirrors it to y up.
void writeVtr(const Stokes3DSolver& solver, const std::filesystem::path& file);
/// Speed in the mid-depth layer of a 3D solution (its fastest, the Poiseuille centre),
/// one pixel per cell, y up; solid cells grey.
void writeMidDepthSpeedPng(const Stokes3DSolver& solver, const std::filesystem::path& file);

}  // namespace mmval::simulate
