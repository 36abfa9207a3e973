#include "mmval/particles/MicromodelFlow.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <queue>
#include <stdexcept>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <fmt/format.h>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"

namespace mmval::particles {

namespace {
constexpr double kPressureDrop = 1.0;  // Pa; Stokes is linear, the field is rescaled to the target flux
constexpr double kEdge = 1e-9;         // pixels: a cell edge this close to a pixel edge lies on it (rounding of the axis' faces)
/// Fluid grids from this many cells are solved by the friction split (SolverOptions::linear =
/// "iterative" on the depth-averaged problem: FGMRES, the Schur complement by the LU of
/// B diag(A)^-1 B^T, see CoupledSystem), from rest, to kSplitRtol, with the direct LU as the
/// fallback when it has not converged in kSplitMaxIterations (said on stderr). Pore2Chip at 1 cell
/// per pixel (250k cells, 750k unknowns; WarmResolve benchmark, loaded 2-core machine): 19-20
/// iterations, a re-solve 2.7 s CPU against 5.1 s for the numeric LU in the kept pattern, the first
/// solve 5.7 s wall against 46 s (BEST ordering), peak 1.1 GB against 2.2 GB; k within 2e-11 and the
/// velocities within 1-3e-8 of the largest of the direct answer (two direct LUs ordered
/// differently differ by 1.1e-8). Every solve depends only on its own geometry (no kept factors,
/// no warm start): a resumed run repeats the uninterrupted one. Smaller grids keep the direct LU
/// (under ~1 s there), with its kept-pattern re-solves (numerics.resolve, resolve_pattern).
constexpr long long kSplitCells = 40000;
/// ... and only where the Hele-Shaw friction 12 / h^2 is at least this fraction of the Laplacian's
/// diagonal 2 / dx^2 + 2 / dy^2 (cells at least 0.41 of the depth): there diag(A) stands in for the
/// velocity block. Measured: 0.75 (10 um cells, 20 um deep) 19-21 iterations; 0.105 (Table 3's 20 um
/// cells, 107 um deep) 39-53, and 14 of 101 solves not converged in 60 (the LU solved them).
constexpr double kSplitFriction = 0.5;
constexpr double kSplitRtol = 1e-12;
constexpr int kSplitMaxIterations = 60;  // 3x the measured 19-20
/// The friction split after the LU failed (grids finer than the split's own choice, where it needs
/// more iterations: see solve()).
constexpr int kSplitFallbackMaxIterations = 400;
/// Grids whose coupled system has more unknowns than this are not given to the LU even where the
/// friction criterion picks it: the friction split solves them from the start, with
/// kSplitFallbackMaxIterations, as it would once the LU had failed. UMFPACK's peak memory and wall
/// time (/usr/bin/time -v of a short `mmval run cases/particles-micromodel.toml`, the 200 x 150 px
/// window, whose first solve is the LU's, 2026-12-06): 0.15 / 0.31 / 0.63 / 1.08 / 2.42 / 3.82 GB
/// at 22.7k / 90k / 203k / 361k / 811k / 1.44M unknowns (0.5 / 1 / 1.5 / 2 / 3 / 4 cells per
/// pixel), the largest in 44 s; the full scene factorised at 1.4 cells per pixel (1.47M unknowns,
/// 3.9 GB) and failed in UMFPACK at 1.5 (1.69M unknowns) after ~40 s at 4.4 GB. The limit lies
/// between the largest LU that factorised and the smallest that failed. kLuStartupBytes plus
/// kLuBytesPerUnknown per unknown bounds every measured peak (1.5-2.84 kB per unknown above the
/// start-up): 4.5 GB at the limit. Should the split not converge there, SteadyFlowSolver tries the
/// LU after all; should an LU under the limit fail, solve() still hands the run to the split.
constexpr long long kLuMaxUnknowns = 1500000;
constexpr double kLuStartupBytes = 120e6;
constexpr double kLuBytesPerUnknown = 2.9e3;

/// Distance (m) from each pixel centre to the nearest grain or side wall, row-major
/// from the bottom row up (j * cols + i, j = 0 the image's last row). Mirror sides: to the
/// nearest grain or mirror image of one (the image mirrored once across each edge).
std::vector<double> pixelWallDistance(const PixelMask& solid, double pixel, bool mirror_sides) {
  const int rows = static_cast<int>(solid.rows()), cols = static_cast<int>(solid.cols());
  // One solid row beyond each side wall, or the image mirrored across each side; distances come
  // from GriddedFlow's transform.
  const int pad = mirror_sides ? rows : 1;
  GriddedFlow g(cols, rows + 2 * pad, 0.5 * pixel, (0.5 - pad) * pixel, pixel, pixel);
  const auto n = static_cast<std::size_t>(cols) * (rows + 2 * pad);
  std::vector<double> zero(n, 0.0), h(n, 1.0);
  std::vector<std::uint8_t> s(n, 1);
  for (int j = 0; j < rows + 2 * pad; ++j) {
    bool flipped = false;
    const int b = j - pad;
    if (!mirror_sides && (b < 0 || b >= rows)) continue;
    const int src = mirroredRow(b, rows, flipped);
    for (int i = 0; i < cols; ++i) s[static_cast<std::size_t>(j) * cols + i] = solid(rows - 1 - src, i) ? 1 : 0;
  }
  g.update(zero, zero, h, s);
  std::vector<double> d(static_cast<std::size_t>(rows) * cols);
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) d[static_cast<std::size_t>(j) * cols + i] = g.wallDistance((i + 0.5) * pixel, (j + 0.5) * pixel);
  return d;
}

/// Face y = f pixels (any integer) of a mirrored image `rows` high, reflected into [0, rows];
/// `flipped`: an odd number of reflections.
int mirroredFace(int f, int rows, bool& flipped) {
  const int period = 2 * rows;
  const int r = ((f % period) + period) % period;
  flipped = r > rows;
  return flipped ? period - r : r;
}

/// Net h-weighted outflow, per pixel width, of fluid image pixel (c, b) of the engines' face arrays
/// (MicromodelFlow's node layout: pixel (c, b), b from the bottom, is node (P + b) NX + c + 1, its
/// east face ux[k], its north face uy[k]; faces to solid pixels and the sides' faces count as
/// zero, the inlet faces (the padding column's ux) as they are, the outlet faces as they are).
/// A face's depth is the mean of its two pixels' (what GriddedFlow::depth reads at the face's
/// midpoint), an outlet or inlet face its pixel's.
double pixelOutflow(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<std::uint8_t>& solid,
                    const std::vector<double>& h, int nc, int nr, int P, int c, int b) {
  const int NX = nc + 2;
  const std::size_t k = static_cast<std::size_t>(P + b) * NX + c + 1;
  const auto face = [&](std::size_t other, double u) { return solid[other] ? 0.0 : 0.5 * (h[k] + h[other]) * u; };
  double out = (c == nc - 1 ? h[k] * ux[k] : face(k + 1, ux[k])) - (c == 0 ? h[k] * ux[k - 1] : face(k - 1, ux[k - 1]));
  out += (b < nr - 1 ? face(k + NX, uy[k]) : 0.0) - (b > 0 ? face(k - NX, uy[k - NX]) : 0.0);
  return out;
}

/// The largest |pixelOutflow| of the fluid image pixels.
double largestImbalance(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<std::uint8_t>& solid,
                        const std::vector<double>& h, int nc, int nr, int P) {
  const int NX = nc + 2;
  double worst = 0;
  for (int b = 0; b < nr; ++b)
    for (int c = 0; c < nc; ++c)
      if (!solid[static_cast<std::size_t>(P + b) * NX + c + 1]) worst = std::max(worst, std::abs(pixelOutflow(ux, uy, solid, h, nc, nr, P, c, b)));
  return worst;
}

/// The largest face speed (the inlet faces included) times the largest depth, of the fluid image pixels.
double imbalanceScale(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<std::uint8_t>& solid,
                      const std::vector<double>& h, int nc, int nr, int P) {
  const int NX = nc + 2;
  double u_max = 0, h_max = 0;
  for (int b = 0; b < nr; ++b)
    for (int c = 0; c < nc; ++c) {
      const std::size_t k = static_cast<std::size_t>(P + b) * NX + c + 1;
      if (solid[k]) continue;
      u_max = std::max({u_max, std::abs(ux[k]), std::abs(uy[k]), c == 0 ? std::abs(ux[k - 1]) : 0.0});
      h_max = std::max(h_max, h[k]);
    }
  return u_max * h_max;
}

/// largestImbalance over imbalanceScale (0 for a field at rest).
double faceImbalance(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<std::uint8_t>& solid,
                     const std::vector<double>& h, int nc, int nr, int P) {
  const double scale = imbalanceScale(ux, uy, solid, h, nc, nr, P);
  return scale > 0 ? largestImbalance(ux, uy, solid, h, nc, nr, P) / scale : 0.0;
}

/// The engines' pixel-face field made discretely divergence-free on the fluid pixels (see
/// MicromodelFlowOptions::balance_faces): faces between a fluid and a solid pixel, and the
/// image's top and bottom faces, are set to zero; then the least change of the face velocities,
/// weighted by their faces' depths, that balances every fluid pixel's h-weighted flux: u_f +=
/// phi_a - phi_b across the face from pixel a to pixel b, with L phi = -div, L the pixels' graph
/// Laplacian of face conductance h_f (square pixels: face length over centre distance is 1).
/// Inlet faces keep their values (the prescribed inflow); the outlet faces take phi = 0 beyond
/// them (a pixel beyond the outlet at the outlet's pressure). A component of fluid pixels with
/// no outlet face (a dead end at the pixels' resolution, where the solve's cells joined it to
/// the rest across a corner) has its phi pinned at one pixel and its inlet faces, if any, set to
/// zero: its inflow has nowhere to go. L is factorised (sparse LDL^T, AMD ordering; the strip's
/// 848k fluid pixels: 8.1M entries in L, 1.3 s; conjugate gradients with an incomplete Cholesky
/// preconditioner had not reached the target after 2.5 CPU minutes there, its slow modes spanning the strip's length)
/// and the solve repeated on the remaining imbalance (iterative refinement) until the largest is
/// below kBalanceTarget of (the largest face speed x the largest depth). Only the solve's own fill
/// enters, nothing kept from an earlier solve, so a resumed run's re-solves repeat the
/// uninterrupted one's. Works on the image's nodes only; the padding columns are copied from the
/// edge columns afterwards.
struct BalanceStats {
  double before = 0, after = 0;  ///< largest per-pixel imbalance, of (largest speed x largest depth)
  double dropped_inflow = 0;     ///< inflow of dead-end components set to zero, of the total
  int iterations = 0;            ///< solves with the factors (1 + refinement steps)
};
constexpr double kBalanceTarget = 1e-13;
constexpr int kBalanceRounds = 4;

BalanceStats balanceFaceFluxes(std::vector<double>& ux, std::vector<double>& uy, const std::vector<std::uint8_t>& solid,
                               const std::vector<double>& h, int nc, int nr, int P) {
  BalanceStats st;
  const int NX = nc + 2;
  const auto node = [&](int c, int b) { return static_cast<std::size_t>(P + b) * NX + c + 1; };
  const double scale = imbalanceScale(ux, uy, solid, h, nc, nr, P);
  if (!(scale > 0)) return st;
  double inflow = 0;
  for (int b = 0; b < nr; ++b)
    if (!solid[node(0, b)]) inflow += h[node(0, b)] * ux[node(0, b) - 1];
  st.before = largestImbalance(ux, uy, solid, h, nc, nr, P) / scale;
  // No flux into solid pixels, nor through the image's top and bottom (walls or mirror planes).
  for (int b = 0; b < nr; ++b)
    for (int c = 0; c < nc; ++c) {
      const std::size_t k = node(c, b);
      if (c < nc - 1 && (solid[k] || solid[k + 1])) ux[k] = 0.0;
      if (b == nr - 1 || solid[k] || solid[k + NX]) uy[k] = 0.0;
      if (b == 0) uy[k - NX] = 0.0;
    }
  // Components of fluid pixels (4-neighbours), and whether each reaches the outlet.
  const int n_pix = nc * nr;
  std::vector<int> comp(static_cast<std::size_t>(n_pix), -1), index(static_cast<std::size_t>(n_pix), -1);
  std::vector<std::uint8_t> grounded;
  std::vector<int> first_pixel, stack;
  for (int start = 0; start < n_pix; ++start) {
    if (comp[start] >= 0 || solid[node(start % nc, start / nc)]) continue;
    const int id = static_cast<int>(grounded.size());
    grounded.push_back(0);
    first_pixel.push_back(start);
    comp[start] = id;
    stack.assign(1, start);
    while (!stack.empty()) {
      const int q = stack.back();
      stack.pop_back();
      const int c = q % nc, b = q / nc;
      if (c == nc - 1) grounded[id] = 1;
      const int nbr[4][2] = {{c + 1, b}, {c - 1, b}, {c, b + 1}, {c, b - 1}};
      for (const auto& m : nbr) {
        if (m[0] < 0 || m[0] >= nc || m[1] < 0 || m[1] >= nr) continue;
        const int qq = m[1] * nc + m[0];
        if (comp[qq] >= 0 || solid[node(m[0], m[1])]) continue;
        comp[qq] = id;
        stack.push_back(qq);
      }
    }
  }
  int n = 0;
  double dropped = 0;
  for (int q = 0; q < n_pix; ++q) {
    if (comp[q] < 0) continue;
    const int c = q % nc, b = q / nc;
    if (!grounded[comp[q]] && c == 0) {
      dropped += h[node(c, b)] * ux[node(c, b) - 1];
      ux[node(c, b) - 1] = 0.0;
    }
    if (!grounded[comp[q]] && first_pixel[comp[q]] == q) continue;  // phi = 0 there
    index[q] = n++;
  }
  st.dropped_inflow = inflow != 0 ? std::abs(dropped / inflow) : 0.0;
  if (n == 0) return st;
  const auto hFace = [&](std::size_t a, std::size_t b) { return 0.5 * (h[a] + h[b]); };
  std::vector<Eigen::Triplet<double>> trip;
  trip.reserve(static_cast<std::size_t>(5) * n);
  for (int q = 0; q < n_pix; ++q) {
    if (comp[q] < 0) continue;
    const int c = q % nc, b = q / nc;
    const std::size_t k = node(c, b);
    double diag = c == nc - 1 ? h[k] : 0.0;  // the outlet face, phi = 0 beyond it
    const auto link = [&](int qq, std::size_t kk) {
      const double g = hFace(k, kk);
      diag += g;
      if (index[q] >= 0 && index[qq] >= 0) trip.emplace_back(index[q], index[qq], -g);
    };
    if (c + 1 < nc && !solid[k + 1]) link(q + 1, k + 1);
    if (c > 0 && !solid[k - 1]) link(q - 1, k - 1);
    if (b + 1 < nr && !solid[k + NX]) link(q + nc, k + NX);
    if (b > 0 && !solid[k - NX]) link(q - nc, k - NX);
    if (index[q] >= 0) trip.emplace_back(index[q], index[q], diag);
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(trip.begin(), trip.end());
  trip = {};
  const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>, Eigen::Lower, Eigen::AMDOrdering<int>> ldlt(A);
  if (ldlt.info() != Eigen::Success) throw std::runtime_error("MicromodelFlow: the face balance's factorisation failed");
  Eigen::VectorXd rhs(n), phi(n);
  // Net h-weighted outflow of unknown pixel q (faces already closed above).
  const auto divergence = [&]() {
    double worst = 0;
    for (int q = 0; q < n_pix; ++q) {
      if (comp[q] < 0) continue;
      const double out = pixelOutflow(ux, uy, solid, h, nc, nr, P, q % nc, q / nc);
      worst = std::max(worst, std::abs(out));
      if (index[q] >= 0) rhs[index[q]] = -out;
    }
    return worst;
  };
  for (int round = 0; round < kBalanceRounds; ++round) {
    if (divergence() <= kBalanceTarget * scale) break;
    phi = ldlt.solve(rhs);
    ++st.iterations;
    const auto at = [&](int q) { return index[q] >= 0 ? phi[index[q]] : 0.0; };
    for (int q = 0; q < n_pix; ++q) {
      if (comp[q] < 0) continue;
      const int c = q % nc, b = q / nc;
      const std::size_t k = node(c, b);
      if (c == nc - 1) ux[k] += at(q);
      else if (!solid[k + 1]) ux[k] += at(q) - at(q + 1);
      if (b + 1 < nr && !solid[k + NX]) uy[k] += at(q) - at(q + nc);
    }
  }
  // The padding columns repeat the edge columns' faces (the inlet's own faces stay as they are).
  for (int b = 0; b < nr; ++b) {
    const std::size_t k0 = node(-1, b), k1 = node(nc, b);
    uy[k0] = uy[k0 + 1];
    ux[k1] = ux[k1 - 1];
    uy[k1] = uy[k1 - 1];
  }
  st.after = largestImbalance(ux, uy, solid, h, nc, nr, P) / scale;
  return st;
}

/// The shape the fluid solver cuts against. The grains are the mask itself (simulate::MaskShape:
/// a node on a pixel edge reads one of the two pixels, and the outlet face nodes on the image's
/// edge x = width read the edge pixel, so a grain touching the outlet closes its outlet faces).
/// Pixels closed since (deposits, pockets cut off) are closed squares: a node on any of their
/// edges is solid (u = 0 on a wall through the node). So the cells of a closed pixel have no fluid
/// face at 1 cell per pixel and finer: they are pinned (p = 0, no flow), never merged into a
/// neighbour, and closing a pixel only turns rows of the solver's matrix into identities within
/// their old stencils (what SolverOptions::fixed_pattern keeps). Read as a MaskShape, a node on
/// the far edge of a closed pixel stayed fluid at ~1 % of its neighbour's velocity (its wall
/// distance clamped to 1 % of a cell) and the pixel's cell merged into the neighbour beyond it.
/// Distances to the surface are the mask's of grains and closed pixels together.
/// Smooth walls: the grains are the SmoothMaskShape, the distance along a line the nearer of its
/// crossing and the first closed pixel's edge.
class PoreShape final : public simulate::Shape {
 public:
  PoreShape(const PixelMask& grains, const PixelMask& all, double pixel, std::shared_ptr<const simulate::SmoothMaskShape> smooth)
      : m_grains(grains, pixel), m_all(all, pixel), m_closed(all && !grains), m_any(m_closed.any()), m_pixel(pixel),
        m_smooth(std::move(smooth)) {
    if (m_smooth && m_any) m_closed_shape = std::make_unique<simulate::MaskShape>(m_closed, pixel);
  }
  int bodyAt(double x, double y) const override {
    if (m_smooth ? m_smooth->bodyAt(x, y) >= 0 : m_grains.bodyAt(x, y) >= 0) return 0;
    if (!m_any) return -1;
    const double u = x / m_pixel, v = (m_all.height() - y) / m_pixel;  // pixel column and row coordinates (row 0 at the top)
    const int c0 = static_cast<int>(std::floor(u - kEdge)), c1 = static_cast<int>(std::floor(u + kEdge));
    const int r0 = static_cast<int>(std::floor(v - kEdge)), r1 = static_cast<int>(std::floor(v + kEdge));
    for (int r = std::max(r0, 0); r <= std::min(r1, static_cast<int>(m_closed.rows()) - 1); ++r)
      for (int c = std::max(c0, 0); c <= std::min(c1, static_cast<int>(m_closed.cols()) - 1); ++c)
        if (m_closed(r, c)) return 0;
    return -1;
  }
  double distanceAlong(double x, double y, int axis, int sign, double max_distance) const override {
    if (!m_smooth) return m_all.distanceAlong(x, y, axis, sign, max_distance);
    const double d = m_smooth->distanceAlong(x, y, axis, sign, max_distance);
    return m_closed_shape ? m_closed_shape->distanceAlong(x, y, axis, sign, d) : d;
  }
  int bodies() const override { return 1; }
  Eigen::Vector2d centre(int body) const override { return m_all.centre(body); }

 private:
  simulate::MaskShape m_grains, m_all;
  PixelMask m_closed;
  bool m_any;
  double m_pixel;
  std::shared_ptr<const simulate::SmoothMaskShape> m_smooth;
  std::unique_ptr<simulate::MaskShape> m_closed_shape;  ///< smooth walls: the closed pixels alone
};

std::shared_ptr<const PoreShape> solverShape(const PixelMask& grains, const PixelMask& all, double pixel,
                                             std::shared_ptr<const simulate::SmoothMaskShape> smooth) {
  return std::make_shared<const PoreShape>(grains, all, pixel, std::move(smooth));
}
}  // namespace

std::shared_ptr<const simulate::Shape> poreShape(const PixelMask& grains, const PixelMask& all, double pixel,
                                                 std::shared_ptr<const simulate::SmoothMaskShape> smooth) {
  return solverShape(grains, all, pixel, std::move(smooth));
}

FluidSolverChoice fluidSolverChoice(long long nx, long long ny, double dx, double dy, double depth) {
  FluidSolverChoice c;
  c.unknowns = (nx + 1) * ny + nx * (ny + 1) + nx * ny;
  c.lu_bytes = kLuStartupBytes + kLuBytesPerUnknown * static_cast<double>(c.unknowns);
  const double friction = 12 / (depth * depth);
  if (nx * ny >= kSplitCells && friction >= kSplitFriction * (2 / (dx * dx) + 2 / (dy * dy))) {
    c.split = true;
    c.max_iterations = kSplitMaxIterations;
  } else if (c.unknowns > kLuMaxUnknowns) {
    c.split = c.lu_too_large = true;
    c.max_iterations = kSplitFallbackMaxIterations;
  }
  return c;
}

MicromodelFlow::MicromodelFlow(PixelMask grains, MicromodelFlowOptions options) : m_grains(std::move(grains)), m_opt(options) {
  if (m_grains.rows() < 2 || m_grains.cols() < 2) throw std::invalid_argument("MicromodelFlow: the mask needs at least 2 x 2 pixels");
  if (!(m_opt.pixel > 0) || !(m_opt.depth > 0) || !(m_opt.viscosity > 0) || !(m_opt.darcy_velocity >= 0) || !(m_opt.cells_per_pixel > 0) ||
      m_opt.warm_max_iterations < 0)
    throw std::invalid_argument("MicromodelFlow: pixel, depth, viscosity, cells_per_pixel must be > 0, the Darcy velocity and the warm-start iterations >= 0");
  // Particles see the walls the fluid solver cuts against: the pixel mask's own edges (it takes
  // the mask as a simulate::MaskShape), or with smooth walls the contour of the SmoothMaskShape it
  // takes then (set below; closed pixels stay squares in both): exact distances, whatever the
  // fluid grid's resolution, on nodes at the pixel centres. Near walls they feel the
  // Brinkman-Hele-Shaw layer (GridWalls::brinkman) matched to the solved velocity beyond both
  // the fluid cell and the pixel next to the wall, the first distance the solve resolves.
  const double resolved = std::max(m_opt.pixel, m_opt.pixel / m_opt.cells_per_pixel);
  if (m_opt.mirror_sides) {
    // GriddedFlow's wall-search reach at the chip depth (deposit layers only thin it): a point
    // within the image searches that far beyond the plane, and the near-wall layer's probes along
    // the normal from a mirrored wall point that far again.
    const double match = std::max(m_opt.depth / std::sqrt(12.0), resolved) + 0.5 * m_opt.pixel;
    const int reach = std::max(GriddedFlow::kExactCells, static_cast<int>(std::ceil(match / m_opt.pixel)));
    m_pad = 2 * reach + 2;
  }
  m_field = std::make_shared<GriddedFlow>(cols() + 2, rows() + 2 * m_pad, -0.5 * m_opt.pixel, (0.5 - m_pad) * m_opt.pixel, m_opt.pixel,
                                          m_opt.pixel, GridWalls::brinkman, resolved);
  if (m_opt.mirror_sides) m_field->setDomain({-0.5 * m_opt.pixel, width() + 0.5 * m_opt.pixel, 0.0, height()});
  if (m_opt.smooth_walls) {
    m_smooth = std::make_shared<const simulate::SmoothMaskShape>(m_grains, m_opt.pixel, m_opt.smoothing_px);
    // The particles' grain walls: the same level, in the field's coordinates (the image's, y up).
    // Beyond the inlet and the outlet the padding columns repeat the edge pixels, and the level
    // its value on the edge; with mirror sides the rows beyond y = 0 and y = H are the image
    // mirrored, and so is the level; without, they are wall squares and the level there is fluid.
    const int nr = rows(), nc = cols(), P = m_pad, NX = nc + 2, NY = nr + 2 * P;
    const double W = width(), H = height();
    simulate::SmoothMaskShape const* shape = m_smooth.get();
    const bool mirror = m_opt.mirror_sides;
    SmoothGrainWalls walls;
    walls.level = [shape, W, H, mirror, keep = m_smooth](double x, double y) {
      x = std::clamp(x, 0.0, W);
      if (mirror) {
        const double r = std::fmod(std::fmod(y, 2 * H) + 2 * H, 2 * H);
        y = r > H ? 2 * H - r : r;
      } else if (y < 0 || y > H) {
        return -0.5;
      }
      return shape->level(x, y);
    };
    walls.grain.assign(static_cast<std::size_t>(NX) * NY, 0);
    for (int j = 0; j < NY; ++j) {
      bool flipped = false;
      const int b = j - P;
      if (!mirror && (b < 0 || b >= nr)) continue;
      const int src = mirroredRow(b, nr, flipped);
      for (int i = 0; i < NX; ++i) walls.grain[static_cast<std::size_t>(j) * NX + i] = m_grains(nr - 1 - src, std::clamp(i - 1, 0, nc - 1)) ? 1 : 0;
    }
    m_field->setSmoothWalls(std::move(walls));
  }
}

int mirroredRow(int b, int rows, bool& flipped) {
  // Pixel centres in half pixels, 2 b + 1, reflected at 0 and 2 rows with period 4 rows.
  const int period = 4 * rows;
  const int r = (((2 * b + 1) % period) + period) % period;
  flipped = r > 2 * rows;
  return ((flipped ? period - r : r) - 1) / 2;
}

MicromodelFlow::~MicromodelFlow() = default;
MicromodelFlow::MicromodelFlow(MicromodelFlow&&) noexcept = default;
MicromodelFlow& MicromodelFlow::operator=(MicromodelFlow&&) noexcept = default;

void MicromodelFlow::pixelOf(double x, double y, int& col, int& row) const {
  col = static_cast<int>(std::floor(x / m_opt.pixel));
  row = rows() - 1 - static_cast<int>(std::floor(y / m_opt.pixel));
}

bool MicromodelFlow::buildProblem(const PixelMask& extra_solid, const std::vector<double>& aperture, simulate::FlowProblem& prob, PixelMask& all) const {
  all = m_grains;
  if (extra_solid.size() > 0) {
    if (extra_solid.rows() != all.rows() || extra_solid.cols() != all.cols()) throw std::invalid_argument("MicromodelFlow::solve: extra solid has the wrong shape");
    all = all || extra_solid;
  }
  const int nr = rows(), nc = cols();
  const double W = width(), H = height(), p = m_opt.pixel;
  const int nx = std::max(4, static_cast<int>(std::lround(nc * m_opt.cells_per_pixel)));
  const int ny = std::max(4, static_cast<int>(std::lround(nr * m_opt.cells_per_pixel)));
  prob = simulate::FlowProblem();
  prob.x = simulate::uniformAxis(0, W, nx);
  prob.y = simulate::uniformAxis(0, H, ny);
  prob.boundary[0].type = prob.boundary[1].type = simulate::BoundaryType::pressure;
  prob.boundary[0].pressure = kPressureDrop;
  prob.boundary[1].pressure = 0.0;
  prob.boundary[2].type = prob.boundary[3].type = simulate::BoundaryType::slip;
  prob.viscosity = m_opt.viscosity;
  prob.depth = m_opt.depth;
  // Deposits (or a coarse grid) can wall off pockets of pore space. A cell is pore when its
  // centre is, and two pore cells (or a pore cell and the inlet/outlet) communicate when the
  // velocity node of their shared face is fluid too, with the solver's own node positions
  // (Axis::face, Axis::centre: at 0.5 cells per pixel the nodes lie on pixel corners, where
  // i * W / nx and the axis' face can round to different pixels). No path from inlet to outlet:
  // blocked, no solve. Pore cells reachable from neither are closed (the pixels under them).
  // A cell whose centre is in a grain does not carry the path here, though the sharp solve
  // merges it into a neighbour when a face is fluid: at 0.5 cells per pixel a wall of closed
  // pixels one pixel thick at an odd column passes between the face nodes and only the cell
  // centres see it, and it must still stop the pump. Components of such cells that reach
  // neither side get their pressure pinned by the solver (FlowOperator) and carry no flow.
  for (int pass = 0; pass < 8; ++pass) {  // closing pixels can cut off more cells: repeat until none is
    const auto shape = solverShape(m_grains, all, p, m_smooth);
    const simulate::Shape& probe = *shape;
    std::vector<std::uint8_t> fluid(static_cast<std::size_t>(nx) * ny), reach(fluid.size(), 0);
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) fluid[static_cast<std::size_t>(j) * nx + i] = !probe.solid(prob.x.centre(i), prob.y.centre(j));
    const auto openX = [&](int i, int j) { return !probe.solid(prob.x.face(i), prob.y.centre(j)); };  // x-face i of row j
    const auto openY = [&](int i, int j) { return !probe.solid(prob.x.centre(i), prob.y.face(j)); };  // y-face j of column i
    const auto flood = [&](int column, std::uint8_t bit) {
      std::vector<int> stack;
      for (int j = 0; j < ny; ++j) {
        const int k = j * nx + column;
        if (fluid[k] && openX(column == 0 ? 0 : nx, j) && !(reach[k] & bit)) {
          reach[k] |= bit;
          stack.push_back(k);
        }
      }
      while (!stack.empty()) {
        const int k = stack.back();
        stack.pop_back();
        const int i = k % nx, j = k / nx;
        const auto go = [&](int ii, int jj, bool open) {
          if (ii < 0 || ii >= nx || jj < 0 || jj >= ny || !open) return;
          const int kk = jj * nx + ii;
          if (!fluid[kk] || (reach[kk] & bit)) return;
          reach[kk] |= bit;
          stack.push_back(kk);
        };
        go(i + 1, j, i + 1 < nx && openX(i + 1, j));
        go(i - 1, j, i > 0 && openX(i, j));
        go(i, j + 1, j + 1 < ny && openY(i, j + 1));
        go(i, j - 1, j > 0 && openY(i, j));
      }
    };
    flood(0, 1);
    flood(nx - 1, 2);
    bool spanning = false;
    for (int j = 0; j < ny && !spanning; ++j) spanning = reach[static_cast<std::size_t>(j) * nx + nx - 1] == 3;
    if (!spanning) return false;
    bool isolated = false;
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        const auto k = static_cast<std::size_t>(j) * nx + i;
        if (!fluid[k] || reach[k]) continue;
        isolated = true;
        // The pixels under cell (i, j) (b counts pixel rows from the bottom): those it overlaps by
        // more than kEdge of a pixel, so that a cell edge on a pixel edge closes no pixel beyond it.
        const auto first = [&](double lo) { return static_cast<int>(std::floor(lo / p + kEdge)); };
        const auto last = [&](double hi) { return static_cast<int>(std::ceil(hi / p - kEdge)) - 1; };
        const int c0 = std::max(0, first(prob.x.face(i))), c1 = std::min(nc - 1, last(prob.x.face(i + 1)));
        const int b0 = std::max(0, first(prob.y.face(j))), b1 = std::min(nr - 1, last(prob.y.face(j + 1)));
        for (int b = b0; b <= b1; ++b)
          for (int cc = c0; cc <= c1; ++cc) all(nr - 1 - b, cc) = true;
      }
    if (!isolated) break;
  }
  const double cw = W / nx, ch = H / ny;
  prob.shape = solverShape(m_grains, all, p, m_smooth);
  prob.method = simulate::ImmersedMethod::sharp;
  if (!aperture.empty()) {
    // Cell depth: mean aperture of the open pixels whose centres lie in the cell
    // (the pixel under the cell centre when the cell is smaller than a pixel);
    // cells without an open pixel keep the chip depth (they are solid anyway).
    prob.depth_field = Eigen::ArrayXXd::Constant(ny, nx, m_opt.depth);
    for (int j = 0; j < ny; ++j)
      for (int i = 0; i < nx; ++i) {
        int ca = static_cast<int>(std::ceil(i * cw / p - 0.5)), cb = static_cast<int>(std::ceil((i + 1) * cw / p - 0.5)) - 1;
        int ba = static_cast<int>(std::ceil(j * ch / p - 0.5)), bb = static_cast<int>(std::ceil((j + 1) * ch / p - 0.5)) - 1;
        if (cb < ca) ca = cb = static_cast<int>(std::floor((i + 0.5) * cw / p));
        if (bb < ba) ba = bb = static_cast<int>(std::floor((j + 0.5) * ch / p));
        double sum = 0;
        int n_open = 0;
        for (int b = std::max(ba, 0); b <= std::min(bb, nr - 1); ++b)
          for (int cc = std::max(ca, 0); cc <= std::min(cb, nc - 1); ++cc) {
            const int row = nr - 1 - b;
            if (all(row, cc)) continue;
            sum += aperture[static_cast<std::size_t>(row) * nc + cc];
            ++n_open;
          }
        if (n_open > 0 && sum > 0) prob.depth_field(j, i) = sum / n_open;
      }
  }
  return true;
}

