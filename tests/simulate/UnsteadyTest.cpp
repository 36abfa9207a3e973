// Unsteady Navier-Stokes (UnsteadyFlowSolver, BDF2) on 1 MPI rank: temporal
// accuracy against the exact start-up of plane Poiseuille flow, the Courant
// limit on requested steps, the divergence guard, shedding behind a
// cylinder at Re 200 on a coarse grid for 20 periods (no blow-up, no NaN), and
// the body force against a control-volume momentum balance around the body,
// and a checkpoint restart that continues bit for bit.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "CylinderChannelProblem.hpp"

#include "mmval/core/Checkpoint.hpp"
#include "mmval/simulate/ForceHistory.hpp"
#include "mmval/simulate/UnsteadyFlowSolver.hpp"

using namespace mmval::simulate;

namespace {

constexpr double kW = 1e-3, kMu = 1e-3, kRho = 1000, kG = 10;  // m, Pa s, kg/m3, N/m3

/// Periodic channel of width kW driven from rest by the body force kG.
FlowProblem startupProblem(int ny) {
  FlowProblem p;
  p.x = uniformAxis(0, kW, 4);
  p.y = uniformAxis(0, kW, ny);
  p.boundary[0].type = p.boundary[1].type = BoundaryType::periodic;
  p.density = kRho;
  p.viscosity = kMu;
  p.body_force = {kG, 0};
  return p;
}

/// Exact start-up flow u(y, t) = G/(2 mu) y (W - y) - sum_odd 4 G W^2 / (mu pi^3 n^3) sin(n pi y / W) exp(-n^2 pi^2 nu t / W^2).
double startupExact(double y, double t) {
  const double nu = kMu / kRho;
  double u = kG / (2 * kMu) * y * (kW - y);
  for (int n = 1; n < 400; n += 2)
    u -= 4 * kG * kW * kW / (kMu * std::pow(M_PI * n, 3)) * std::sin(n * M_PI * y / kW) * std::exp(-n * n * M_PI * M_PI * nu * t / (kW * kW));
  return u;
}

/// u at the channel centre-row faces after t_end with a fixed step.
Eigen::ArrayXd startupProfile(int ny, double dt, double t_end) {
  UnsteadyFlowSolver s(startupProblem(ny));
  const int n = static_cast<int>(std::lround(t_end / dt));
  for (int k = 0; k < n; ++k) EXPECT_EQ(s.advance(dt), 1);
  Eigen::ArrayXXd u, v, p;
  s.fields(u, v, p);
  return u.col(0);
}

/// Box of whole cells [i0, i1) x [j0, j1) for the control-volume momentum balance.
struct CellBox {
  int i0, i1, j0, j1;
};

/// Momentum of the fluid in the box, kg m/s per unit depth (cell-averaged MAC velocities).
Eigen::Vector2d boxMomentum(const FlowProblem& pr, const Eigen::ArrayXXd& u, const Eigen::ArrayXXd& v, const CellBox& b) {
  Eigen::Vector2d m(0, 0);
  for (int j = b.j0; j < b.j1; ++j)
    for (int i = b.i0; i < b.i1; ++i) {
      const double area = pr.x.width(i) * pr.y.width(j);
      m += pr.density * area * Eigen::Vector2d(0.5 * (u(j, i) + u(j, i + 1)), 0.5 * (v(j, i) + v(j + 1, i)));
    }
  return m;
}

/// Momentum the box's faces let in per unit time and depth, N/m: - oint (rho u (u.n) + p n - mu du/dn) dS,
/// written from the fields alone (face values interpolated linearly, gradients centred), independently of
/// the solver's residual rows.
Eigen::Vector2d boxInflux(const FlowProblem& pr, const Eigen::ArrayXXd& u, const Eigen::ArrayXXd& v, const Eigen::ArrayXXd& p, const CellBox& b) {
  const Axis& X = pr.x;
  const Axis& Y = pr.y;
  const double rho = pr.density, mu = pr.viscosity;
  Eigen::Vector2d s(0, 0);
  for (const int side : {0, 1}) {  // west, east faces x = const
    const int i = side == 0 ? b.i0 : b.i1;
    const double n = side == 0 ? -1.0 : 1.0, dc = X.centre(i) - X.centre(i - 1), w = (X.face(i) - X.centre(i - 1)) / dc;
    for (int j = b.j0; j < b.j1; ++j) {
      const double pf = (1 - w) * p(j, i - 1) + w * p(j, i);
      const double dudx = (u(j, i + 1) - u(j, i - 1)) / (X.face(i + 1) - X.face(i - 1));
      double vf = 0, dvdx = 0;
      for (const int jj : {j, j + 1}) {
        vf += 0.5 * ((1 - w) * v(jj, i - 1) + w * v(jj, i));
        dvdx += 0.5 * (v(jj, i) - v(jj, i - 1)) / dc;
      }
      const double un = n * u(j, i);
      s += Y.width(j) * Eigen::Vector2d(-rho * u(j, i) * un - n * pf + mu * n * dudx, -rho * vf * un + mu * n * dvdx);
    }
  }
  for (const int side : {0, 1}) {  // south, north faces y = const
    const int j = side == 0 ? b.j0 : b.j1;
    const double n = side == 0 ? -1.0 : 1.0, dc = Y.centre(j) - Y.centre(j - 1), w = (Y.face(j) - Y.centre(j - 1)) / dc;
    for (int i = b.i0; i < b.i1; ++i) {
      const double pf = (1 - w) * p(j - 1, i) + w * p(j, i);
      const double dvdy = (v(j + 1, i) - v(j - 1, i)) / (Y.face(j + 1) - Y.face(j - 1));
      double uf = 0, dudy = 0;
      for (const int ii : {i, i + 1}) {
        uf += 0.5 * ((1 - w) * u(j - 1, ii) + w * u(j, ii));
        dudy += 0.5 * (u(j, ii) - u(j - 1, ii)) / dc;
      }
      const double vn = n * v(j, i);
      s += X.width(i) * Eigen::Vector2d(-rho * uf * vn + mu * n * dudy, -rho * v(j, i) * vn - n * pf + mu * n * dvdy);
    }
  }
  return s;
}

}  // namespace

