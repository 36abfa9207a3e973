// The fluid side of the coupled micromodel scene: a pore mask (image
// pixels, row 0 at the top, y up in metres as simulate::MaskShape has it), its
// depth-averaged Stokes flow from mmval's own solver (simulate::SteadyFlowSolver,
// Hele-Shaw friction -12 mu u / h^2 of the chip depth), scaled to a given Darcy
// velocity, and handed to the particle engines as a GriddedFlow on the pixels
// (walls at the pixel edges, velocities on the pixel faces). Four-way coupling: cells the deposits have filled are added to the
// solids, deposit layers on the plates thin the local aperture (the solver's
// per-cell depth: Reynolds lubrication, div(h^3 grad p) = 0 in the friction
// limit), and the flow is solved again (Stokes has no memory, so the new
// steady field is the answer). The engines see the thinned aperture as the
// local depth h(x, y), with z measured from the top of the layer.
// Permeability by Darcy's law at a fixed pressure drop,
//   k = mu q L / (W dp)   (q: flux through the outlet per unit chip depth, the
//                          undisturbed depth, so that k/k0 sees the thinned aperture),
// the definition of the image-permeability kind. Solids enter by the sharp immersed
// boundary (cut viscous stencils at the exact pixel edges, as the permeability kinds
// use; docs/validation/particle-physics.md, "Grid and seed convergence"): the
// penalized one's first-order wall error in narrow throats kept the scene's retention
// from converging with the grid. The method must not change between re-solves, or
// k/k0 would jump for numerical reasons. Pockets cut off from both inlet and outlet
// (connectivity as the sharp solve sees it) are closed before each solve; the solver
// pins the pressure of any component without a pressure boundary anyway. Closed pixels
// (deposits, pockets) are closed squares to the solver, edges included: their faces carry
// u = 0 and their cells are pinned, not merged (MicromodelFlow.cpp, PoreShape).
#pragma once
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mmval/particles/FlowField.hpp"

namespace mmval::simulate {
class SteadyFlowSolver;
struct FlowProblem;
class Shape;
class SmoothMaskShape;
}

