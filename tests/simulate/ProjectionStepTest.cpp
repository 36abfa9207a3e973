// UnsteadyFlowSolver with the incremental pressure-correction step (UnsteadyMethod::projection,
// simulate/src/ProjectionStep.cpp), on 1 MPI rank: the Taylor-Green vortex against its exact
// decay, vortex shedding behind a cylinder against the coupled solve on the same grid, and a
// checkpoint restart that continues bit for bit.
#include <cmath>
#include <cstdio>
#include <memory>

#include <gtest/gtest.h>

#include "CylinderChannelProblem.hpp"

#include "mmval/core/Checkpoint.hpp"
#include "mmval/simulate/ForceHistory.hpp"
#include "mmval/simulate/UnsteadyFlowSolver.hpp"

using namespace mmval::simulate;

namespace {

UnsteadyOptions projection(double courant) {
  UnsteadyOptions o;
  o.method = UnsteadyMethod::projection;
  o.max_courant = courant;
  return o;
}

/// Taylor-Green vortex in the periodic unit square: u = -U cos(kx) sin(ky) E, v = U sin(kx) cos(ky) E,
/// p = -rho U^2 (cos 2kx + cos 2ky) E^2 / 4, E = exp(-2 nu k^2 t), k = 2 pi; an exact Navier-Stokes solution.
constexpr double kL = 1.0, kU = 1.0, kNu = 0.01;  // Re = U L / nu = 100
const double kK = 2 * M_PI / kL;

FlowProblem taylorGreenProblem(int n) {
  FlowProblem p;
  p.x = uniformAxis(0, kL, n);
  p.y = uniformAxis(0, kL, n);
  for (auto& b : p.boundary) b.type = BoundaryType::periodic;
  p.density = 1;
  p.viscosity = kNu;
  return p;
}

struct TaylorGreen {
  double amplitude;        ///< least-squares amplitude of the discrete u on the exact mode, relative to U
  double pressure_error;   ///< max |p - p_exact| (both with zero mean) over rho U^2 E^2 / 4 at t
  double divergence;
};

TaylorGreen runTaylorGreen(UnsteadyMethod method, int n, double courant, double t_end, bool rotational = false) {
  UnsteadyOptions o = projection(courant);
  o.method = method;
  o.projection_rotational = rotational;
  UnsteadyFlowSolver s(taylorGreenProblem(n), {}, o);
  s.setVelocity([](double x, double y) { return Eigen::Vector2d(-kU * std::cos(kK * x) * std::sin(kK * y), kU * std::sin(kK * x) * std::cos(kK * y)); });
  while (s.time() < t_end * (1 - 1e-12)) s.step(t_end - s.time());
  Eigen::ArrayXXd u, v, p;
  s.fields(u, v, p);
  const double h = kL / n, E = std::exp(-2 * kNu * kK * kK * s.time());
  double num = 0, den = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double shape = -std::cos(kK * i * h) * std::sin(kK * (j + 0.5) * h);  // u node (face x_i, centre y_j)
      num += u(j, i) * shape;
      den += shape * shape;
    }
  const Eigen::ArrayXXd pc = p - p.mean();
  double perr = 0;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double x = (i + 0.5) * h, y = (j + 0.5) * h;
      const double pe = -kU * kU / 4 * (std::cos(2 * kK * x) + std::cos(2 * kK * y)) * E * E;  // zero mean on the cell centres
      perr = std::max(perr, std::abs(pc(j, i) - pe));
    }
  return {num / den / (kU * E), perr / (kU * kU / 4 * E * E), s.maxRelativeDivergence()};
}

Eigen::Vector2d vortex(double x, double y) {  // starts the shedding early
  const double X = (x - 0.35) / 0.1, Y = (y - 0.2) / 0.1, g = 0.5 * std::exp(-(X * X + Y * Y));
  return {-Y * g, X * g};
}

}  // namespace

