// Field output of a solved flow: VTK XML rectilinear grid (.vtr, opens in
// ParaView; stretched axes kept exactly) with cell pressure, cell velocity
// and solid fraction, and a PNG of the velocity magnitude over the geometry
// (solid cells grey) for reports. Both are written atomically; callers write
// from one MPI rank only.
#pragma once
#include <filesystem>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/UnsteadyFlowSolver.hpp"

namespace mmval::simulate {

/// Writes `file` (.vtr). Throws std::runtime_error on I/O failure.
void writeVtr(const SteadyFlowSolver& solver, const std::filesystem::path& file);
/// The current time level of an unsteady solution.
void writeVtr(const UnsteadyFlowSolver& solver, const std::filesystem::path& file);

/// Writes `file` (.png), one pixel per cell resampled to at most max_pixels on
/// the long side (uniform in physical space, so stretched grids look right).
void writeSpeedPng(const SteadyFlowSolver& solver, const std::filesystem::path& file, int max_pixels = 1200);
void writeSpeedPng(const UnsteadyFlowSolver& solver, const std::filesystem::path& file, int max_pixels = 1200);

}  // namespace mmval::simulate