namespace mmval::particles {

using PixelMask = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>;  ///< rows x cols, true = solid, row 0 = top

struct MicromodelFlowOptions {
  double pixel = 10e-6;             ///< m per pixel
  double depth = 20e-6;             ///< chip depth, m
  double viscosity = 1e-3;          ///< Pa s
  double darcy_velocity = 0.0;      ///< m/s, superficial velocity the flow is scaled to (>= 0)
  double cells_per_pixel = 0.5;     ///< fluid grid resolution
  /// Re-solves (numerics.resolve): true ("warm") keeps the fluid solver between solves. With
  /// fixed_pattern (below) every re-solve that fits the clean chip's pattern is a numeric
  /// factorisation. Without it: while the matrix keeps its pattern (aperture changes) a re-solve is
  /// a numeric factorisation with the kept ordering and symbolic analysis; closed pixels change the
  /// sharp solve's pattern, and then the re-solve orders and analyses the new matrix as a new
  /// solver does, the direct answer bit for bit. false ("direct") builds a new solver per solve.
  /// The first solve is the same either way. Grids of 40,000 cells and more whose Hele-Shaw
  /// friction dominates (cells at least ~0.41 of the depth) are not solved by the LU at all but by
  /// the friction split (block-preconditioned FGMRES, MicromodelFlow.cpp kSplitCells), from rest,
  /// with nothing kept between solves: these options and numerics.resolve / resolve_pattern then
  /// do not apply. Nor do they on grids whose LU would be too large to factorise
  /// (fluidSolverChoice below): the friction split solves those too.
  bool warm_start = true;
  /// Warm start: > 0 first runs GMRES from the last field, preconditioned by the kept LU factors
  /// of an earlier geometry, factorising only when it has not converged (1e-12 of the
  /// preconditioned right-hand side) within this many iterations. The answer then differs from
  /// the direct one by ~1e-11 and depends on which geometry was factorised last, which a
  /// checkpoint does not carry: a resumed run is then not bit for bit the uninterrupted one.
  /// 0 (the default): every re-solve factorises. On the full Pore2Chip scene a re-solve's change
  /// (0.5 % of the pore columns) left GMRES at a residual of ~1e-2 after 40 iterations (WarmResolveTest).
  int warm_max_iterations = 0;
  /// Warm start (numerics.resolve_pattern = "fixed"): the kept solver keeps the clean chip's matrix
  /// pattern (SolverOptions::fixed_pattern): a re-solve whose closed pixels and thinner apertures fit
  /// in it (closed faces: identity rows; closed cells: pinned; see PoreShape in MicromodelFlow.cpp)
  /// is a numeric factorisation with the clean chip's ordering and symbolic analysis; one that does
  /// not fit is solved by a new solver (FlowSolveResult::pattern_kept false). The answer equals the
  /// rebuilt solver's to rounding, not bit for bit. false ("rebuild"): as described above.
  bool fixed_pattern = true;
  /// The image's top and bottom edges (y = 0 and y = height) as the particles see them (case key
  /// geometry.sides; the fluid solve's top and bottom are slip either way). false ("walls"): the
  /// particles' field is padded by a solid row beyond each edge, a wall there. true ("slip"): the
  /// edges are mirror planes: the padding rows are the pore space mirrored across the edge (solid,
  /// depth and u_x copied, u_y reversed, zero on the plane), deep enough that every wall search of
  /// a point within the image sees the mirrored grains (a throat between a grain and the plane is
  /// twice its distance to it), and the field reports the image as its bounds (GriddedFlow::setDomain);
  /// the engines reflect particles at the planes (SceneConfig::mirror_sides).
  bool mirror_sides = false;
  /// Grain walls (case key geometry.boundary). false ("pixels"): the mask's staircase, for the
  /// fluid solve (simulate::MaskShape) and the particles (the grain pixels' edges). true
  /// ("smooth"): both see the grains as simulate::SmoothMaskShape of the mask with smoothing_px,
  /// the 1/2 level of the mask smoothed by a Gaussian (the image-permeability kind's
  /// geometry.boundary = "smooth"): the fluid solve cuts its cells against it, the particles' field
  /// takes its contour as the grain walls (GriddedFlow::setSmoothWalls). Closed pixels (deposits,
  /// pockets) and the side walls stay squares in both.
  bool smooth_walls = false;
  double smoothing_px = 0.75;  ///< smooth walls: Gaussian width, pixels (geometry.smoothing)
  /// The engines' pixel faces balanced (true, what every kind uses): the face means of the
  /// solve's velocities (solve()) balance each fluid pixel away from walls but not beside them,
  /// where the solve's cut cells carry flux through pixel edges into pixels the mask calls solid
  /// (2.8 % / 22 % of the largest speed at 1 / 0.5 cells per pixel beside a pixel disc, 7 % / 17 %
  /// with smooth walls; docs/validation/paper-scenes.md, "A continuous near-wall layer"). Balanced,
  /// the faces into solid pixels are zero and every fluid pixel's h-weighted net outflow is zero
  /// to ~1e-13 of (largest speed x pixel x depth), by the least depth-weighted change of the
  /// faces (a projection on the fluid pixels' graph, MicromodelFlow.cpp balanceFaceFluxes), the
  /// inlet faces kept: the pixels then carry the solve's flow rate and particles the solve's
  /// fluxes. false: the face means as they are (for comparisons; docs/validation/particle-physics.md,
  /// "Balanced face fluxes beside walls").
  bool balance_faces = true;
};

struct FlowSolveResult {
  double permeability = 0;     ///< m2 (depth-averaged model)
  double flux_scale = 0;       ///< velocity factor from the 1 Pa solve to the target Darcy velocity
  /// Pa: inlet-to-outlet pressure drop across the geometry that drives the target
  /// Darcy velocity, mu u L / k by Darcy's law (the solve's 1 Pa times flux_scale);
  /// +infinity when blocked with a positive target (no pressure can drive it), 0 at zero flow.
  double pressure_drop = 0;
  double seconds = 0;          ///< wall time of the solve
  bool blocked = false;        ///< no flow path left (k = 0)
  bool factorised = false;     ///< the solve factorised the system (LU) rather than reuse kept factors
  int iterations = 0;          ///< warm start with GMRES: its iterations (0: straight to the LU)
  /// Fixed pattern: a numeric factorisation into the kept pattern (no ordering nor symbolic
  /// analysis); false for the first solve and for a re-solve that took a new solver.
  bool pattern_kept = false;
  /// The pixel faces' balance (MicromodelFlowOptions::balance_faces): the largest net h-weighted
  /// outflow of a fluid pixel, faces to solid pixels counted as zero, over (largest face speed x
  /// pixel x largest depth), of the face means before and of the field handed to the engines
  /// after (equal when the balance is off); the solves with its factors it took (1 plus the
  /// refinement steps); the inflow it set to zero (dead ends at the pixels' resolution), a fraction of the inflow.
  double imbalance_before = 0;
  double imbalance_after = 0;
  int balance_iterations = 0;
  double balance_dropped_inflow = 0;
  double balance_seconds = 0;  ///< wall time of the balance (included in seconds)
};

/// The linear solver MicromodelFlow::solve takes for an nx x ny grid of cells dx x dy (m, the
/// smallest) on a chip `depth` deep, before any failure: the friction split where the grid is large
/// and the Hele-Shaw friction dominates (MicromodelFlow.cpp kSplitCells, kSplitFriction), else the
/// direct LU unless its estimated size is beyond what the LU factorises (kLuMaxUnknowns): then the
/// split too, with the larger iteration budget of the split after a failed LU.
struct FluidSolverChoice {
  bool split = false;         ///< the friction split (FGMRES), not the direct LU
  bool lu_too_large = false;  ///< split because the LU would be too large (friction alone would pick the LU)
  int max_iterations = 0;     ///< the split's FGMRES iterations (0 for the LU)
  long long unknowns = 0;     ///< the coupled system's unknowns, (nx + 1) ny + nx (ny + 1) + nx ny
  double lu_bytes = 0;        ///< estimated peak memory of the direct LU's solve, bytes
};
FluidSolverChoice fluidSolverChoice(long long nx, long long ny, double dx, double dy, double depth);

class MicromodelFlow {
 public:
  /// `grains`: solid pixels (isolated pores already closed). Throws std::invalid_argument on bad options.
  MicromodelFlow(PixelMask grains, MicromodelFlowOptions options);
  ~MicromodelFlow();
  MicromodelFlow(MicromodelFlow&&) noexcept;
  MicromodelFlow& operator=(MicromodelFlow&&) noexcept;

