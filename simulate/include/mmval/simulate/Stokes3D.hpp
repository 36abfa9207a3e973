// Steady 3D Stokes flow through a chip: a 2D grain mask extruded through the
// depth between two no-slip plates.
//
// Discretisation. Staggered MAC grid (Harlow & Welch 1965), uniform spacing
// per axis (dx, dy in the plane, dz across the depth; cells may be strongly
// anisotropic, e.g. 40 x 40 x 2.5 um). Pressure at cell centres, u, v, w on
// the x-, y-, z-faces. Momentum is the finite-volume balance of viscous
// fluxes mu A (u_P - u_Q) / d and the pressure force on each face's control
// volume; continuity is the discrete divergence of the face velocities, so
// the solution is divergence-free to solver tolerance.
//
// Geometry and boundaries.
//  - x (flow): pressure inlet (x = 0) and outlet (x = L): the boundary face's
//    control volume is the half cell next to it, the given pressure acts on
//    the boundary face, and the normal gradient of every velocity is zero.
//  - y (sides): slip (zero normal velocity, zero shear) or no-slip.
//  - z = 0 and z = h: no-slip plates (mirror ghost, wall half a cell away).
//  - Solids are whole cells of the (coarse) mask, the same in every z layer.
//    Every face touching a solid cell carries zero velocity. A fluid node's
//    viscous flux towards a zero node uses the true wall distance: a full
//    spacing when that node lies on the solid's surface, half a spacing when it
//    lies inside the solid (the wall is then the cell face between them), as
//    the sharp treatment of the 2D solver does on a pixel staircase.
//  - Pores not joined to both the inlet and the outlet (4-connected in the
//    plane, which is face connectivity of the extruded geometry) are made
//    solid (PoreSpace), so every remaining pressure is determined.
// Known discrete error: plane Poiseuille between the plates gives exactly
// Q_h / Q = 1 + 2 (dz / h)^2 (the ghost-wall closure shifts the parabola by
// G dz^2 / (8 mu), the midpoint rule adds G h dz^2 / (24 mu)), second order.
//
// Solution. The coupled (u, v, w, p) system of the free unknowns (faces not
// fixed, fluid cells) is assembled into one PETSc AIJ matrix; every rank
// assembles its own row range of the replicated grid and receives the whole
// solution. FGMRES with a Schur-complement fieldsplit (upper factorisation):
// BoomerAMG (hypre) on the velocity block, and for the Schur complement one of
//  - "lsc" (default): the least-squares commutator (Elman, Howle, Shadid,
//    Shuttleworth & Tuminaro 2006), S^-1 ~ (B B^T)^-1 B A B^T (B B^T)^-1 with
//    BoomerAMG for the two pressure Poisson solves. It sees the velocity
//    operator itself, so it follows the Poiseuille response across the depth:
//    on Pore2Chip with 40 um cells in the plane, 15 / 20 / 28 / 41 iterations
//    at nz 4 / 8 / 16 / 32 (against 15 / 28 / 55 / 107 for selfp); with 80 um
//    cells 17 / 25 / 34 at nz 8 / 16 / 32 (selfp 24 / 48 / 91).
//  - "selfp": B diag(A)^-1 B^T, AMG-preconditioned. In a thin gap diag(A) is
//    dominated by the viscous term across the depth (~2 mu / dz^2), while a
//    pressure gradient constant across the depth drives a Poiseuille profile
//    (mean velocity h^2 / (12 mu) per unit gradient): the approximation is
//    off by ~nz^2 / 6 for those modes (and by less for slow variations across
//    the depth): measured iterations grow ~linearly in nz (15 / 28 / 55 / 107 at
//    nz 4 / 8 / 16 / 32 on Pore2Chip). A two-level variant (this plus an exact
//    depth-averaged Hele-Shaw solve for the depth mean) gave 46 vs 48 (63 x 63 x 16)
//    iterations, so it was not kept; a column-coupled (z-line) Schur
//    approximation is the candidate for large nz.
//  - "mass": the pressure mass matrix / mu (Silvester & Wathen 1994):
//    grid-independent for open Stokes problems, but its quality falls with
//    the gap aspect ratio (the inf-sup constant of a thin domain): more than
//    1000 iterations on Pore2Chip (5 mm x 20 um).
// PETSc options with prefix "stokes3d_" (lsc), "stokes3ds_" (selfp) or "stokes3dm_" (mass)
// override the defaults (e.g. -stokes3d_ksp_monitor).
#pragma once
#include <optional>
#include <vector>
#include <memory>
#include <string>
#include <vector>

