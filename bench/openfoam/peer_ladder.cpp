// Speed against error of the OpenFOAM peer on Schaefer-Turek 2D-1 and the
// square array at solid fraction 0.2: cells, error against the literature,
// meshing and solving wall time per level. Usage: bench_openfoam_ladder [OUT_DIR]
#include <cmath>
#include <cstdio>
#include <filesystem>

#include <fmt/format.h>

#include "mmval/openfoam/Peer.hpp"

int main(int argc, char** argv) {
  using namespace mmval::openfoam;
  const std::filesystem::path out = argc > 1 ? argv[1] : "out/bench-openfoam";
  if (!detect().available) {
    std::fprintf(stderr, "%s\n", detect().reason.c_str());
    return 1;
  }
  std::printf("%-22s %6s %8s %12s %10s %8s %8s %6s\n", "case", "level", "cells", "value", "error %", "mesh s", "solve s", "iters");
  const double cd_ref = 5.57953523384;  // John & Matthies (2001)
  int level = 0;
  for (int around : {32, 64, 128, 256}) {
    Scene s;
    s.cells_around = around;
    s.max_iterations = 4000;
    const Result r = runCase(s, out / fmt::format("st2d1-{}", around));
    if (!r.ok) {
      std::printf("st2d1 level %d failed: %s\n", level, r.failure.c_str());
      continue;
    }
    std::printf("%-22s %6d %8lld %12.6f %10.4f %8.2f %8.2f %6d\n", "ST 2D-1 c_D", level++, r.cells, *r.c_d, 100 * (*r.c_d - cd_ref) / cd_ref,
                r.mesh_seconds, r.solve_seconds, r.iterations);
  }
  const double fstar_ref = 51.53;  // Sangani & Acrivos (1982), phi = 0.2
  level = 0;
  for (int around : {32, 64, 128, 256}) {
    Scene s;
    s.kind = Scene::Kind::periodic_array;
    s.cell = 1e-4;
    s.radius = s.cell * std::sqrt(0.2 / M_PI);
    s.depth = 1e-5;
    s.nu = 1e-6;
    s.rho = 1000;
    s.mean_velocity = 1e-4;
    s.cells_around = around;
    s.max_iterations = 8000;
    const Result r = runCase(s, out / fmt::format("array02-{}", around));
    if (!r.ok) {
      std::printf("array level %d failed: %s\n", level, r.failure.c_str());
      continue;
    }
    std::printf("%-22s %6d %8lld %12.6f %10.4f %8.2f %8.2f %6d\n", "array phi=0.2 F*", level++, r.cells, *r.f_star,
                100 * (*r.f_star - fstar_ref) / fstar_ref, r.mesh_seconds, r.solve_seconds, r.iterations);
  }
  return 0;
}
