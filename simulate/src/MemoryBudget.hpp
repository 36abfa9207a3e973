// Memory a fluid run will need, estimated before it starts: a grid
// of 4096^2 cells or a 30000 x 30000 mask is refused in a second with the
// estimate and the key to change, instead of ending in PETSc's out-of-memory
// dump or std::bad_alloc after minutes.
//
// The constants are measured peaks (/usr/bin/time -v "Maximum resident set
// size" of `mmval run`, one level, this build), not guesses. The direct LU's
// fill grows like cells log(cells), so the per-cell figure measured at 65536
// cells is a lower bound for larger grids: the check never refuses a run that
// would fit, and refuses the ones that certainly do not.
#pragma once

#include <algorithm>
#include <string>

#include <fmt/format.h>

#include "mmval/core/Case.hpp"
#include "mmval/core/Resources.hpp"

namespace mmval::simulate::detail {

/// Start-up (MPI, PETSc, libraries): 111 MB for `mmval case-check`, ~120 MB before the first solve.
inline constexpr double kStartupBytes = 120e6;
/// Steady coupled (u, v, p) solve, direct LU (UMFPACK): periodic-array phi 0.2 peaked at 156 MB
/// (64^2 cells), 254 MB (128^2), 687 MB (256^2): 8.0 then 8.8 kB per added cell.
inline constexpr double kDirectBytesPerCell = 8.8e3;
/// The same with numerics.linear_solver = "iterative" (GMRES + Schur fieldsplit), measured 2026-12-05
/// after its exact preallocation: square array 2.9 kB per cell (1448^2 and 2048^2); Pore2Chip plane 2D
/// 3.4 kB (3 cells/px) and 3.6 kB (4 cells/px, 14.6 GB); depth-averaged friction split 2.4 kB (1
/// cell/px). 3.8 kB keeps a margin over the largest (was 4.5 kB, FGMRES with 24 entries per row).
inline constexpr double kIterativeBytesPerCell = 3.8e3;
/// The coarse 3D Stokes model of image-permeability (FGMRES + lsc Schur, the default): the Pore2Chip
/// mask at cells_per_pixel_3d 0.25 peaked at 342 MB (125 x 125 x 4 cells) and 585 MB (x 8): 3.9 kB per cell.
inline constexpr double kStokes3DBytesPerCell = 3.9e3;
/// A mask image read and analysed (cv::imread grey 1 B, the bool mask 1 B, its pore-space copy
/// 1 B, component labels 4 B, flood-fill stack up to 4 B, the MaskShape copy 1 B): 12 B per pixel,
/// measured with a 6000 x 6000 all-pore PNG (533 MB peak, the run stopping right after the analysis).
inline constexpr double kMaskBytesPerPixel = 12;
/// What stays of the mask while the solver runs (the bool mask, the pore-space copy, the shape).
inline constexpr double kMaskKeptBytesPerPixel = 3;

/// Peak bytes of one steady 2D solve on `cells` cells, direct LU or iterative.
inline double steadyFlowBytes(double cells, bool iterative) { return kStartupBytes + cells * (iterative ? kIterativeBytesPerCell : kDirectBytesPerCell); }

/// Peak bytes of one steady 2D solve on `cells` cells with the case's numerics.linear_solver.
inline double steadyFlowBytes(const Case& c, double cells) {
  return steadyFlowBytes(cells, c.has("numerics.linear_solver") && c.text("numerics.linear_solver") == "iterative");
}

/// Refuses a steady solve on an nx x ny grid (plus `extra_bytes` held alongside) that does not fit
/// in run.max_memory; `key` is the resolution key to change, `advice` how.
inline void requireSteadyFlowMemory(const Case& c, double nx, double ny, double extra_bytes, const std::string& key, const std::string& advice) {
  const double cells = nx * ny;
  requireMemory(c, steadyFlowBytes(c, cells) + extra_bytes,
                fmt::format("the flow solve on {:.0f} x {:.0f} = {:.3g} cells ({} linear solver, about {:.1f} kB per cell measured)", nx, ny, cells,
                            c.has("numerics.linear_solver") ? c.text("numerics.linear_solver") : "direct",
                            (c.has("numerics.linear_solver") && c.text("numerics.linear_solver") == "iterative" ? kIterativeBytesPerCell
                                                                                                              : kDirectBytesPerCell) /
                                1e3),
                key, advice);
}

}  // namespace mmval::simulate::detail
