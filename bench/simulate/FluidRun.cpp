// fluid_run CASE.toml OUT_DIR: runs a fluid case with mmval's own solver
// (registerFluidKinds) and writes OUT_DIR/result.json; prints the metrics.
// A stand-in for `mmval run` until apps/ registers the fluid kinds.
#include <cstdio>
#include <exception>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/Kinds.hpp"
#include "mmval/simulate/Petsc.hpp"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: fluid_run CASE.toml OUT_DIR\n");
    return 1;
  }
  try {
    mmval::simulate::PetscSession::ensure();
    mmval::CaseKindRegistry registry;
    mmval::simulate::registerFluidKinds(registry);
    const mmval::Case c = mmval::Case::load(argv[1], registry);
    const auto s = mmval::runCase(c, registry, argv[2], {true, false});
    for (const auto& m : s.metrics)
      fmt::print("{:<28} {:>14.7g} {:<8} {}\n", m.name, m.value, m.unit,
                 m.pass ? fmt::format("{} (error {:+.3g}, tolerance {})", *m.pass ? "PASS" : "FAIL", m.error, m.tolerance) : std::string("info"));
    fmt::print("wall {:.2f} s -> {}\n", s.wall_seconds, s.result_file.string());
    return s.all_pass ? 0 : 3;
  } catch (const mmval::InputError& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "error: %s\n", e.what());
    return 4;
  }
}
