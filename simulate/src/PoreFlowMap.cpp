#include "mmval/simulate/PoreFlowMap.hpp"

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::simulate {

namespace {
/// Cells of the coarse grid the flow is solved on, whatever the image size: the
/// synthetic video needs the flow pattern, not a converged permeability.
constexpr double kMaxCells = 40000;
}  // namespace

PoreFlowMap::PoreFlowMap(const cv::Mat& grains, double mean_speed) : m_w(grains.cols), m_h(grains.rows) {
  // The mirrored image is coarsened by an integer factor to at most kMaxCells cells.
  m_f = std::max(1, static_cast<int>(std::ceil(std::sqrt(2.0 * m_w * m_h / kMaxCells))));
  // Mirrored mask at image resolution, rows top to bottom as MaskShape wants.
  BoolArray solid(m_h, 2 * m_w);
  for (int r = 0; r < m_h; ++r)
    for (int c = 0; c < 2 * m_w; ++c) solid(r, c) = grains.at<unsigned char>(r, c < m_w ? c : 2 * m_w - 1 - c) != 0;
  PoreSpaceReport pores;
  try {
    pores = analysePoreSpace(solid);
  } catch (const NoFlowPath&) {
    throw std::runtime_error("no pore path crosses the geometry from left to right: the synthetic flow would be zero everywhere");
  }
  // Lengths in pixels, unit viscosity and driving force: the scale drops out below.
  FlowProblem p;
  const int nx = std::max(4, 2 * m_w / m_f), ny = std::max(4, m_h / m_f);
  p.x = uniformAxis(0, 2.0 * m_w, nx);
  p.y = uniformAxis(0, m_h, ny);
  p.boundary[static_cast<int>(Side::west)].type = BoundaryType::periodic;
  p.boundary[static_cast<int>(Side::east)].type = BoundaryType::periodic;
  p.boundary[static_cast<int>(Side::south)].type = BoundaryType::no_slip;
  p.boundary[static_cast<int>(Side::north)].type = BoundaryType::no_slip;
  p.density = 1;
  p.viscosity = 1;
  p.body_force = {1, 0};
  p.shape = std::make_shared<MaskShape>(pores.solid_connected, 1.0);
  p.method = ImmersedMethod::penalized;  // smooth through the pixel staircase at a coarse grid
  SteadyFlowSolver solver(p, {}, MPI_COMM_SELF);
  solver.solve();
  const Eigen::ArrayXXd u = solver.cellVelocity(0), v = solver.cellVelocity(1);
  // Solver rows run bottom to top (y up); images top to bottom (y down).
  m_u.create(ny, nx, CV_64F);
  m_v.create(ny, nx, CV_64F);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      m_u.at<double>(ny - 1 - j, i) = u(j, i);
      m_v.at<double>(ny - 1 - j, i) = -v(j, i);
    }
  double sum = 0;
  int n = 0;
  for (int y = 0; y < m_h; y += 2)
    for (int x = 0; x < m_w; x += 2)
      if (!pores.solid_connected(y, x)) {
        const cv::Point2d w = raw(x + 0.5, y + 0.5);
        sum += std::hypot(w.x, w.y);
        ++n;
      }
  m_scale = n > 0 && sum > 0 ? mean_speed / (sum / n) : 0;
}

cv::Point2d PoreFlowMap::at(double x, double y) const {
  const cv::Point2d w = raw(x, y);
  return {w.x * m_scale, w.y * m_scale};
}

cv::Point2d PoreFlowMap::raw(double x, double y) const {
  // Cell (r, c) is centred at ((c + 0.5) * cell_w, (r + 0.5) * cell_h) in image pixels.
  const double cw = 2.0 * m_w / m_u.cols, ch = static_cast<double>(m_h) / m_u.rows;
  const double gx = x / cw - 0.5, gy = y / ch - 0.5;
  const int c0 = static_cast<int>(std::floor(gx)), r0 = static_cast<int>(std::floor(gy));
  const double fx = gx - c0, fy = gy - r0;
  auto sample = [&](const cv::Mat& a) {
    auto A = [&](int r, int c) { return a.at<double>(std::clamp(r, 0, a.rows - 1), ((c % a.cols) + a.cols) % a.cols); };
    return (1 - fx) * (1 - fy) * A(r0, c0) + fx * (1 - fy) * A(r0, c0 + 1) + (1 - fx) * fy * A(r0 + 1, c0) + fx * fy * A(r0 + 1, c0 + 1);
  };
  return {sample(m_u), sample(m_v)};
}

}  // namespace mmval::simulate
