// The periodic-array scene, solver-neutral: a square unit cell of side L with
// one cylinder of solid area fraction phi at its centre, creeping flow at a
// mean velocity (a case of kind "periodic-array"), read once from the case for
// mmval's own solver and the OpenFOAM peer. The resolution,
// numerics.cells_per_side, sets h = L / n for both: the peer derives its cells
// around the cylinder from it (openfoam::arrayCellsAround). SI units.
#pragma once

namespace mmval {
class Case;
}

namespace mmval::simulate {

struct PeriodicArrayScene {
  double cell_m = 100e-6;       ///< side L of the unit cell
  double solid_fraction = 0.2;  ///< phi = pi a^2 / L^2
  double density_kg_m3 = 1000.0, viscosity_pa_s = 1e-3;
  double mean_velocity_m_s = 1e-4;  ///< superficial velocity scale (Stokes: F* does not depend on it)

  /// Cylinder radius a = L sqrt(phi / pi), m.
  double radius() const;
  double kinematicViscosity() const { return viscosity_pa_s / density_kg_m3; }
};

/// Largest solid fraction: at pi / 4 neighbouring cylinders touch and close the array.
inline constexpr double kTouchingSolidFraction = 0.78539816339744830962;

/// Reads the scene from a case of kind "periodic-array" (geometry.cell, geometry.solid_fraction,
/// fluid.*, flow.mean_velocity). Throws InputError naming geometry.solid_fraction when the
/// cylinders touch (phi >= pi / 4).
PeriodicArrayScene readPeriodicArrayScene(const Case& c);

}  // namespace mmval::simulate
