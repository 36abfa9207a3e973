// Chip permeability with the project's solver (see ChipFlow.hpp).
#include "mmval/simulate/ChipFlow.hpp"

#include <chrono>
#include <cmath>
#include <memory>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"
#include "mmval/simulate/Stokes3D.hpp"

namespace mmval::simulate {

ChipFlowResult chipPermeability(const BoolArray& solid, const ChipFlowSettings& s, double cpp) {
  const auto t0 = std::chrono::steady_clock::now();
  std::shared_ptr<const Shape> shape;
  if (s.smooth_boundary) shape = std::make_shared<SmoothMaskShape>(solid, s.pixel_m, s.smoothing_px);
  else shape = std::make_shared<MaskShape>(solid, s.pixel_m);
  const double width = static_cast<double>(solid.cols()) * s.pixel_m, height = static_cast<double>(solid.rows()) * s.pixel_m;
  FlowProblem p;
  p.x = uniformAxis(0, width, std::max(4, static_cast<int>(std::lround(solid.cols() * cpp))));
  p.y = uniformAxis(0, height, std::max(4, static_cast<int>(std::lround(solid.rows() * cpp))));
  p.boundary[static_cast<int>(Side::west)].type = BoundaryType::pressure;
  p.boundary[static_cast<int>(Side::east)].type = BoundaryType::pressure;
  p.boundary[static_cast<int>(Side::west)].pressure = s.pressure_drop_Pa;
  p.boundary[static_cast<int>(Side::south)].type = BoundaryType::slip;
  p.boundary[static_cast<int>(Side::north)].type = BoundaryType::slip;
  p.viscosity = s.viscosity_Pa_s;
  p.depth = s.depth_m;
  p.shape = shape;
  SteadyFlowSolver solver(p);
  solver.solve();
  ChipFlowResult r;
  // Darcy: k = mu Q L / (A dp), Q per unit depth and A = height in the depth-averaged model too.
  r.permeability_m2 = s.viscosity_Pa_s * solver.flowRate(Side::east) * width / (height * s.pressure_drop_Pa);
  r.nx = solver.nx();
  r.ny = solver.ny();
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

ChipFlow3DResult chipPermeability3D(const BoolArray& solid, const ChipFlowSettings& s, double cpp, const std::vector<int>& cells_z) {
  const auto t0 = std::chrono::steady_clock::now();
  ChipFlow3DResult r;
  r.cells_per_pixel = cpp;
  r.cells_z = cells_z;
  // The problem image-permeability's 3D model builds (KindsPorous.cpp, run3d).
  Stokes3DProblem p = maskStokes3DProblem(solid, s.pixel_m, s.depth_m, s.viscosity_Pa_s, s.pressure_drop_Pa, cpp);
  r.nx = p.nx;
  r.ny = p.ny;
  for (const int nz : cells_z) {
    p.nz = nz;
    Stokes3DSolver solver(p);
    solver.solve();
    r.permeability_m2.push_back(solver.permeability());
    r.iterations.push_back(solver.stats().iterations);
    r.cells.push_back(solver.stats().cells);
  }
  r.extrapolated_m2 = extrapolateInDepthCells(cells_z, r.permeability_m2).value_or(r.permeability_m2.empty() ? 0.0 : r.permeability_m2.back());
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

ChipLadder chipLadder(const BoolArray& solid, const ChipFlowSettings& s, const std::vector<double>& levels, const std::string& model,
                      const std::vector<std::pair<double, ChipFlowResult>>& known) {
  ChipLadder l;
  l.model = model;
  l.cells_per_pixel = levels;
  ChipFlowSettings ms = s;
  if (model == "2d") ms.depth_m = 0;
  std::vector<double> h, k_darcy;
  for (const double cpp : levels) {
    ChipFlowResult r;
    bool have = false;
    for (const auto& [c, res] : known)
      if (std::abs(c - cpp) < 1e-12) {
        r = res;
        have = true;
      }
    if (!have) r = chipPermeability(solid, ms, cpp);
    l.runs.push_back(r);
    h.push_back(1.0 / r.nx);
    k_darcy.push_back(r.permeability_m2 / kDarcyM2);
  }
  // Formal order when none is observed: 2 on the smooth boundary, 1 on the staircase (KindsPorous.cpp).
  l.convergence = gridConvergence(h, k_darcy, s.smooth_boundary ? 2.0 : 1.0);
  return l;
}

}  // namespace mmval::simulate
