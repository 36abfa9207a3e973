// Rigid bodies moving in creeping flow (ResolvedStokes, the resolved coupling
// mode) against exact Stokes solutions for a cylinder inside a fixed
// concentric cylinder (radii a < b), per unit length:
//   rotation (circular Couette flow):  T = -4 pi mu Omega a^2 b^2 / (b^2 - a^2)
//   translation:                       F = -4 pi mu U / (ln(b/a) - (b^2 - a^2) / (b^2 + a^2))
// (Happel & Brenner, Low Reynolds Number Hydrodynamics, 1965, the concentric-
// cylinder problems of ch. 4; the translation result is the annulus analogue of
// Lamb's 2D drag and tends to 4 pi mu U / (ln(b/a) - 1) for b >> a.)
#include <cmath>
#include <cstdio>
#include <memory>

#include <gtest/gtest.h>

#include "mmval/simulate/ResolvedStokes.hpp"

using namespace mmval::simulate;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Solid outside a circle of radius b about the origin (the fixed outer cylinder).
class Outside final : public Shape {
 public:
  explicit Outside(double b) : m_b(b) {}
  int bodyAt(double x, double y) const override { return x * x + y * y > m_b * m_b ? 0 : -1; }
  int bodies() const override { return 1; }
  Eigen::Vector2d centre(int) const override { return {0, 0}; }

 private:
  double m_b;
};

struct Annulus {
  double a, b, mu = 1e-3;
  int n;  ///< cells across the box [-1.1 b, 1.1 b]
  FlowProblem problem(Eigen::Vector2d centre = {0, 0}) const {
    FlowProblem p;
    const double L = 1.1 * b;
    p.x = uniformAxis(-L, L, n);
    p.y = uniformAxis(-L, L, n);
    p.viscosity = mu;
    p.shape = std::make_shared<ShapeUnion>(std::vector<std::shared_ptr<const Shape>>{
        std::make_shared<Circles>(std::vector<Circle>{{centre.x(), centre.y(), a}}), std::make_shared<Outside>(b)});
    return p;
  }
  double torquePerSpin() const { return -4 * kPi * mu * a * a * b * b / (b * b - a * a); }
  double forcePerVelocity() const { return -4 * kPi * mu / (std::log(b / a) - (b * b - a * a) / (b * b + a * a)); }
};

}  // namespace

TEST(ResolvedStokes, RotatingCylinderTorqueMatchesCouetteFlow) {
  const Annulus A{25e-6, 50e-6, 1e-3, 96};  // 17 cells across the inner diameter
  ResolvedStokes s(A.problem());
  const std::vector<BodyLoad> L = s.loads({RigidMotion{{0, 0}, 2.0}, RigidMotion{}}, 0.0);
  const double exact = A.torquePerSpin() * 2.0;
  std::printf("rotating cylinder: torque / Couette = %.5f\n", L[0].torque / exact);
  // Second-order sharp boundary on both circles: 1 % at 17 cells per inner diameter (measured below).
  EXPECT_NEAR(L[0].torque / exact, 1.0, 0.01) << L[0].torque << " vs " << exact;
  // No net force on a spinning centred cylinder; the outer cylinder takes the opposite torque.
  EXPECT_LT(L[0].force.norm() * A.a, 1e-3 * std::abs(exact));
  EXPECT_NEAR(L[1].torque / -L[0].torque, 1.0, 0.01);
}

TEST(ResolvedStokes, TranslatingCylinderDragMatchesAnnulusSolution) {
  const Annulus A{20e-6, 60e-6, 1e-3, 96};
  ResolvedStokes s(A.problem());
  const double U = 1e-3;
  const std::vector<BodyLoad> L = s.loads({RigidMotion{{U, 0}, 0}, RigidMotion{}}, 0.0);
  const double exact = A.forcePerVelocity() * U;
  std::printf("translating cylinder: force / annulus solution = %.5f\n", L[0].force.x() / exact);
  EXPECT_NEAR(L[0].force.x() / exact, 1.0, 0.01) << L[0].force.x() << " vs " << exact;
  EXPECT_LT(std::abs(L[0].force.y()), 1e-3 * std::abs(exact));
  // Action and reaction through the fluid: the outer cylinder is pulled along with the same force.
  EXPECT_NEAR(L[1].force.x() / -L[0].force.x(), 1.0, 0.01);
}

