// The image's edge in a mask shape (MaskShape, SmoothMaskShape): the permeability kinds solve on
// a domain exactly the image, so the inlet's and outlet's face nodes lie on x = 0 and x = width.
// A point on the edge must read the edge pixel: MaskShape read the pixel beyond the outlet
// (outside the image, fluid), so a wall or grain touching the outlet had open outlet faces and the
// sharp solve's cut stencils there saw no wall (1 % more flux through an 8-cell channel).
//
// Reference: a channel between solid walls 4 pixels thick that run the whole image length (so
// they touch inlet and outlet), walls on cell faces at 1 and 2 cells per pixel. The sharp
// method's cut stencil gives the fully developed discrete profile exactly (PressureComponentTest):
// q_h = G (H^3 + 2 h^2 H) / (12 mu), h the cell size. With the edge read right the flow is fully
// developed from inlet to outlet and the solve gives q_h to rounding (1e-9 relative); the smooth
// boundary keeps a pixel-aligned wall on its pixel edge (ImageLadderTest), so it gives q_h too.
#include <gtest/gtest.h>

#include <memory>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"

namespace mmval::simulate {
namespace {

using Mask = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>;

constexpr double kPixel = 10e-6, kMu = 1e-3, kDp = 1.0;  // m, Pa s, Pa
constexpr int kRows = 16, kCols = 24, kWall = 4;          // pixels: an 8-pixel channel

Mask channel() {
  Mask m = Mask::Constant(kRows, kCols, false);
  m.topRows(kWall).setConstant(true);
  m.bottomRows(kWall).setConstant(true);
  return m;
}

double flux(std::shared_ptr<const Shape> shape, int cpp) {
  FlowProblem p;
  p.x = uniformAxis(0, kCols * kPixel, kCols * cpp);
  p.y = uniformAxis(0, kRows * kPixel, kRows * cpp);
  p.viscosity = kMu;
  p.shape = std::move(shape);
  p.method = ImmersedMethod::sharp;
  p.boundary[0].type = p.boundary[1].type = BoundaryType::pressure;
  p.boundary[0].pressure = kDp;
  p.boundary[2].type = p.boundary[3].type = BoundaryType::slip;
  SteadyFlowSolver s(p);
  s.solve();
  EXPECT_NEAR(s.flowRate(Side::west), s.flowRate(Side::east), 1e-9 * std::abs(s.flowRate(Side::east)));
  return s.flowRate(Side::east);
}

double discretePoiseuille(int cpp) {
  const double G = kDp / (kCols * kPixel), H = (kRows - 2 * kWall) * kPixel, h = kPixel / cpp;
  return G * (H * H * H + 2 * h * h * H) / (12 * kMu);
}

TEST(MaskEdge, PointsOnTheImageEdgeReadTheEdgePixels) {
  const MaskShape m(channel(), kPixel);
  const SmoothMaskShape s(channel(), kPixel, 0.75);
  const double W = kCols * kPixel, wall = 2 * kPixel, pore = 8 * kPixel;  // y of a wall row and of the channel's middle
  for (const Shape* shape : {static_cast<const Shape*>(&m), static_cast<const Shape*>(&s)}) {
    EXPECT_EQ(shape->bodyAt(W, wall), 0);  // the outlet's edge, in a wall row: solid
    EXPECT_EQ(shape->bodyAt(0, wall), 0);  // the inlet's
    EXPECT_EQ(shape->bodyAt(W, pore), -1);
    EXPECT_EQ(shape->bodyAt(W + 0.5 * kPixel, wall), -1);  // beyond the image: fluid, as before
    EXPECT_EQ(shape->bodyAt(-0.5 * kPixel, wall), -1);
    // From the channel's middle on the outlet edge, the wall is 4 pixels away across the flow.
    EXPECT_NEAR(shape->distanceAlong(W, pore, 1, -1, 10 * kPixel), 4 * kPixel, 1e-9 * kPixel);
  }
}

TEST(MaskEdge, WallsTouchingInletAndOutletCarryTheDiscretePoiseuilleFlux) {
  for (const int cpp : {1, 2}) {
    const double q_h = discretePoiseuille(cpp);
    EXPECT_NEAR(flux(std::make_shared<MaskShape>(channel(), kPixel), cpp), q_h, 1e-9 * q_h) << "pixels, " << cpp << " cells per pixel";
    EXPECT_NEAR(flux(std::make_shared<SmoothMaskShape>(channel(), kPixel, 0.75), cpp), q_h, 1e-9 * q_h)
        << "smooth, " << cpp << " cells per pixel";
  }
}

}  // namespace
}  // namespace mmval::simulate