TEST(Unsteady, BodyForceMatchesControlVolumeMomentumBalance) {
  // The force on the cylinder from the residual rows (bodyLoads) against the momentum balance of a
  // box of fluid around it, F = -d/dt int rho u dV - oint (rho u u.n + p n - mu du/dn) dS, written
  // from the fields alone with the BDF2 derivative of the box momentum. Re 100 (U_max 1.5 m/s),
  // h = D/10, a vortex behind the cylinder so that lift and d/dt are both large from the start.
  // A lift missing the unsteady term, the pressure inside the body or with wrong y-face signs or
  // areas fails by 30-100 % of the lift (the d/dt part alone is 0.1-0.25 in c_L, 0.7 in c_D at the
  // start); the two forms differ by the box integral's O(h^2) truncation where the box cuts the young
  // wake (measured here: c_L within 1 %, c_D within 2.4 %; on a D/10 Schaefer-Turek 2D-2 run in its
  // periodic state c_L max 0.6652 against 0.6639, c_D 0.2 %).
  const double D = 0.1, Ubar = 1.0, c = 2 / (Ubar * Ubar * D);
  const FlowProblem pr = mmval::test::cylinderChannelProblem(1.5, D / 10, 1.0);
  UnsteadyFlowSolver s(pr);
  s.setVelocity([](double x, double y) {
    const double X = (x - 0.35) / 0.1, Y = (y - 0.2) / 0.1, g = 0.35 * std::exp(-(X * X + Y * Y));
    return Eigen::Vector2d(-Y * g, X * g);
  });
  const CellBox box{pr.x.cellOf(0.13), pr.x.cellOf(0.29), pr.y.cellOf(0.12), pr.y.cellOf(0.28)};
  Eigen::ArrayXXd u, v, p;
  Eigen::Vector2d m1(0, 0), m2(0, 0);
  double dt1 = 0, worst_cd = 0, worst_cl = 0, max_cl = 0, max_unsteady_cl = 0;
  for (int k = 0; k < 60; ++k) {
    const double dt = s.step(0.01);
    s.fields(u, v, p);
    const Eigen::Vector2d m = boxMomentum(pr, u, v, box);
    if (k >= 2) {  // BDF2 with the solver's variable step, as the solver integrates
      const double w = dt / dt1, a0 = (1 + 2 * w) / (1 + w), a1 = 1 + w, a2 = w * w / (1 + w);
      const Eigen::Vector2d dmdt = (a0 * m - a1 * m1 + a2 * m2) / dt;
      const Eigen::Vector2d cv = c * (-dmdt + boxInflux(pr, u, v, p, box));
      const Eigen::Vector2d res = c * s.bodyLoads()[0].force;
      worst_cd = std::max(worst_cd, std::abs(res.x() - cv.x()) / std::abs(res.x()));
      worst_cl = std::max(worst_cl, std::abs(res.y() - cv.y()));
      max_cl = std::max(max_cl, std::abs(res.y()));
      max_unsteady_cl = std::max(max_unsteady_cl, std::abs(c * dmdt.y()));
    }
    m2 = m1;
    m1 = m;
    dt1 = dt;
  }
  std::printf("residual vs control volume: c_D rel %.2e, c_L abs %.2e (max |c_L| %.3f, max |d/dt| part %.3f), t = %.3f s\n", worst_cd, worst_cl,
              max_cl, max_unsteady_cl, s.time());
  EXPECT_LT(worst_cd, 0.035);
  EXPECT_LT(worst_cl, 0.03 * max_cl);
  EXPECT_GT(max_unsteady_cl, 0.2 * max_cl);  // the check is sensitive to a missing d/dt term
}