FlowSolveResult MicromodelFlow::solve(const PixelMask& extra_solid, const std::vector<double>& aperture) {
  const auto t0 = std::chrono::steady_clock::now();
  if (!aperture.empty() && aperture.size() != static_cast<std::size_t>(m_grains.size()))
    throw std::invalid_argument("MicromodelFlow::solve: the aperture needs one value per pixel");
  simulate::FlowProblem prob;
  PixelMask all;
  if (!buildProblem(extra_solid, aperture, prob, all)) {
    FlowSolveResult blocked;
    blocked.blocked = true;
    blocked.pressure_drop = m_opt.darcy_velocity > 0 ? std::numeric_limits<double>::infinity() : 0.0;
    m_ux.assign(m_ux.size(), 0.0);
    m_uy.assign(m_uy.size(), 0.0);
    if (!m_ux.empty()) m_field->update(m_ux, m_uy, m_h, m_solid);
    blocked.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return blocked;
  }
  const int nr = rows(), nc = cols(), nx = prob.x.cells(), ny = prob.y.cells();
  const double W = width(), H = height(), p = m_opt.pixel, cw = W / nx, ch = H / ny;
  const FluidSolverChoice choice = fluidSolverChoice(nx, ny, prob.x.minWidth(), prob.y.minWidth(), m_opt.depth);
  if (m_linear_solver.empty() && choice.lu_too_large)  // once per run: the grid does not change
    std::fprintf(stderr,
                 "mmval: fluid solve: the direct LU on %d x %d cells (%lld unknowns, over %lld; estimated peak %.1f GB) would be too large; "
                 "every solve uses the friction split (block-preconditioned FGMRES, up to %d iterations)\n",
                 nx, ny, choice.unknowns, kLuMaxUnknowns, choice.lu_bytes / 1e9, choice.max_iterations);
  if (!m_lu_failed)
    m_linear_solver = !choice.split         ? std::string("direct LU")
                      : choice.lu_too_large ? fmt::format("friction split: the direct LU would be too large ({} unknowns, over {}; estimated peak {:.1f} GB)",
                                                          choice.unknowns, kLuMaxUnknowns, choice.lu_bytes / 1e9)
                                            : std::string("friction split");
  // Warm start: the kept solver takes the changed geometry (same grid); direct: a fresh solver
  // per solve, dropped after it (as its LU factors).
  std::unique_ptr<simulate::SteadyFlowSolver> fresh;
  simulate::SteadyFlowSolver* solver = nullptr;
  const auto splitOptions = [](int max_iterations) {
    simulate::SolverOptions so;
    so.linear = "iterative";
    so.linear_rtol = kSplitRtol;
    so.linear_max_iterations = max_iterations;
    so.keep_factorisation = so.fixed_pattern = false;  // nothing is kept between split solves
    so.warm_max_iterations = 0;
    return so;
  };
  const auto prepare = [&](simulate::FlowProblem&& problem) {
    if (m_opt.warm_start && m_solver) {
      m_solver->update(std::move(problem));
      solver = m_solver.get();
      return;
    }
    simulate::SolverOptions so;
    so.keep_factorisation = m_opt.warm_start;
    so.warm_max_iterations = m_opt.warm_start ? m_opt.warm_max_iterations : 0;
    so.fixed_pattern = m_opt.warm_start && m_opt.fixed_pattern;
    if (m_lu_failed)
      so = splitOptions(kSplitFallbackMaxIterations);
    else if (choice.split)
      so = splitOptions(choice.max_iterations);
    simulate::FlowProblem clean;
    PixelMask clean_all;
    const bool is_clean = !(extra_solid.size() > 0 && extra_solid.any()) &&
                          std::all_of(aperture.begin(), aperture.end(), [&](double h) { return h == m_opt.depth; });
    auto& owner = m_opt.warm_start ? m_solver : fresh;
    if (so.fixed_pattern && !is_clean && buildProblem({}, {}, clean, clean_all)) {
      // The kept pattern and its ordering are the clean chip's, whatever geometry comes first (a
      // resumed run starts with deposits): a re-solve then depends only on the clean chip and the
      // current geometry, so a resumed run is the uninterrupted one. Costs one factorisation more.
      owner = std::make_unique<simulate::SteadyFlowSolver>(std::move(clean), so);
      owner->solve();
      owner->update(std::move(problem));
    } else {
      owner = std::make_unique<simulate::SteadyFlowSolver>(std::move(problem), so);
    }
    solver = owner.get();
  };
  const simulate::FlowStats* stats = nullptr;
  try {
    prepare(std::move(prob));
    stats = &solver->solve();
  } catch (const simulate::LinearSolverFailure& e) {
    // This kind chooses its linear solver itself (the friction split where cells are coarse
    // against the depth, else the direct LU with its kept re-solves). An LU its library cannot
    // factorise (UMFPACK at 1.69M unknowns: Pore2Chip at 1.5 cells per pixel, 2026-12-06) hands
    // this solve and every later one of the run to the friction split, with more iterations
    // allowed (its diag(A) stands in less well for the velocity block on cells finer than ~0.41
    // of the depth); a resumed run takes the same path, so it repeats the uninterrupted one.
    if (!e.direct() || m_lu_failed || choice.lu_too_large)  // the last: the split already had the fallback's iterations
      throw NumericalFailure(e.cause(), "numerics.cells_per_pixel",
                             fmt::format("fewer cells per pixel (this grid has {} x {} cells; the kind picks its linear solver itself)", nx, ny));
    m_lu_failed = true;
    m_linear_solver = fmt::format("friction split: the direct LU failed ({})", e.cause());
    std::fprintf(stderr,
                 "mmval: fluid solve: the direct LU failed on %d x %d cells (%s); this solve and the later ones use the friction split "
                 "(block-preconditioned FGMRES, up to %d iterations)\n",
                 nx, ny, e.cause().c_str(), kSplitFallbackMaxIterations);
    m_solver.reset();
    fresh.reset();
    simulate::FlowProblem again;
    PixelMask again_all;
    buildProblem(extra_solid, aperture, again, again_all);
    try {
      prepare(std::move(again));
      stats = &solver->solve();
    } catch (const simulate::FlowFailure& e2) {
      throw NumericalFailure(e.cause() + "; then the friction split: " + e2.cause(), "numerics.cells_per_pixel",
                             fmt::format("fewer cells per pixel (this grid has {} x {} cells; neither the LU nor the friction split solved it)", nx, ny));
    }
  }
  FlowSolveResult r;
  r.pattern_kept = stats->pattern_kept;
  r.factorised = stats->factorisations > 0;
  r.iterations = stats->linear_iterations - stats->factorisations;  // a factorising solve counts its LU solve as one
  const double q = solver->flowRate(simulate::Side::east);
  r.blocked = !(q > 0) || !std::isfinite(q);
  r.permeability = r.blocked ? 0.0 : m_opt.viscosity * q * W / (H * kPressureDrop);
  r.flux_scale = r.blocked ? 0.0 : m_opt.darcy_velocity * H / q;
  r.pressure_drop = r.blocked ? (m_opt.darcy_velocity > 0 ? std::numeric_limits<double>::infinity() : 0.0) : r.flux_scale * kPressureDrop;
  const int P = m_pad, NX = nc + 2, NY = nr + 2 * P;  // node row j is the image's row j - P from the bottom
  const auto n = static_cast<std::size_t>(NX) * NY;
  m_ux.assign(n, 0.0);
  m_uy.assign(n, 0.0);
  m_h.assign(n, m_opt.depth);
  m_solid.assign(n, 1);
  for (int j = P; j < P + nr; ++j)
    for (int i = 0; i < NX; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * NX + i;
      const int col = std::clamp(i - 1, 0, nc - 1), row = nr - 1 - (j - P);
      if (all(row, col)) continue;
      m_solid[k] = 0;
      if (!aperture.empty()) m_h[k] = aperture[static_cast<std::size_t>(row) * nc + col];
    }
  // Pixel-face velocities for the engines' field (GridWalls::brinkman): the mean, over a pixel
  // face, of the solver's face velocities interpolated as Pollock does within each fluid cell
  // (linear along the component's own axis, constant across it). That reconstruction is
  // divergence-free wherever the solver's cells balance, so pixel faces balance too, at every
  // cells_per_pixel: finer or coarser than the pixels, particles follow the solver's fluxes.
  const Eigen::ArrayXXd& fu = solver->u();  // ny x (nx + 1), x-face ic at x = ic cw
  const Eigen::ArrayXXd& fv = solver->v();  // (ny + 1) x nx, y-face jc at y = jc ch
  const auto overlap = [](double a0, double a1, double b0, double b1) { return std::max(0.0, std::min(a1, b1) - std::max(a0, b0)); };
  // Mean of u over x = X, y in [y0, y1] (metres, inside the chip).
  const auto xFace = [&](double X, double y0, double y1) {
    const double f = std::clamp(X / cw, 0.0, static_cast<double>(nx));
    const int ic = std::min(static_cast<int>(f), nx - 1);
    const double s = f - ic;
    double sum = 0;
    for (int jc = std::max(0, static_cast<int>(std::floor(y0 / ch))); jc < ny && jc * ch < y1; ++jc)
      sum += overlap(y0, y1, jc * ch, (jc + 1) * ch) * ((1 - s) * fu(jc, ic) + s * fu(jc, ic + 1));
    return sum / (y1 - y0);
  };
  const auto yFace = [&](double Y, double x0, double x1) {
    const double f = std::clamp(Y / ch, 0.0, static_cast<double>(ny));
    const int jc = std::min(static_cast<int>(f), ny - 1);
    const double t = f - jc;
    double sum = 0;
    for (int ic = std::max(0, static_cast<int>(std::floor(x0 / cw))); ic < nx && ic * cw < x1; ++ic)
      sum += overlap(x0, x1, ic * cw, (ic + 1) * cw) * ((1 - t) * fv(jc, ic) + t * fv(jc + 1, ic));
    return sum / (x1 - x0);
  };
  for (int j = P; j < P + nr; ++j)
    for (int i = 0; i < NX; ++i) {
      const std::size_t k = static_cast<std::size_t>(j) * NX + i;
      if (m_solid[k]) continue;
      // Node i sits at x = (i - 1/2) p: its right face at x = i p (the padding beyond the
      // outlet repeats the outlet face); its top face at y = (j - P + 1) p.
      const double y0 = (j - P) * p, y1 = (j - P + 1) * p;
      m_ux[k] = r.flux_scale * xFace(std::min(i * p, W), y0, y1);
      const int col = std::clamp(i - 1, 0, nc - 1);
      m_uy[k] = r.flux_scale * yFace(y1, col * p, (col + 1) * p);
    }
  {
    const auto tb = std::chrono::steady_clock::now();
    if (m_opt.balance_faces) {
      const BalanceStats st = balanceFaceFluxes(m_ux, m_uy, m_solid, m_h, nc, nr, P);
      r.imbalance_before = st.before;
      r.imbalance_after = st.after;
      r.balance_iterations = st.iterations;
      r.balance_dropped_inflow = st.dropped_inflow;
    } else {
      r.imbalance_before = r.imbalance_after = faceImbalance(m_ux, m_uy, m_solid, m_h, nc, nr, P);
    }
    r.balance_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - tb).count();
  }
  if (m_opt.mirror_sides) {
    // The padding rows: the image mirrored across y = 0 and y = H (solid, depth, u_x copied; u_y,
    // on the top faces, taken from the mirrored face and reversed; zero on the planes themselves).
    const auto row = [&](int j) { return static_cast<std::size_t>(j) * NX; };
    for (int j = 0; j < NY; ++j) {
      bool flipped = false;
      if (j >= P && j < P + nr) {
        if (j == P + nr - 1)
          for (int i = 0; i < NX; ++i) m_uy[row(j) + i] = 0.0;  // the top plane's face
        continue;
      }
      const int src = P + mirroredRow(j - P, nr, flipped);
      const int face = mirroredFace(j - P + 1, nr, flipped);  // the node's top face, reflected into [0, nr]
      for (int i = 0; i < NX; ++i) {
        m_solid[row(j) + i] = m_solid[row(src) + i];
        m_h[row(j) + i] = m_h[row(src) + i];
        m_ux[row(j) + i] = m_ux[row(src) + i];
        m_uy[row(j) + i] = face == 0 || face == nr ? 0.0 : (flipped ? -1.0 : 1.0) * m_uy[row(P + face - 1) + i];
      }
    }
  }
  m_field->update(m_ux, m_uy, m_h, m_solid);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

