// Smooth grain walls (geometry.boundary = "smooth" of the particles-micromodel kind): the
// particles see the grains as the contour of simulate::SmoothMaskShape, the boundary the fluid
// solve cuts against, not the pixel staircase. References: a rasterised disc against the exact
// circle (distance and normal), a 45 degree staircase against its straight line (no notches left),
// the fluid solve against the same solver fed the SmoothMaskShape directly (the image-permeability
// kind's smooth problem), and the default ("pixels") unchanged.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>

#include "mmval/particles/FlowField.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/Grid.hpp"

namespace mmval::particles {
namespace {

constexpr double kPixel = 10e-6;
constexpr double kDepth = 20e-6;
constexpr double kPi = 3.14159265358979323846;

MicromodelFlowOptions options(bool smooth, double cells_per_pixel = 0.5) {
  MicromodelFlowOptions o;
  o.pixel = kPixel;
  o.depth = kDepth;
  o.cells_per_pixel = cells_per_pixel;
  o.darcy_velocity = 1e-4;
  o.smooth_walls = smooth;
  return o;
}

/// Pixels whose centres lie within `radius` px of (cx, cy) px (x along columns, y up from the bottom edge).
PixelMask disc(int rows, int cols, double cx, double cy, double radius) {
  PixelMask m = PixelMask::Constant(rows, cols, false);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) m(r, c) = std::hypot(c + 0.5 - cx, rows - r - 0.5 - cy) < radius;
  return m;
}

struct RingErrors {
  double max_distance = 0, rms_distance = 0, max_angle_deg = 0, rms_angle_deg = 0;
};

/// Wall distance and normal of `f` at n points on the circle of radius r_px about (cx, cy) px
/// against the exact disc of radius R_px: distance r - R, normal radial.
RingErrors ringErrors(const FlowField& f, double cx, double cy, double R_px, double r_px, int n) {
  RingErrors e;
  double sum2 = 0, angle2 = 0;
  for (int k = 0; k < n; ++k) {
    const double a = 2 * kPi * (k + 0.5) / n;
    const Vec2 radial(std::cos(a), std::sin(a));
    const double x = (cx + r_px * radial.x()) * kPixel, y = (cy + r_px * radial.y()) * kPixel;
    const double err = std::abs(f.wallDistance(x, y) - (r_px - R_px) * kPixel) / kPixel;
    e.max_distance = std::max(e.max_distance, err);
    sum2 += err * err;
    const double c = std::clamp(f.wallNormal(x, y).dot(radial), -1.0, 1.0);
    e.max_angle_deg = std::max(e.max_angle_deg, std::acos(c) * 180 / kPi);
    angle2 += std::pow(std::acos(c) * 180 / kPi, 2);
  }
  e.rms_distance = std::sqrt(sum2 / n);
  e.rms_angle_deg = std::sqrt(angle2 / n);
  return e;
}

/// Distance (px) from the fluid point p (px) to the level set {level > 0} of `shape`, by brute
/// force: the first crossing along rays from p (marched by 1/32 px, bisected to 1e-12 px), the
/// least over 360 rays, then refined over rays in shrinking windows about the best; `dir` gets the
/// unit vector from the nearest point to p. Independent of the contour's marching squares.
double levelDistance(const std::function<double(double, double)>& level, const Vec2& p, double max_px, Vec2& dir) {
  const auto first = [&](double a) {
    const Vec2 e(std::cos(a), std::sin(a));
    const auto lv = [&](double t) { return level((p.x() + t * e.x()) * kPixel, (p.y() + t * e.y()) * kPixel); };
    for (double t = 0; t < max_px; t += 1.0 / 32) {
      if (lv(t + 1.0 / 32) > 0) {
        double lo = t, hi = t + 1.0 / 32;
        for (int it = 0; it < 40; ++it) (lv(0.5 * (lo + hi)) > 0 ? hi : lo) = 0.5 * (lo + hi);
        return 0.5 * (lo + hi);
      }
    }
    return 1e300;
  };
  double best = 1e300, best_a = 0;
  for (int k = 0; k < 360; ++k) {
    const double a = 2 * kPi * k / 360, d = first(a);
    if (d < best) best = d, best_a = a;
  }
  for (double w = 2 * kPi / 360; w > 1e-7; w /= 8)
    for (int k = -10; k <= 10; ++k) {
      const double a = best_a + w * k / 10, d = first(a);
      if (d < best) best = d, best_a = a;
    }
  dir = -Vec2(std::cos(best_a), std::sin(best_a));
  return best;
}

double levelDistance(const simulate::SmoothMaskShape& shape, const Vec2& p, double max_px, Vec2& dir) {
  return levelDistance([&](double x, double y) { return shape.level(x, y); }, p, max_px, dir);
}

// The particles' walls are the SmoothMaskShape's level set itself: at points near a disc's
// boundary, wallDistance against the brute-force distance to {level > 0}, wallNormal against the
// direction from its nearest point, isSolid against the level's sign. The contour is made of
// chords between crossings a quarter pixel apart (samples_per_cell 4): their sagitta L^2 / (8 rho)
// is 1e-3 px for L = 0.35 px on a curve of radius rho = 15 px, and ~0.02 px where the level's
// digitisation ripple bends it to rho ~ 1 px; tolerance 0.02 px on the distance, 6 degrees on the
// normal (a chord's direction against the curve's tangent at its nearest point: L / (2 rho) for
// rho >= 1.7 px), at 1 to 2.5 px from the wall, where particles touch it. Measured: 0.0055 px,
// 4.2 degrees.
TEST(SmoothWalls, ContourIsTheSmoothMaskLevel) {
  const int N = 64;
  const double cx = 32.2, cy = 31.7, R = 17.3;
  const PixelMask m = disc(N, N, cx, cy, R);
  MicromodelFlow smooth(m, options(true));
  ASSERT_FALSE(smooth.solve({}).blocked);
  const simulate::SmoothMaskShape shape(m, kPixel, 0.75);
  const FlowField& f = *smooth.field();
  double worst_d = 0, worst_a = 0;
  for (int k = 0; k < 120; ++k) {
    const double a = 2 * kPi * (k + 0.31) / 120, r = R + 1.0 + 1.5 * ((k * 7) % 11) / 10.0;
    const Vec2 p(cx + r * std::cos(a), cy + r * std::sin(a));
    Vec2 dir;
    const double d = levelDistance(shape, p, 4.0, dir);
    ASSERT_FALSE(f.isSolid(p.x() * kPixel, p.y() * kPixel)) << k;
    worst_d = std::max(worst_d, std::abs(f.wallDistance(p.x() * kPixel, p.y() * kPixel) / kPixel - d));
    worst_a = std::max(worst_a, std::acos(std::clamp(f.wallNormal(p.x() * kPixel, p.y() * kPixel).dot(dir), -1.0, 1.0)) * 180 / kPi);
  }
  std::printf("contour vs level set: distance within %.5f px, normal within %.3f deg\n", worst_d, worst_a);
  EXPECT_LT(worst_d, 0.02);
  EXPECT_LT(worst_a, 6.0);
  // Solid exactly where the level is positive (points off the level by more than round-off).
  int checked = 0;
  for (int k = 0; k < 4000; ++k) {
    const double a = 2 * kPi * k / 4000, r = R - 1.0 + 2.0 * ((k * 37) % 101) / 100.0;
    const double x = (cx + r * std::cos(a)) * kPixel, y = (cy + r * std::sin(a)) * kPixel, lv = shape.level(x, y);
    if (std::abs(lv) < 1e-9) continue;
    ++checked;
    EXPECT_EQ(smooth.field()->isSolid(x, y), lv > 0) << k;
  }
  EXPECT_GT(checked, 3900);
}

// Mirror sides (geometry.sides = "slip"): a grain cut by the bottom edge y = 0 continues as its
// mirror image beyond it, and so does its smooth boundary. Reference: the brute-force distance
// to {level(x, |y|) > 0} (the level mirrored across the plane, no wall on it) from points within
// 2 px of the plane beside the grain's cut and in the open pore; same tolerances as above. Points
// nearer the plane than the grain would read their height if the plane were a wall.
TEST(SmoothWalls, MirrorSidesSeeTheMirroredContour) {
  const int rows = 30, cols = 60;
  const PixelMask m = disc(rows, cols, 30.3, 2.4, 7.2);
  MicromodelFlowOptions o = options(true);
  o.mirror_sides = true;
  MicromodelFlow f(m, o);
  ASSERT_FALSE(f.solve({}).blocked);
  const simulate::SmoothMaskShape shape(m, kPixel, 0.75);
  const auto mirrored = [&](double x, double y) { return shape.level(x, std::abs(y)); };
  double worst_d = 0, worst_a = 0;
  int n = 0, open = 0;
  for (double x = 15.1; x < 46; x += 0.7)
    for (const double y : {0.3, 1.1, 1.9}) {
      if (mirrored(x * kPixel, y * kPixel) > 0) {
        EXPECT_TRUE(f.field()->isSolid(x * kPixel, y * kPixel)) << x << " " << y;
        continue;
      }
      Vec2 dir;
      const double d = levelDistance(mirrored, Vec2(x, y), 4.0, dir);
      if (d > y + 0.1) ++open;  // a wall on the plane would be nearer
      if (d > 2.5) {            // beyond the field's exact wall search (3 px here): at least that far
        EXPECT_GT(f.field()->wallDistance(x * kPixel, y * kPixel), 2.5 * kPixel) << x << " " << y;
        continue;
      }
      ++n;
      ASSERT_FALSE(f.field()->isSolid(x * kPixel, y * kPixel)) << x << " " << y;
      worst_d = std::max(worst_d, std::abs(f.field()->wallDistance(x * kPixel, y * kPixel) / kPixel - d));
      worst_a = std::max(worst_a, std::acos(std::clamp(f.field()->wallNormal(x * kPixel, y * kPixel).dot(dir), -1.0, 1.0)) * 180 / kPi);
    }
  std::printf("mirror sides: %d points within 2.5 px of the grain (%d nearer the plane), distance within %.5f px, normal within %.3f deg\n", n,
              open, worst_d, worst_a);
  EXPECT_GT(n, 15);
  EXPECT_GT(open, 20);
  EXPECT_LT(worst_d, 0.02);
  EXPECT_LT(worst_a, 6.0);
}

// A disc of radius 20 px rasterised by pixel centres, against the exact circle at 0.6, 1.5 and
// 2.3 px from it (within the field's exact wall search, 3 px here). The staircase's corners stray
// up to ~0.7 px and its normal turns by 90 degrees at each notch. The smooth boundary cannot place
// the circle better than the pixels tell (SmoothMaskShape's own test, tests/simulate: rms ~0.19
// px at R = 12.3 px): where the circle runs near an axis its staircase has long steps, which a
// Gaussian of 0.75 px rounds but does not straighten. Bounds: rms under 0.2 px, max 0.35 px,
// normal within 30 degrees (measured 0.15 px rms, 0.30 px max, 26 degrees max, 10 rms); and better than the staircase: its rms distance error at least 1.5
// times, its rms normal error at least 1.5 times the smooth's, and at 0.6 px, where a point sees a
// notch's two walls, its worst normal 90 degrees off (so the test fails if the walls fall back to
// pixels).
TEST(SmoothWalls, DiscDistanceAndNormalFollowTheCircle) {
  const int N = 64;
  const double cx = 32, cy = 32, R = 20;  // the centre on a pixel corner
  const PixelMask m = disc(N, N, cx, cy, R);
  MicromodelFlow smooth(m, options(true)), pixels(m, options(false));
  ASSERT_FALSE(smooth.solve({}).blocked);
  ASSERT_FALSE(pixels.solve({}).blocked);
  ASSERT_TRUE(smooth.field()->smoothWalls());
  ASSERT_FALSE(pixels.field()->smoothWalls());
  for (const double r : {R + 0.6, R + 1.5, R + 2.3}) {
    const RingErrors s = ringErrors(*smooth.field(), cx, cy, R, r, 720), p = ringErrors(*pixels.field(), cx, cy, R, r, 720);
    std::printf("ring r = %.1f px: smooth max %.4f rms %.4f px, normal max %.2f rms %.2f deg; pixels max %.4f rms %.4f px, normal max %.2f rms %.2f deg\n",
                r, s.max_distance, s.rms_distance, s.max_angle_deg, s.rms_angle_deg, p.max_distance, p.rms_distance, p.max_angle_deg,
                p.rms_angle_deg);
    EXPECT_LT(s.max_distance, 0.35) << r;
    EXPECT_LT(s.rms_distance, 0.2) << r;
    EXPECT_LT(s.max_angle_deg, 30.0) << r;
    EXPECT_GT(p.rms_distance, 1.5 * s.rms_distance) << r;
    EXPECT_GT(p.rms_angle_deg, 1.5 * s.rms_angle_deg) << r;
    if (r < R + 1) {
      EXPECT_GT(p.max_angle_deg, 89.0);
    }
  }
}

// A grain bounded by a 45 degree staircase (pixel centres below y = x + b, b = 0.3 px): on the
// pixels every concave notch is a corner whose two walls' normals are 90 degrees apart, where a
// particle pushed against the grain rests on two contacts; the smooth contour is the straight
// line but for a ripple of the pixel period (the Gaussian damps the steps to exp(-2 pi^2 0.75^2 /
// 2) = 0.004 of their amplitude; the cubic convolution between the blurred pixel centres leaves
// a ripple of its own, measured 0.043 px peak to peak, 3.8 degrees). Along a path parallel to the
// line, 1 px from it, through the notches' bisectors: the smooth normal stays within 6 degrees of
// the line's, the distance within 0.06 px of constant (and within a quarter pixel of the drawn
// line's); the staircase's normal swings by 45 degrees.
TEST(SmoothWalls, StaircaseNotchesAreGone) {
  const int rows = 40, cols = 60;
  const double b = 0.3;
  PixelMask m = PixelMask::Constant(rows, cols, false);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      const double x = c + 0.5, y = rows - r - 0.5;
      m(r, c) = y < x - 10 + b && y > 2;  // the grain below the diagonal, off the bottom wall
    }
  MicromodelFlow smooth(m, options(true)), pixels(m, options(false));
  ASSERT_FALSE(smooth.solve({}).blocked);
  ASSERT_FALSE(pixels.solve({}).blocked);
  const Vec2 n_line = Vec2(-1, 1).normalized();  // from the grain into the pore
  double s_angle = 0, p_angle = 0, s_min = 1e300, s_max = 0;
  for (double t = 20; t <= 40; t += 0.05) {
    // The line y = x - 10 + b, and the path 1 px from it into the pore.
    const Vec2 on(t, t - 10 + b), at = on + 1.0 * n_line;
    const double x = at.x() * kPixel, y = at.y() * kPixel;
    ASSERT_FALSE(smooth.field()->isSolid(x, y));
    const double d = smooth.field()->wallDistance(x, y) / kPixel;
    s_min = std::min(s_min, d);
    s_max = std::max(s_max, d);
    s_angle = std::max(s_angle, std::acos(std::clamp(smooth.field()->wallNormal(x, y).dot(n_line), -1.0, 1.0)) * 180 / kPi);
    p_angle = std::max(p_angle, std::acos(std::clamp(pixels.field()->wallNormal(x, y).dot(n_line), -1.0, 1.0)) * 180 / kPi);
  }
  std::printf("45 degree staircase: smooth normal within %.3f deg, distance %.4f .. %.4f px; pixels normal within %.1f deg\n", s_angle,
              s_min, s_max, p_angle);
  EXPECT_LT(s_angle, 6.0);
  EXPECT_LT(s_max - s_min, 0.06);
  EXPECT_NEAR(s_min, 1.0, 0.25);  // the level's line lies within a quarter pixel of the drawn one
  EXPECT_GT(p_angle, 40.0);
}