TEST(Unsteady, StartupPoiseuilleIsSecondOrderInTime) {
  // t = 0.05 W^2 / nu: the start-up is still far from steady (u_centre ~ 60 % of its final value).
  const int ny = 16;
  const double t_end = 0.05 * kW * kW * kRho / kMu, dt = t_end / 10;
  const Eigen::ArrayXd u1 = startupProfile(ny, dt, t_end), u2 = startupProfile(ny, dt / 2, t_end), u4 = startupProfile(ny, dt / 4, t_end);
  const double e1 = (u1 - u2).abs().maxCoeff(), e2 = (u2 - u4).abs().maxCoeff();
  const double order = std::log2(e1 / e2);
  std::printf("start-up: successive differences %.3e %.3e, observed order %.3f\n", e1, e2, order);
  EXPECT_NEAR(order, 2.0, 0.25) << "successive differences " << e1 << " " << e2;  // BDF2 (first step Euler: O(dt^2) overall)
  // Against the exact solution: the remaining error is the O(h^2) spatial one of the
  // 3-point Laplacian on 16 cells (u'''' h^2 / 12 relative ~ 0.3 %); tolerance 1 % of the peak.
  const double umax = kG * kW * kW / (8 * kMu);
  double err = 0;
  for (int j = 0; j < ny; ++j) err = std::max(err, std::abs(u4(j) - startupExact((j + 0.5) * kW / ny, t_end)));
  std::printf("start-up: max error against the exact series %.3e of the peak\n", err / umax);
  EXPECT_LT(err / umax, 0.01) << "max error " << err << " m/s of peak " << umax;
}

