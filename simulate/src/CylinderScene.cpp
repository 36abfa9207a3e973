#include "mmval/simulate/CylinderScene.hpp"

#include <cmath>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"

namespace mmval::simulate {

CylinderScene readCylinderScene(const Case& c) {
  CylinderScene s;
  s.length_m = c.quantity("geometry.length");
  s.height_m = c.quantity("geometry.height");
  s.depth_m = c.quantity("geometry.depth");
  s.centre_x_m = c.quantity("geometry.cylinder_x");
  s.centre_y_m = c.quantity("geometry.cylinder_y");
  s.diameter_m = c.quantity("geometry.diameter");
  const double r = 0.5 * s.diameter_m;
  if (s.centre_x_m - r <= 0 || s.centre_y_m - r <= 0 || s.centre_y_m + r >= s.height_m || s.centre_x_m + r >= s.length_m)
    throw InputError(c.where("geometry.cylinder_x"), "the cylinder does not fit inside the channel", {},
                     "0 < x - d/2, x + d/2 < length, 0 < y - d/2, y + d/2 < height");
  s.density_kg_m3 = c.quantity("fluid.density");
  s.viscosity_pa_s = c.quantity("fluid.viscosity");
  s.uniform_inflow = c.text("inflow.profile") == "uniform";
  s.slip_walls = c.text("geometry.walls") == "slip";
  s.inflow_max_m_s = c.quantity("inflow.max_velocity");
  // The mean of the parabola 4 U y (H - y) / H^2 over [0, H] is 2/3 U.
  s.u_ref_m_s = c.has("forces.reference_velocity") ? c.quantity("forces.reference_velocity")
                                                    : (s.uniform_inflow ? 1.0 : 2.0 / 3.0) * s.inflow_max_m_s;
  s.l_ref_m = c.has("forces.reference_length") ? c.quantity("forces.reference_length") : s.diameter_m;
  if (c.has("probes.pressure_a") && c.has("probes.pressure_b")) {
    const auto& a = c.reals("probes.pressure_a");
    const auto& b = c.reals("probes.pressure_b");
    if (a.size() != 2 || b.size() != 2) throw InputError(c.where("probes.pressure_a"), "a probe needs two coordinates", {}, "[\"x\", \"y\"]");
    s.pressure_probes = {{a[0], a[1]}, {b[0], b[1]}};
  }
  return s;
}

double surfaceSpacing(const CylinderScene& s, int cells_around) { return M_PI * s.diameter_m / cells_around; }

}  // namespace mmval::simulate