/// k of the depth-averaged solve of `shape` on the micromodel's grid (as the image-permeability
/// kind's imageProblem: 1 Pa west to east, slip sides, sharp immersed boundary): k = mu q L / (H dp).
double directPermeability(std::shared_ptr<const simulate::Shape> shape, int rows, int cols, double cells_per_pixel) {
  simulate::FlowProblem p;
  const double W = cols * kPixel, H = rows * kPixel;
  p.x = simulate::uniformAxis(0, W, std::max(4, static_cast<int>(std::lround(cols * cells_per_pixel))));
  p.y = simulate::uniformAxis(0, H, std::max(4, static_cast<int>(std::lround(rows * cells_per_pixel))));
  p.boundary[0].type = p.boundary[1].type = simulate::BoundaryType::pressure;
  p.boundary[0].pressure = 1.0;
  p.boundary[1].pressure = 0.0;
  p.boundary[2].type = p.boundary[3].type = simulate::BoundaryType::slip;
  p.viscosity = 1e-3;
  p.depth = kDepth;
  p.method = simulate::ImmersedMethod::sharp;
  p.shape = std::move(shape);
  simulate::SteadyFlowSolver s(p);
  s.solve();
  return 1e-3 * s.flowRate(simulate::Side::east) * W / (H * 1.0);
}