TEST(Unsteady, RequestedStepAboveCourantLimitIsSubdivided) {
  UnsteadyOptions o;
  o.max_courant = 0.8;
  UnsteadyFlowSolver s(mmval::test::cylinderChannelProblem(0.3, 0.02, 1.0), {}, o);
  const double stable = s.stableTimeStep();
  ASSERT_TRUE(std::isfinite(stable));
  const int steps = s.advance(20 * stable);  // far above the limit
  EXPECT_GT(steps, 20);
  EXPECT_NEAR(s.time(), 20 * stable, 1e-12 * stable);
  EXPECT_EQ(s.stepStats().reduced_steps, 1);
  EXPECT_NE(s.stepStats().warning.find("Courant"), std::string::npos) << s.stepStats().warning;
  EXPECT_LE(s.stepStats().max_courant, 0.8 * (1 + 1e-9));
  EXPECT_TRUE(std::isfinite(s.maxVelocity()));
  EXPECT_LT(s.maxRelativeDivergence(), 1e-8);
  EXPECT_THROW(s.advance(-1.0), std::invalid_argument);
  EXPECT_THROW(s.advance(std::nan("")), std::invalid_argument);
}

TEST(Unsteady, SolidCanBeInsertedBetweenSteps) {
  // Coupling-loop use: empty channel for 10 steps, then the cylinder appears. The drag is zero
  // before (no body) and positive after; the flow stays divergence-free.
  FlowProblem p = mmval::test::cylinderChannelProblem(0.3, 0.02, 1.0);
  const auto cylinder = p.shape;
  p.shape = nullptr;
  UnsteadyFlowSolver s(p);
  for (int k = 0; k < 10; ++k) s.step(0.05);
  EXPECT_TRUE(s.bodyLoads().empty());
  s.setShape(cylinder);
  for (int k = 0; k < 10; ++k) s.step(0.05);
  ASSERT_EQ(s.bodyLoads().size(), 1U);
  EXPECT_GT(s.bodyLoads()[0].force.x(), 0);
  EXPECT_LT(s.maxRelativeDivergence(), 1e-8);
}

TEST(Unsteady, DivergenceGuardThrowsAndKeepsTheLastGoodState) {
  // A guard at 1.05 x the inflow peak trips as soon as the flow accelerates past the cylinder:
  // the solver must refuse with a message (a FlowFailure: exit 5 once the kind names its key),
  // not return the offending state.
  UnsteadyOptions o;
  o.blowup_factor = 1.05;
  UnsteadyFlowSolver s(mmval::test::cylinderChannelProblem(0.3, 0.02, 1.0), {}, o);
  bool threw = false;
  for (int k = 0; k < 200 && !threw; ++k) {
    const double t = s.time();
    try {
      s.step(1e-2);
    } catch (const FlowFailure& e) {  // a NumericalFailure (exit 5), not a bug (exit 4)
      threw = true;
      EXPECT_NE(std::string(e.what()).find("diverged"), std::string::npos) << e.what();
      EXPECT_TRUE(e.key().empty());  // the solver knows no case keys; the kind names its own
      const std::string named = e.withKey("numerics.cells_around").what();
      EXPECT_NE(named.find("; change 'numerics.cells_around': refine the grid or lower the Courant limit"), std::string::npos) << named;
      EXPECT_EQ(s.time(), t);
      EXPECT_LE(s.maxVelocity(), 1.05 * 0.3);
    }
  }
  EXPECT_TRUE(threw);
}