TEST(UnsteadyProjection, TaylorGreenDecaysAsTheExactSolution) {
  // Re 100, 32 x 32 cells, Courant 0.5, t = 0.5 (the amplitude decays to 0.67). Error budget of the
  // amplitude: the 5-point Laplacian's eigenvalue is 2 k^2 (1 - (kh)^2 / 12), +0.13 % at kh = 0.2
  // (the coupled solve reads +0.13 %); the splitting, second order in dt (next test), measured
  // +0.19 % here against the coupled solve (the rotational form, ProjectionStep.hpp, changes it by
  // 2 %: without walls there is no pressure boundary layer to remove). Tolerances: 0.5 % against the exact decay,
  // 0.3 % against the coupled solve. A projection that lost the pressure increment (velocity not
  // corrected) or doubled it changes the decay by 5-50 %; a missing transient mass in the
  // correction leaves the divergence O(1); a first step without its pressure sweeps was 1.9 % off
  // the coupled solve at Courant 1 (0.38 % with them).
  const TaylorGreen tg = runTaylorGreen(UnsteadyMethod::projection, 32, 0.5, 0.5);
  const TaylorGreen ref = runTaylorGreen(UnsteadyMethod::coupled, 32, 0.5, 0.5);
  std::printf("Taylor-Green: amplitude / exact %.6f (coupled %.6f), pressure error %.4f (coupled %.4f), divergence %.2e\n", tg.amplitude, ref.amplitude,
              tg.pressure_error, ref.pressure_error, tg.divergence);
  EXPECT_NEAR(tg.amplitude, 1.0, 5e-3);
  // Against the coupled solve of the same discretisation: what differs is the splitting, O(dt^2).
  EXPECT_NEAR(tg.amplitude, ref.amplitude, 3e-3);
  // The pressure: second-order MAC plus the incremental scheme's pressure error (coupled 1.4 %,
  // projection 0.7 % of the peak); 3 %.
  EXPECT_LT(tg.pressure_error, 0.03);
  EXPECT_LT(tg.divergence, 1e-6);  // the correction makes the velocity divergence-free to the Poisson tolerance
  // On one rank the pressure solve is K's LU factorisation (made once), exact to rounding: measured
  // 1.7e-16. CG with BoomerAMG to its 1e-8 tolerance (the path of several ranks) left 2.1e-12 on 2 ranks.
  EXPECT_LT(tg.divergence, 1e-13);

  // The rotational form (numerics.projection_rotational) against the same exact decay and the
  // same tolerances; it differs from the standard form by a few % of the splitting error here
  // (no walls), so more than 1e-3 between the two would be a fault in its pressure update.
  const TaylorGreen rot = runTaylorGreen(UnsteadyMethod::projection, 32, 0.5, 0.5, true);
  std::printf("Taylor-Green, rotational: amplitude / exact %.6f, pressure error %.4f\n", rot.amplitude, rot.pressure_error);
  EXPECT_NEAR(rot.amplitude, 1.0, 5e-3);
  EXPECT_NEAR(rot.amplitude, tg.amplitude, 1e-3);
  EXPECT_NE(rot.amplitude, tg.amplitude);  // the option reaches the step
  EXPECT_LT(rot.pressure_error, 0.03);
  EXPECT_LT(rot.divergence, 1e-6);
}

TEST(UnsteadyProjection, TaylorGreenErrorFallsAtSecondOrderInTheStep) {
  // Same vortex at Courant 1, 0.5, 0.25 on a fine grid against the coupled solve at 0.125 (the
  // splitting and step errors only; the spatial error is common to both). BDF2 with incremental
  // pressure correction: second order for the velocity (Guermond, Minev & Shen 2006). Measured
  // 1.88 and 1.97 (1.86 and 1.96 with the rotational form).
  double last = 0;
  const double ref = runTaylorGreen(UnsteadyMethod::coupled, 32, 0.125, 0.25).amplitude;
  std::vector<double> err;
  for (const double c : {1.0, 0.5, 0.25}) err.push_back(std::abs(runTaylorGreen(UnsteadyMethod::projection, 32, c, 0.25).amplitude - ref));
  for (std::size_t k = 1; k < err.size(); ++k) {
    const double order = std::log2(err[k - 1] / err[k]);
    std::printf("Taylor-Green: amplitude error %.3e -> %.3e, observed order %.2f\n", err[k - 1], err[k], order);
    last = order;
  }
  EXPECT_GT(last, 1.6);
}