/// Three discs of radii 6-9 px in a 40 x 80 px chip: throats of a few pixels.
PixelMask threeGrains() {
  PixelMask m = disc(40, 80, 20.3, 22.1, 9.2) || disc(40, 80, 44.6, 14.7, 7.1) || disc(40, 80, 60.2, 29.4, 6.4);
  return m;
}

// The fluid k with smooth walls is the image-permeability kind's smooth problem on the same mask
// (same solver, same grid, same SmoothMaskShape): equal to the direct solve's round-off (1e-9).
// The pixels one equals the MaskShape solve likewise (the default unchanged), and the two differ
// by more than that (the boundary really changed).
TEST(SmoothWalls, FluidPermeabilityIsTheSmoothMaskShapes) {
  const PixelMask m = threeGrains();
  for (const double cpp : {0.5, 1.0}) {
    MicromodelFlow smooth(m, options(true, cpp)), pixels(m, options(false, cpp));
    const double ks = smooth.solve({}).permeability, kp = pixels.solve({}).permeability;
    const double ks_direct = directPermeability(std::make_shared<simulate::SmoothMaskShape>(m, kPixel, 0.75), 40, 80, cpp);
    const double kp_direct = directPermeability(std::make_shared<simulate::MaskShape>(m, kPixel), 40, 80, cpp);
    std::printf("%.1f cells/px: k smooth %.9g (direct %.9g), pixels %.9g (direct %.9g) m2\n", cpp, ks, ks_direct, kp, kp_direct);
    EXPECT_NEAR(ks, ks_direct, 1e-9 * ks_direct);
    EXPECT_NEAR(kp, kp_direct, 1e-9 * kp_direct);
    EXPECT_GT(std::abs(ks / kp - 1), 1e-3);
  }
}