TEST(Unsteady, Re200CoarseShedsTwentyPeriodsWithoutBlowUp) {
  // Schaefer-Turek channel at Re = Ubar D / nu = 200 (U_max 3 m/s), h = D/8, Courant 1.
  // Coarse on purpose (cheap): the test asserts stability and sustained shedding, not accuracy.
  const double Umax = 3.0, Ubar = 2.0, D = 0.1;
  UnsteadyFlowSolver s(mmval::test::cylinderChannelProblem(Umax, D / 8, 1.2));
  s.setVelocity([](double x, double y) {  // small vortex behind the cylinder: shedding starts early
    const double X = (x - 0.35) / 0.1, Y = (y - 0.2) / 0.1, g = 0.5 * std::exp(-(X * X + Y * Y));
    return Eigen::Vector2d(-Y * g, X * g);
  });
  ForceHistory hist;
  const double c = 2 / (Ubar * Ubar * D);
  while (s.time() < 4.6) {
    s.step(0.01);
    const auto L = s.bodyLoads()[0];
    ASSERT_TRUE(std::isfinite(L.force.x()) && std::isfinite(L.force.y())) << "t = " << s.time();
    hist.add(s.time(), c * L.force.x(), c * L.force.y());
  }
  const SheddingStats st = hist.analyse(0.9, 100);
  std::printf("Re 200: %lld cells, %lld steps, %d periods, St %.4f, c_D max %.4f, c_L amplitude %.4f\n", s.stats().cells, s.stepStats().steps,
              st.periods, st.frequency_hz * D / Ubar, st.cd_max, st.cl_amplitude);
  EXPECT_GE(st.periods, 20);
  // Confined cylinder at Re 200: St ~ 0.3-0.4 (blockage 0.24 raises it over the free 0.19);
  // a broad physical band, since this grid is coarse.
  const double strouhal = st.frequency_hz * D / Ubar;
  EXPECT_GT(strouhal, 0.2);
  EXPECT_LT(strouhal, 0.5);
  EXPECT_GT(st.cl_amplitude, 0.2);
  EXPECT_LT(s.maxVelocity(), 4 * Umax);
  EXPECT_LT(s.maxRelativeDivergence(), 1e-8);
}

TEST(Unsteady, ForceHistoryStatisticsOfAKnownSignal) {
  // c_L = 0.2 + sin(2 pi f t), c_D = 3.23 + 0.01 sin(4 pi f t + 0.3), f = 3 Hz, sampled at 37 points
  // per period with a start-up ramp before t = 1 s: the frequency is exact to the crossing
  // interpolation (~1e-4), the peaks to the parabolic refinement (~(2 pi / 37)^4 / 24 ~ 4e-5).
  ForceHistory h;
  const double f = 3.0;
  for (int k = 0; k <= 37 * 12; ++k) {
    const double t = k / (37 * f), ramp = std::min(1.0, t);
    h.add(t, 3.23 + 0.01 * std::sin(4 * M_PI * f * t + 0.3), ramp * (0.2 + std::sin(2 * M_PI * f * t)));
  }
  const SheddingStats s = h.analyse(1.0, 4);
  EXPECT_EQ(s.periods, 4);
  EXPECT_NEAR(s.frequency_hz / f, 1.0, 1e-3);
  EXPECT_NEAR(s.cl_max, 1.2, 1e-3);
  EXPECT_NEAR(s.cl_min, -0.8, 1e-3);
  EXPECT_NEAR(s.cd_max, 3.24, 1e-4);
  EXPECT_NEAR(s.cd_mean, 3.23, 1e-4);
  EXPECT_NEAR(s.cl_mean, 0.2, 2e-3);
  EXPECT_NEAR(s.cl_amplitude_drift, 0.0, 1e-3);  // periodic
  // A start-up that has not saturated: amplitude 1 - 0.5 exp(-t / tau), tau = 4 periods; the last whole
  // period (centred near 11.5 periods) is ~0.8 % larger than the one before.
  ForceHistory g;
  for (int k = 0; k <= 37 * 12; ++k) {
    const double t = k / (37 * f), a = 1 - 0.5 * std::exp(-t * f / 4);
    g.add(t, 3.23, a * std::sin(2 * M_PI * f * t));
  }
  const SheddingStats gs = g.analyse(1.0, 4);
  EXPECT_GT(gs.cl_amplitude_drift, 0.005);
  EXPECT_LT(gs.cl_amplitude_drift, 0.05);
  // No oscillation: no periods, extrema over the window.
  ForceHistory flat;
  for (int k = 0; k < 10; ++k) flat.add(k * 0.1, 1.0, 0.0);
  EXPECT_EQ(flat.analyse(0.0).periods, 0);
}

