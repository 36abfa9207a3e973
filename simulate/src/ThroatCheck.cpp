#include "mmval/simulate/ThroatCheck.hpp"

#include <cmath>
#include <cstdio>
#include <limits>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/simulate/Petsc.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::simulate {

namespace {

/// key_value scaled by `factor`, rounded up: to an integer when key_value is one, else to 2 decimals.
std::string scaledUp(double key_value, double factor) {
  const double v = key_value * factor;
  if (key_value == std::floor(key_value)) return fmt::format("{}", static_cast<long long>(std::ceil(v - 1e-9)));
  return fmt::format("{:.2f}", std::ceil(v * 100 - 1e-9) / 100);
}

}  // namespace

double checkThroats(const FlowProblem& p, const std::string& key, double key_value, RunOutput& out, bool quiet, double warn_cells, double image_pixel_m,
                    ThroatFound* found) {
  if (!p.shape) return std::numeric_limits<double>::infinity();
  const bool px = p.boundary[0].type == BoundaryType::periodic, py = p.boundary[2].type == BoundaryType::periodic;
  Throat t;
  if (const auto* mask = dynamic_cast<const MaskShape*>(p.shape.get()); mask != nullptr && std::abs(mask->width() - p.x.length()) < 1e-9 * p.x.length() &&
                                                                        std::abs(mask->height() - p.y.length()) < 1e-9 * p.y.length())
    t = narrowestThroat(mask->mask(), mask->pixel(), px, py, p.x.lo(), p.y.lo());
  else
    t = narrowestThroat(*p.shape, p.x.lo(), p.x.hi(), p.y.lo(), p.y.hi(), std::min(p.x.minWidth(), p.y.minWidth()) / 8, px, py);
  if (!t.path) return 0.0;  // no path at all: the kinds report that as an input error (analysePoreSpace)
  if (!std::isfinite(t.width_m)) return t.width_m;
  const double h = std::min(p.x.width(p.x.cellOf(t.x_m)), p.y.width(p.y.cellOf(t.y_m)));
  const double cells = t.width_m / h;
  std::string where = fmt::format("{:.3g} m at x = {:.4g} m, y = {:.4g} m", t.width_m, t.x_m, t.y_m);
  ThroatFound f;
  f.throat = t;
  f.cells = cells;
  if (image_pixel_m > 0) {
    // The throat's pixel (its centre) as the image's column and row, row 0 at the top.
    f.x_px = std::floor((t.x_m - p.x.lo()) / image_pixel_m);
    f.y_px = std::floor((p.y.hi() - t.y_m) / image_pixel_m);
    f.width_px = t.width_m / image_pixel_m;
    where = fmt::format("{:.3g} px = {:.3g} m at pixel x = {:.0f}, y = {:.0f} of the image (column, row from its top-left corner)", f.width_px,
                        t.width_m, f.x_px, f.y_px);
  }
  if (found != nullptr) *found = f;
  if (cells < 1.0 - 1e-6)  // a throat of exactly one cell (a one-pixel throat at 1 cell per pixel) still carries flow
    throw NumericalFailure(fmt::format("the narrowest throat of the flow path is {:.2f} cells wide ({}) at {} = {}: narrower than one cell, the grid "
                                       "cannot carry flow through it",
                                       cells, where, key, key_value),
                           key, fmt::format("at least {} (2 cells across the throat)", scaledUp(key_value, kWarnThroatCells / cells)));
  if (cells < warn_cells) {
    const std::string w = fmt::format("the narrowest throat of the flow path is {:.2f} cells wide ({}) at {} = {}: below {} cells the flow through it is "
                                      "under-resolved and the result can be off by a large factor (a one-pixel throat at 1 cell per pixel: +197 %); "
                                      "raise '{}' to at least {}",
                                      cells, where, key, key_value, warn_cells, key, scaledUp(key_value, warn_cells / cells));
    if (!out.details.contains("warnings")) out.details["warnings"] = nlohmann::json::array();
    out.details["warnings"].push_back(w);
    if (!quiet && PetscSession::rank() == 0) std::fprintf(stderr, "mmval: warning: %s\n", w.c_str());
  }
  return cells;
}

const FlowStats& solveNamingKey(SteadyFlowSolver& s, const std::string& key) {
  try {
    return s.solve();
  } catch (const FlowFailure& e) {
    throw e.withKey(key);
  }
}

}  // namespace mmval::simulate