  /// Solves the flow with the grains plus `extra_solid` (same shape, may be empty
  /// for none) and the local aperture `aperture` (m per pixel, row-major from the
  /// top row, as DepositGrid::aperture(); empty: the chip depth everywhere; a fluid
  /// cell's depth is the mean over the open pixels it covers), fills field() and
  /// returns the permeability. Throws std::runtime_error when the solver fails,
  /// std::invalid_argument on wrong sizes.
  FlowSolveResult solve(const PixelMask& extra_solid, const std::vector<double>& aperture = {});

  /// The field the engines see: nodes at pixel centres, padded by one node on
  /// every side (solid rows beyond the two side walls; copies of the first and
  /// last columns beyond the inlet and the outlet, so that x = 0 and x = width are inside);
  /// with mirror sides padRows() mirrored rows beyond each side instead of the solid one.
  /// Its walls are the pixel edges of the grains and closed pixels (smooth_walls: the grains' are
  /// the contour of their SmoothMaskShape, GriddedFlow::setSmoothWalls) and its velocities live on
  /// the pixel faces (GridWalls::brinkman: exact wall distance; away from walls a
  /// divergence-free field that follows them, near them the Brinkman-Hele-Shaw layer matched
  /// to the solve beyond max(pixel, fluid cell)), whatever cells_per_pixel is; the fluid grid
  /// sets only the face velocities.
  std::shared_ptr<GriddedFlow> field() const { return m_field; }
  /// The field's arrays of the last solve (velocities on the pixel faces, solid and depth at
  /// the pixel centres; GriddedFlow::update's layout), for checkpoints, and restoring them exactly.
  const std::vector<double>& nodeUx() const { return m_ux; }
  const std::vector<double>& nodeUy() const { return m_uy; }
  const std::vector<std::uint8_t>& nodeSolid() const { return m_solid; }
  const std::vector<double>& nodeDepth() const { return m_h; }
  void restore(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<std::uint8_t>& solid,
               const std::vector<double>& depth);