#include <mpi.h>

#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::simulate {

struct Stokes3DProblem {
  double length = 0;  ///< x extent L (flow direction), m
  double width = 0;   ///< y extent W, m
  double depth = 0;   ///< z extent h (gap between the plates), m
  int nx = 0, ny = 0, nz = 0;
  /// Solid cells, ny rows x nx columns (row j = y cell j, column i = x cell i),
  /// extruded through the depth; empty: no grains.
  BoolArray solid;
  bool slip_sides = true;       ///< y = 0, W: slip (true) or no-slip walls
  double viscosity = 1e-3;      ///< Pa s
  double inlet_pressure = 1.0;  ///< at x = 0, Pa
  double outlet_pressure = 0;   ///< at x = L, Pa
};

struct Stokes3DOptions {
  std::string schur = "lsc";  ///< "lsc", "selfp" or "mass" (see the top comment)
  double rtol = 1e-9;           ///< FGMRES relative residual
  int max_iterations = 1000;
};

struct Stokes3DStats {
  long long cells = 0;        ///< nx ny nz
  long long fluid_cells = 0;  ///< connected fluid cells
  long long unknowns = 0;     ///< free velocities + fluid-cell pressures
  int iterations = 0;         ///< FGMRES iterations
  double assemble_seconds = 0, solve_seconds = 0;
  double porosity_total = 0;      ///< fluid cells / cells of the coarse grid
  double porosity_connected = 0;  ///< after removing isolated pores
};

class Stokes3DSolver {
 public:
  /// Throws std::invalid_argument for a malformed problem (sizes, mask shape,
  /// options) and NoFlowPath if no fluid path joins inlet and outlet.
  explicit Stokes3DSolver(Stokes3DProblem problem, Stokes3DOptions options = {}, MPI_Comm comm = MPI_COMM_WORLD);
  ~Stokes3DSolver();
  Stokes3DSolver(const Stokes3DSolver&) = delete;
  Stokes3DSolver& operator=(const Stokes3DSolver&) = delete;

  /// Solves (collective on comm). Throws std::runtime_error if FGMRES does not
  /// converge or the solution is not finite.
  void solve();

  const Stokes3DProblem& problem() const;
  const Stokes3DStats& stats() const;
  /// Volume flow rate through the x-face plane n (0: inlet, nx: outlet), m3/s.
  double flowRate(int n) const;
  /// Darcy permeability from the outlet flow rate, k = mu Q L / (W h dp), m2.
  double permeability() const;
  /// Face velocities (m/s) and cell pressure (Pa) by grid index; fixed faces are 0.
  double u(int i, int j, int k) const;
  double v(int i, int j, int k) const;
  double w(int i, int j, int k) const;
  double p(int i, int j, int k) const;
  /// max over fluid cells of |div u| min(dx, dy, dz) / max |u| (solver-tolerance small).
  double maxRelativeDivergence() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

/// Block-averages a fine mask (rows x cols) onto ny x nx coarse cells: a cell is
/// solid if more than half of the pixels whose centres it contains are solid
/// (with no pixel centre inside, the pixel under the cell centre decides).
BoolArray coarsenMask(const BoolArray& fine, int nx, int ny);

/// The coarse 3D model of a pore mask (image-permeability's depth_model "3d", `mmval chip
/// --permeability-model 3d`): the mask (rows x cols pixels of `pixel` m) block-averaged onto
/// round(cols x cells_per_pixel) x round(rows x cells_per_pixel) cells (at least 4 each), extruded
/// between no-slip plates `depth` apart, slip sides, `pressure_drop` from x = 0 to x = L; nz unset.
Stokes3DProblem maskStokes3DProblem(const BoolArray& solid, double pixel, double depth, double viscosity, double pressure_drop, double cells_per_pixel);

/// Richardson extrapolation of k over the two finest cells_z levels with the plate closure's order 2
/// (exact for plane Poiseuille); none with fewer than two levels or equal finest two.
std::optional<double> extrapolateInDepthCells(const std::vector<int>& cells_z, const std::vector<double>& k);

}  // namespace mmval::simulate
