// Pressure Poisson solve (CG + GAMG) against N: the O(N) part of the fluid
// solver. Three sizes; time per solve / N should stay ~flat.
#include <cmath>

#include <benchmark/benchmark.h>

#include "mmval/simulate/Petsc.hpp"
#include "mmval/simulate/PressurePoisson.hpp"

using namespace mmval::simulate;

static void BM_PoissonSolve(benchmark::State& state) {
  PetscSession::ensure();
  const int n = static_cast<int>(state.range(0));
  PressurePoisson poisson(uniformAxis(0, 1, n), uniformAxis(0, 1, n), false, false, 1e-8);
  Eigen::ArrayXXd f(n, n);
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) f(j, i) = std::cos(M_PI * (i + 0.5) / n) * std::cos(2 * M_PI * (j + 0.5) / n);
  for (auto _ : state) benchmark::DoNotOptimize(poisson.solve(f));
  state.counters["unknowns"] = static_cast<double>(n) * n;
  state.counters["iterations"] = poisson.stats().iterations;
  state.counters["setup_s"] = poisson.stats().setup_seconds;
  state.counters["ns_per_unknown"] = benchmark::Counter(static_cast<double>(n) * n, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}
BENCHMARK(BM_PoissonSolve)->Arg(128)->Arg(256)->Arg(512)->Arg(1024)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