  /// Rows of padding beyond each side of the image in field(): 1, or with mirror sides twice the
  /// field's wall-search reach at the chip depth plus 2 (a point within the image searches up to
  /// the reach beyond it, and the near-wall layer's probes from a mirrored wall point as far again).
  int padRows() const { return m_pad; }
  int rows() const { return static_cast<int>(m_grains.rows()); }
  int cols() const { return static_cast<int>(m_grains.cols()); }
  double width() const { return cols() * m_opt.pixel; }   ///< m, along x (flow)
  double height() const { return rows() * m_opt.pixel; }  ///< m, along y
  const MicromodelFlowOptions& options() const { return m_opt; }
  const PixelMask& grains() const { return m_grains; }

  /// Image pixel (column, row) of a point in metres; may be outside the image.
  void pixelOf(double x, double y, int& col, int& row) const;

  /// The fluid solve's linear solver so far, for result.json: "direct LU", "friction split", or
  /// the friction split with why ("friction split: the direct LU would be too large (...)",
  /// "friction split: the direct LU failed (...)"); empty before the first solve.
  const std::string& linearSolver() const { return m_linear_solver; }

 private:
  PixelMask m_grains;
  MicromodelFlowOptions m_opt;
  std::shared_ptr<GriddedFlow> m_field;
  int m_pad = 1;
  std::vector<double> m_ux, m_uy, m_h;
  std::vector<std::uint8_t> m_solid;
  std::shared_ptr<const simulate::SmoothMaskShape> m_smooth;  ///< smooth walls: the grains' reconstructed boundary
  std::unique_ptr<simulate::SteadyFlowSolver> m_solver;  ///< warm start: kept between solves
  bool m_lu_failed = false;  ///< the direct LU could not factorise: the friction split solves from then on
  std::string m_linear_solver;  ///< linearSolver()

  /// The flow problem of the grains plus `extra_solid` and `aperture` (solve's arguments) and the
  /// solid pixels it closes (pockets cut off included); false when no flow path is left.
  bool buildProblem(const PixelMask& extra_solid, const std::vector<double>& aperture, simulate::FlowProblem& prob, PixelMask& all) const;
};

/// Largest particle diameter (m) that can travel from the inlet column to the
/// outlet column of `solid` through the pore space: the bottleneck of the
/// Euclidean distance to the grains and side walls (the maximin path through
/// the medial axis), sampled at pixel centres: a throat n pixels wide reads n
/// pixels for odd n and n - 1 for even n. 0 when no pore path exists.
/// `mirror_sides`: the top and bottom edges are mirror planes, not walls (the distance is to the
/// grains and their mirror images, so a throat between a grain and a plane is twice its distance).
double passableDiameter(const PixelMask& solid, double pixel, bool mirror_sides = false);

/// Largest particle diameter (m) that fits somewhere in the inlet column (mirror_sides: as above).
double inletOpening(const PixelMask& solid, double pixel, bool mirror_sides = false);

/// Image row (counted from the bottom, 0 to rows - 1) whose mirror image row b is, for any
/// integer b, reflecting at y = 0 and y = rows (pixel units) as often as needed; `flipped` says
/// whether an odd number of reflections was made (a y-velocity changes sign).
int mirroredRow(int b, int rows, bool& flipped);

/// The shape the micromodel's fluid solve cuts against: `grains` read as the mask itself
/// (simulate::MaskShape), the pixels of `all` that are not grains (deposits, cut-off pockets) as
/// closed squares, solid on their edges too, so that closing a pixel turns rows of the solver's
/// matrix into identities within their old stencils (SolverOptions::fixed_pattern). `smooth`
/// (smooth walls): the grains are that shape instead (built from `grains`), the closed pixels squares as before.
std::shared_ptr<const simulate::Shape> poreShape(const PixelMask& grains, const PixelMask& all, double pixel,
                                                 std::shared_ptr<const simulate::SmoothMaskShape> smooth = nullptr);

}  // namespace mmval::particles