// Re-solves with closed pixels keep working with smooth grains: the kept solver (fixed pattern)
// and a new solver per solve give the same k (1e-9), lower than the clean chip's, and the closed
// pixels are wall squares to the particles (solid, at distance 0 on their edges).
TEST(SmoothWalls, ReSolvesWithClosedPixels) {
  const PixelMask m = threeGrains();
  PixelMask closed = PixelMask::Constant(40, 80, false);
  // Pixels beside the first grain's right flank and in the open pore.
  closed(17, 30) = closed(18, 30) = closed(19, 30) = true;
  closed(5, 50) = true;
  MicromodelFlowOptions kept_opt = options(true, 1.0), rebuilt_opt = options(true, 1.0);
  rebuilt_opt.warm_start = false;
  MicromodelFlow kept(m, kept_opt), rebuilt(m, rebuilt_opt);
  const double k0 = kept.solve({}).permeability;
  const FlowSolveResult a = kept.solve(closed), b = rebuilt.solve(closed);
  std::printf("closed pixels: k %.12g (kept solver, pattern %s) vs %.12g (new solver), clean %.12g\n", a.permeability,
              a.pattern_kept ? "kept" : "rebuilt", b.permeability, k0);
  EXPECT_NEAR(a.permeability, b.permeability, 1e-9 * b.permeability);
  EXPECT_LT(a.permeability, k0);
  const auto& f = *kept.field();
  const double x = 50.5 * kPixel, y = (40 - 5 - 0.5) * kPixel;  // the closed pixel's centre (row 5 from the top)
  EXPECT_TRUE(f.isSolid(x, y));
  EXPECT_NEAR(f.wallDistance(x + 0.8 * kPixel, y), 0.3 * kPixel, 1e-9 * kPixel);  // its right edge, a square's
  EXPECT_NEAR(f.wallNormal(x + 0.8 * kPixel, y).x(), 1.0, 1e-9);
}