void MicromodelFlow::restore(const std::vector<double>& ux, const std::vector<double>& uy, const std::vector<std::uint8_t>& solid,
                             const std::vector<double>& depth) {
  m_ux = ux;
  m_uy = uy;
  m_solid = solid;
  m_h = depth;
  m_field->update(m_ux, m_uy, m_h, m_solid);
}

double passableDiameter(const PixelMask& solid, double pixel, bool mirror_sides) {
  const int rows = static_cast<int>(solid.rows()), cols = static_cast<int>(solid.cols());
  const std::vector<double> d = pixelWallDistance(solid, pixel, mirror_sides);
  // Widest path (maximin) from the inlet column to the outlet column over
  // 4-connected pore pixels: a Dijkstra with max-heap on the bottleneck.
  std::vector<double> best(d.size(), -1.0);
  std::priority_queue<std::pair<double, int>> heap;
  for (int j = 0; j < rows; ++j) {
    const int k = j * cols;
    if (solid(rows - 1 - j, 0)) continue;
    best[k] = d[k];
    heap.emplace(d[k], k);
  }
  double answer = 0.0;
  while (!heap.empty()) {
    const auto [b, k] = heap.top();
    heap.pop();
    if (b < best[k]) continue;
    const int i = k % cols, j = k / cols;
    if (i == cols - 1) {
      answer = b;  // the first outlet pixel popped has the widest bottleneck
      break;
    }
    const int ni[4] = {i + 1, i - 1, i, i}, nj[4] = {j, j, j + 1, j - 1};
    for (int m = 0; m < 4; ++m) {
      if (ni[m] < 0 || ni[m] >= cols || nj[m] < 0 || nj[m] >= rows) continue;
      if (solid(rows - 1 - nj[m], ni[m])) continue;
      const int kk = nj[m] * cols + ni[m];
      const double nb = std::min(b, d[kk]);
      if (nb > best[kk]) {
        best[kk] = nb;
        heap.emplace(nb, kk);
      }
    }
  }
  return 2.0 * std::max(answer, 0.0);
}

double inletOpening(const PixelMask& solid, double pixel, bool mirror_sides) {
  const int rows = static_cast<int>(solid.rows()), cols = static_cast<int>(solid.cols());
  const std::vector<double> d = pixelWallDistance(solid, pixel, mirror_sides);
  double m = 0.0;
  for (int j = 0; j < rows; ++j) m = std::max(m, d[static_cast<std::size_t>(j) * cols]);
  return 2.0 * m;
}

}  // namespace mmval::particles
