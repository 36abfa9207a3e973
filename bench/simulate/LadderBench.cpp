// Prints the resolution ladders (cells, unknowns, wall time, iterations,
// error, observed order) of the square array at phi 0.2 (both immersed
// treatments) and of Schaefer-Turek 2D-1 (with and without a finer box about the
// cylinder), with mmval's own solver.
#include <fmt/format.h>

#include "mmval/core/Run.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace {

void table(const mmval::Case& c, const mmval::CaseKindRegistry& reg, const char* title) {
  const auto out = reg.find(c.kind())->run(c, mmval::RunContext{{}, true, false, 0});
  fmt::print("\n{}\n{:>6} {:>8} {:>9} {:>8} {:>7} {:>12} {:>10} {:>7} {:>10}\n", title, "level", "cells", "unknowns", "wall s", "its", "value", "error %",
             "order", "c_L err %");
  for (const auto& r : out.details["ladder"])
    fmt::print("{:>6} {:>8} {:>9} {:>8.3f} {:>7} {:>12.6g} {:>10} {:>7} {:>10}\n", r["resolution"].get<int>(), r["cells"].get<long long>(),
               r["unknowns"].get<long long>(), r["wall_seconds"].get<double>(), r["linear_iterations"].get<int>(), r["value"].get<double>(),
               r.contains("error") ? fmt::format("{:+.4f}", 100 * r["error"].get<double>()) : "-",
               r.contains("observed_order") ? fmt::format("{:.2f}", r["observed_order"].get<double>()) : "-",
               r.contains("c_L_error") ? fmt::format("{:+.2f}", 100 * r["c_L_error"].get<double>()) : "-");
}

}  // namespace

int main() {
  mmval::simulate::PetscSession::ensure();
  mmval::CaseKindRegistry reg;
  mmval::simulate::registerFluidKinds(reg);
  const std::string dir = std::string(MMVAL_SOURCE_DIR) + "/cases/";
  mmval::Case arr = mmval::Case::load(dir + "fluid-square-array-phi020.toml", reg);
  arr.set("numerics.levels", std::vector<std::int64_t>{16, 32, 64, 128});
  table(arr, reg, "square array phi 0.2, sharp: F* vs Sangani & Acrivos 51.53");
  arr.set("numerics.immersed", std::string("penalized"));
  table(arr, reg, "square array phi 0.2, penalized (volume fraction): F*");
  mmval::Case st = mmval::Case::load(dir + "fluid-schaefer-turek-2d1.toml", reg);
  st.set("numerics.levels", std::vector<std::int64_t>{32, 64, 96, 128});
  table(st, reg, "Schaefer-Turek 2D-1, sharp: c_D vs 5.57953523384");
  // The same with a box of h / 2 within 1 D of the centre: D/41 at the body from cells_around 64.
  st.set("numerics.levels", std::vector<std::int64_t>{32, 48, 64});
  st.set("numerics.body_refine", std::int64_t{2});
  table(st, reg, "Schaefer-Turek 2D-1, sharp, body box h/2 (numerics.body_refine 2): c_D vs 5.57953523384");
  return 0;
}