TEST(ResolvedStokes, FreeCylinderSettlesAtTheVelocityOfItsDrag) {
  const Annulus A{20e-6, 60e-6, 1e-3, 96};
  ResolvedStokes s(A.problem());
  const double F = 1e-7;  // N/m along -y, e.g. buoyant weight per unit length
  const MobilityResult r = s.freeMotion({BodyLoad{{0, -F}, 0}, BodyLoad{}}, {true, false});
  const double exact = -F / A.forcePerVelocity();  // negative: F_drag = R U balances -F
  EXPECT_NEAR(r.motion[0].velocity.y() / -exact, 1.0, 0.01) << r.motion[0].velocity.y();
  EXPECT_LT(std::abs(r.motion[0].velocity.x()), 1e-3 * std::abs(exact));
  EXPECT_LT(std::abs(r.motion[0].spin) * A.a, 1e-3 * std::abs(exact));
  // The fixed outer body stays at rest; four solves, one factorisation.
  EXPECT_EQ(r.motion[1].velocity.norm(), 0.0);
  EXPECT_EQ(r.factorisations, 1);
}

TEST(ResolvedStokes, AccurateOnEveryGrid) {
  // Translation drag over three grids (7, 13 and 27 cells per inner diameter). Measured with the cut
  // cells merged: 0.77 / 0.076 / 0.016 %, falling at every step (kept separate the error was not
  // monotone, 0.53 / 0.018 / 0.052 %: it depended on where the circles cut the cells).
  double prev = 1;
  for (int n : {48, 96, 192}) {
    const Annulus A{20e-6, 60e-6, 1e-3, n};
    ResolvedStokes s(A.problem());
    const double f = s.loads({RigidMotion{{1e-3, 0}, 0}, RigidMotion{}}, 0.0)[0].force.x();
    const double err = std::abs(f / (A.forcePerVelocity() * 1e-3) - 1);
    std::printf("annulus n %d: drag error %.3e\n", n, err);
    EXPECT_LT(err, n == 48 ? 1e-2 : 1e-3) << n;
    EXPECT_LT(err, 0.5 * prev) << n << ": the error falls with the grid";
    prev = err;
  }
}

TEST(ResolvedStokes, CylinderBetweenPlatesMatchesFaxen) {
  // A cylinder moving midway between two plates 2 l apart in fluid at rest (closed box 16 l long:
  // the disturbance decays like exp(-pi |x| / l)). Faxen's series, as quoted by Happel & Brenner:
  //   F = -4 pi mu U / (ln(l/a) - 0.9157 + 1.7244 k^2 - 1.7302 k^4 + 2.4056 k^6 - 4.5913 k^8), k = a/l.
  // At k = 0.25 we measured 0.9958 of it with 16 cells per diameter; bench_simulate_resolved gives the
  // settling velocity at 1.0165 / 1.0055 / 1.0042 / 1.0014 / 1.0011 of Faxen's with 8 / 12 / 16 / 24 / 32.
  // (At k = 0.5 the solver stays ~5 % from the series; the series is truncated at k^8 and we have no
  // independent value there, so the test stays at k = 0.25.)
  const double l = 50e-6, a = 0.25 * l, mu = 1e-3, U = 1e-3, k = a / l;
  const double h = 2 * a / 16;
  FlowProblem p;
  p.x = uniformAxis(-8 * l, 8 * l, static_cast<int>(std::lround(16 * l / h)));
  p.y = uniformAxis(-l, l, static_cast<int>(std::lround(2 * l / h)));
  p.viscosity = mu;
  p.shape = std::make_shared<Circles>(std::vector<Circle>{{0, 0, a}});
  ResolvedStokes s(p);
  const BodyLoad L = s.loads({RigidMotion{{U, 0}, 0}}, 0.0)[0];
  const double faxen = -4 * kPi * mu * U /
                       (std::log(l / a) - 0.9157 + 1.7244 * k * k - 1.7302 * std::pow(k, 4) + 2.4056 * std::pow(k, 6) - 4.5913 * std::pow(k, 8));
  std::printf("cylinder between plates: force / Faxen = %.5f\n", L.force.x() / faxen);
  EXPECT_NEAR(L.force.x() / faxen, 1.0, 5e-3) << L.force.x() << " vs " << faxen;
  // Midway between the plates nothing pushes it sideways or turns it.
  EXPECT_LT(std::abs(L.force.y()), 1e-3 * std::abs(faxen));
  EXPECT_LT(std::abs(L.torque), 1e-3 * std::abs(faxen) * a);
}
