// The cylinder-channel scene, solver-neutral: what a case of kind
// "cylinder-channel" says about the physics (channel, cylinder, fluid, inflow,
// reference scales, pressure probes), read once from the case. mmval's own
// solver (KindsCylinder.cpp) and the OpenFOAM peer (mmval::openfoam) both build
// their problems from this struct; each solver's resolution keys stay with the
// solver. SI units throughout.
#pragma once
#include <array>
#include <cmath>
#include <vector>

namespace mmval {
class Case;
}

namespace mmval::simulate {

struct CylinderScene {
  double length_m = 2.2, height_m = 0.41;  ///< channel [0, length] x [0, height]
  double depth_m = 0.1;                    ///< extrusion depth (OpenFOAM's one-cell thickness; mmval's coefficients are per unit depth)
  double centre_x_m = 0.2, centre_y_m = 0.2, diameter_m = 0.1;
  double density_kg_m3 = 1.0, viscosity_pa_s = 1e-3;
  bool uniform_inflow = false;  ///< uniform inflow instead of the parabola 4 U y (H - y) / H^2
  bool slip_walls = false;      ///< slip (free-stream) instead of no-slip channel walls
  double inflow_max_m_s = 0.3;  ///< peak of the parabolic inflow, or the uniform inflow speed
  /// Scales of the coefficients c = 2 F / (rho u_ref^2 l_ref) (per unit depth).
  double u_ref_m_s = 0.2, l_ref_m = 0.1;
  /// dp = p(first) - p(second); empty when the case gives no probes.
  std::vector<std::array<double, 2>> pressure_probes;

  double kinematicViscosity() const { return viscosity_pa_s / density_kg_m3; }
  /// Re = rho u_ref D / mu: the cylinder's Reynolds number (on its diameter, whatever l_ref is).
  double reynolds() const { return density_kg_m3 * u_ref_m_s * diameter_m / viscosity_pa_s; }
  /// 2 / (rho u_ref^2 l_ref): turns a force per unit depth (N/m) into its coefficient.
  double forceCoefficient() const { return 2.0 / (density_kg_m3 * u_ref_m_s * u_ref_m_s * l_ref_m); }
  /// D / H: the fraction of the channel height the cylinder blocks.
  double blockage() const { return diameter_m / height_m; }
  /// Inflow speed at height y (m/s): the parabola, or the uniform value.
  double inflowAt(double y) const {
    return uniform_inflow ? inflow_max_m_s : 4 * inflow_max_m_s * y * (height_m - y) / (height_m * height_m);
  }
};

/// Reads the scene from a case of kind "cylinder-channel" (geometry.*, fluid.*, inflow.*,
/// forces.*, probes.*). u_ref defaults to the mean inflow (2/3 of the peak for the parabola),
/// l_ref to the diameter. Throws InputError naming geometry.cylinder_x when the cylinder does not
/// fit inside the channel, and probes.pressure_a when a probe is not two coordinates.
CylinderScene readCylinderScene(const Case& c);

/// The spacing `numerics.cells_around` sets at the cylinder surface, for both solvers: the
/// circumference over the cells around it, pi D / cells_around (m). mmval's uniform cells about
/// the body have this size; the peer's O-grid puts cells_around cells of this arc length on the
/// circumference.
double surfaceSpacing(const CylinderScene& s, int cells_around);

/// The start vortex of an unsteady scene with numerics.initial_perturbation eps, the same for
/// both solvers (mmval's sets it directly, the OpenFOAM peer through setExprFields): a Gaussian
/// vortex 1.5 D behind the cylinder's centre, u = A (-Y, X) exp(-(X^2 + Y^2)) with X, Y in
/// diameters from the vortex and A = eps U sqrt(e / 2), so that its peak speed, at
/// r = D / sqrt 2, is A exp(-1/2) / sqrt 2 = eps U / 2.
struct StartVortex {
  double x_m = 0, y_m = 0, diameter_m = 1, amplitude_m_s = 0;
  std::array<double, 2> velocity(double x, double y) const {
    const double X = (x - x_m) / diameter_m, Y = (y - y_m) / diameter_m, g = amplitude_m_s * std::exp(-(X * X + Y * Y));
    return {-Y * g, X * g};
  }
};
inline StartVortex startVortex(double centre_x_m, double centre_y_m, double diameter_m, double eps, double u_ref_m_s) {
  return {centre_x_m + 1.5 * diameter_m, centre_y_m, diameter_m, eps * u_ref_m_s * std::sqrt(std::exp(1.0) / 2)};
}

}  // namespace mmval::simulate