TEST(Unsteady, RestartFromACheckpointContinuesBitForBit) {
  // Re 200 shedding on the coarse grid of Re200CoarseShedsTwentyPeriodsWithoutBlowUp, 90 steps
  // (the lagged LU is refactorised along the way). A second solver restored from a checkpoint taken
  // after a random step must give the same forces, time and fields as the uninterrupted one, bit
  // for bit: the resumed run rebuilds the lagged LU from the same matrices (a plain refactorisation
  // at the restart moved c_L by ~1e-9 within 20 steps and ~0.5 % after a few periods).
  // The step is random; MMVAL_RESUME_SEED=<seed> replays a failure.
  const char* env = std::getenv("MMVAL_RESUME_SEED");
  const unsigned seed = env != nullptr ? static_cast<unsigned>(std::strtoul(env, nullptr, 10)) : std::random_device{}();
  const int total = 90;
  std::mt19937 gen(seed);
  const int stop = std::uniform_int_distribution<int>(1, total - 1)(gen);
  std::printf("restart after step %d of %d (MMVAL_RESUME_SEED=%u)\n", stop, total, seed);
  const auto vortex = [](double x, double y) {
    const double X = (x - 0.35) / 0.1, Y = (y - 0.2) / 0.1, g = 0.5 * std::exp(-(X * X + Y * Y));
    return Eigen::Vector2d(-Y * g, X * g);
  };
  const auto makeSolver = [&] { return std::make_unique<UnsteadyFlowSolver>(mmval::test::cylinderChannelProblem(3.0, 0.1 / 8, 1.2)); };
  struct Sample {
    double t, fx, fy;
  };
  const auto sample = [](const UnsteadyFlowSolver& s) {
    const auto L = s.bodyLoads()[0];
    return Sample{s.time(), L.force.x(), L.force.y()};
  };
  auto whole = makeSolver();
  whole->setVelocity(vortex);
  std::vector<Sample> a;
  mmval::CheckpointWriter w;
  for (int k = 1; k <= total; ++k) {
    whole->step(0.01);
    a.push_back(sample(*whole));
    if (k == stop) whole->saveState(w);
  }
  auto resumed = makeSolver();  // no initial condition: everything comes from the checkpoint
  mmval::CheckpointReader r(w.bytes(), "in-memory checkpoint");
  resumed->loadState(r);
  ASSERT_EQ(resumed->stepStats().steps, stop);
  std::vector<Sample> b(a.begin(), a.begin() + stop);
  for (int k = stop + 1; k <= total; ++k) {
    resumed->step(0.01);
    b.push_back(sample(*resumed));
  }
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = static_cast<std::size_t>(stop); k < a.size(); ++k) {
    // Bit for bit: compare the representations, not within a tolerance.
    ASSERT_EQ(std::memcmp(&a[k], &b[k], sizeof(Sample)), 0) << "step " << k + 1 << ": t " << a[k].t << " / " << b[k].t << ", F_x " << a[k].fx << " / "
                                                            << b[k].fx << " (difference " << b[k].fx - a[k].fx << "), F_y " << a[k].fy << " / " << b[k].fy
                                                            << " (difference " << b[k].fy - a[k].fy << ")";
  }
  Eigen::ArrayXXd u1, v1, p1, u2, v2, p2;
  whole->fields(u1, v1, p1);
  resumed->fields(u2, v2, p2);
  EXPECT_EQ((u1 != u2).count() + (v1 != v2).count() + (p1 != p2).count(), 0);
  std::printf("after step %d: t %.17g s, F_y %.17g N/m in both runs\n", total, a.back().t, a.back().fy);
}
