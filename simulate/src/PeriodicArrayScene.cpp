#include "mmval/simulate/PeriodicArrayScene.hpp"

#include <cmath>

#include <fmt/format.h>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"

namespace mmval::simulate {

double PeriodicArrayScene::radius() const { return cell_m * std::sqrt(solid_fraction / M_PI); }

PeriodicArrayScene readPeriodicArrayScene(const Case& c) {
  PeriodicArrayScene s;
  s.cell_m = c.quantity("geometry.cell");
  s.solid_fraction = c.quantity("geometry.solid_fraction");
  if (s.solid_fraction > kTouchingSolidFraction - 1e-9)
    throw InputError(c.where("geometry.solid_fraction"), "the cylinders touch (phi > pi/4 closes the square array)", fmt::format("{}", s.solid_fraction),
                     "phi < 0.785");
  s.density_kg_m3 = c.quantity("fluid.density");
  s.viscosity_pa_s = c.quantity("fluid.viscosity");
  s.mean_velocity_m_s = c.quantity("flow.mean_velocity");
  return s;
}

}  // namespace mmval::simulate