// The default is the pixels: no smooth walls, and the particles' distance is the staircase's:
// the exact distance to the nearest solid pixel square (brute force over the mask).
TEST(SmoothWalls, DefaultIsThePixelStaircase) {
  EXPECT_FALSE(MicromodelFlowOptions().smooth_walls);
  const int N = 64;
  const PixelMask m = disc(N, N, 32, 32, 20);
  MicromodelFlow f(m, options(false));
  f.solve({});
  EXPECT_FALSE(f.field()->smoothWalls());
  EXPECT_TRUE(f.field()->contourSegments().empty());
  for (int k = 0; k < 90; ++k) {
    const double a = 2 * kPi * (k + 0.37) / 90, x = (32 + 20.7 * std::cos(a)) * kPixel, y = (32 + 20.7 * std::sin(a)) * kPixel;
    double best = 1e300;
    for (int r = 0; r < N; ++r)
      for (int c = 0; c < N; ++c) {
        if (!m(r, c)) continue;
        const double x0 = c * kPixel, y0 = (N - 1 - r) * kPixel;
        best = std::min(best, std::hypot(std::max({x0 - x, 0.0, x - x0 - kPixel}), std::max({y0 - y, 0.0, y - y0 - kPixel})));
      }
    EXPECT_NEAR(f.field()->wallDistance(x, y), best, 1e-9 * kPixel) << k;
  }
}

}  // namespace
}  // namespace mmval::particles
