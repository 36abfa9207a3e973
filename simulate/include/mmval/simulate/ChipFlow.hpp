// Permeability of a chip mask with mmval's own steady Stokes solver, as the image-permeability
// kind computes it (simulate/src/KindsPorous.cpp): pressure inlet on the left, outlet on the
// right, slip sides, the mask's grains as immersed boundaries (sharp, merged cut cells, direct
// solve); plane 2D, or depth-averaged with the Hele-Shaw friction 12 mu u / h^2 of the chip depth h.
#pragma once
#include <string>
#include <vector>

#include "mmval/simulate/GridConvergence.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::simulate {

struct ChipFlowSettings {
  double pixel_m = 5e-6;
  double depth_m = 20e-6;          ///< 0: plane 2D
  bool smooth_boundary = true;     ///< image-permeability's geometry.boundary = "smooth" (else "pixels")
  double smoothing_px = 0.75;      ///< its geometry.smoothing (default there)
  double viscosity_Pa_s = 1e-3;    ///< Stokes flow: k does not depend on it
  double pressure_drop_Pa = 1;     ///< nor on this
};

struct ChipFlowResult {
  double permeability_m2 = 0;
  int nx = 0, ny = 0;
  double seconds = 0;
};

/// Darcy permeability k = mu Q L / (A dp) of `solid` (row 0 at the top, isolated pores already
/// closed: PoreSpaceReport::solid_connected) at `cells_per_pixel`. Throws NoFlowPath / FlowFailure
/// (the solver's) when no path joins inlet and outlet or the grid cannot carry the flow.
ChipFlowResult chipPermeability(const BoolArray& solid, const ChipFlowSettings& s, double cells_per_pixel);

/// One depth model on a ladder of cells per pixel (coarse to fine).
struct ChipLadder {
  std::string model;               ///< "2d" or "depth-averaged"
  std::vector<double> cells_per_pixel;
  std::vector<ChipFlowResult> runs;
  GridConvergence convergence;     ///< on k in darcy
};

/// The ladder of one model; `known` (cells per pixel -> result) skips levels already solved.
ChipLadder chipLadder(const BoolArray& solid, const ChipFlowSettings& s, const std::vector<double>& levels, const std::string& model,
                      const std::vector<std::pair<double, ChipFlowResult>>& known = {});

/// The coarse 3D Stokes model of the same mask (Stokes3D.hpp, as image-permeability's
/// numerics.depth_model = "3d" builds it): the mask block-averaged onto cells_per_pixel_3d cells per
/// pixel in the plane, extruded between no-slip plates s.depth_m apart, one solve per cells_z level.
struct ChipFlow3DResult {
  double cells_per_pixel = 1;
  std::vector<int> cells_z;           ///< levels, coarse to fine
  std::vector<double> permeability_m2;  ///< per level
  std::vector<int> iterations;        ///< FGMRES iterations per level
  std::vector<long long> cells;       ///< nx ny nz per level
  double extrapolated_m2 = 0;         ///< Richardson in dz over the two finest levels, order 2 (the finest with one level)
  int nx = 0, ny = 0;
  double seconds = 0;
};

/// Throws NoFlowPath when the block-averaged mask has no open path (throats under a cell).
ChipFlow3DResult chipPermeability3D(const BoolArray& solid, const ChipFlowSettings& s, double cells_per_pixel_3d, const std::vector<int>& cells_z);

/// 1 darcy in m^2 (9.869233e-13: the definition 1 cP, 1 cm/s, 1 atm/cm).
inline constexpr double kDarcyM2 = 9.869233e-13;

}  // namespace mmval::simulate