TEST(UnsteadyProjection, CylinderSheddingAgreesWithTheCoupledSolve) {
  // Schaefer-Turek channel at Re 200 (U_max 3 m/s), h = D/8, Courant 1, 1.4 s (about 4 periods
  // after the start-up), both step methods on the same grid from the same initial vortex. Their
  // difference is the splitting error (measured 2026-12-05, see the printout: St -0.11 %, c_D
  // mean +0.034 %, c_L amplitude -0.11 %; with the rotational form -0.105 %, +0.035 %,
  // -0.106 %). Tolerances: St 0.3 %, c_D mean 0.3 %, c_L amplitude 0.5 %; the coarse grid's own
  // error against the benchmark is 3-30 %, so these judge the split, not the grid. A correction
  // without the transient mass or with a lagged pressure moves them by 5-50 %.
  const double D = 0.1, Ubar = 2.0, c = 2 / (Ubar * Ubar * D);
  SheddingStats st[2];
  double divergence = 0;
  for (const int k : {0, 1}) {
    UnsteadyOptions o;
    o.method = k == 0 ? UnsteadyMethod::coupled : UnsteadyMethod::projection;
    UnsteadyFlowSolver s(mmval::test::cylinderChannelProblem(3.0, D / 8, 1.2), {}, o);
    s.setVelocity(vortex);
    ForceHistory hist;
    while (s.time() < 1.4) {
      s.step(0.01);
      const auto L = s.bodyLoads()[0];
      hist.add(s.time(), c * L.force.x(), c * L.force.y());
    }
    st[k] = hist.analyse(0.7, 100);
    if (k == 1) divergence = s.maxRelativeDivergence();
    std::printf("%s: %lld steps, %d periods, St %.5f, c_D mean %.5f, c_L amplitude %.5f\n", k == 0 ? "coupled" : "projection", s.stepStats().steps,
                st[k].periods, st[k].frequency_hz * D / Ubar, st[k].cd_mean, st[k].cl_amplitude);
  }
  ASSERT_GE(st[0].periods, 3);
  ASSERT_GE(st[1].periods, 3);
  EXPECT_NEAR(st[1].frequency_hz / st[0].frequency_hz, 1.0, 3e-3);
  EXPECT_NEAR(st[1].cd_mean / st[0].cd_mean, 1.0, 3e-3);
  EXPECT_NEAR(st[1].cl_amplitude / st[0].cl_amplitude, 1.0, 5e-3);
  EXPECT_LT(divergence, 1e-6);
}

TEST(UnsteadyProjection, RestartFromACheckpointContinuesBitForBit) {
  // The projection step keeps the state and the last pressure change (the checkpoint holds both),
  // so a solver restored after step 17 of 40 must give the uninterrupted run's forces bit for bit.
  const auto make = [] { return std::make_unique<UnsteadyFlowSolver>(mmval::test::cylinderChannelProblem(3.0, 0.1 / 8, 1.2), SolverOptions{}, projection(1.0)); };
  auto whole = make();
  whole->setVelocity(vortex);
  mmval::CheckpointWriter w;
  std::vector<Eigen::Vector2d> a;
  for (int k = 1; k <= 40; ++k) {
    whole->step(0.01);
    a.push_back(whole->bodyLoads()[0].force);
    if (k == 17) whole->saveState(w);
  }
  auto resumed = make();
  mmval::CheckpointReader r(w.bytes(), "in-memory checkpoint");
  resumed->loadState(r);
  for (int k = 18; k <= 40; ++k) {
    resumed->step(0.01);
    const Eigen::Vector2d f = resumed->bodyLoads()[0].force;
    ASSERT_EQ(f.x(), a[static_cast<std::size_t>(k - 1)].x()) << "step " << k;
    ASSERT_EQ(f.y(), a[static_cast<std::size_t>(k - 1)].y()) << "step " << k;
  }
  EXPECT_EQ(resumed->time(), whole->time());
}
