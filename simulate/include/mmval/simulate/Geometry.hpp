// Solid geometry for the immersed-boundary fluid solver.
//
// A Shape answers three questions in physical coordinates (metres): which
// body (if any) covers a point, how far a grid line travels from a fluid
// point before it hits a solid surface (for the sharp treatment), and the
// body's reference point (for torques). Analytic circles (single, or
// repeated periodically for arrays) answer exactly; a binary mask answers at
// pixel resolution (its surface is the pixel staircase, which is what the
// image says), or, reconstructed below pixel resolution, as a smooth
// boundary (SmoothMaskShape).
#pragma once
#include <filesystem>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace mmval::simulate {

class Shape {
 public:
  virtual ~Shape() = default;
  /// Index of the body covering (x, y), or -1 in fluid.
  virtual int bodyAt(double x, double y) const = 0;
  bool solid(double x, double y) const { return bodyAt(x, y) >= 0; }
  /// Distance from the fluid point (x, y) along axis (0: x, 1: y) in direction
  /// sign (+1/-1) to the first solid surface, if it is closer than max_distance;
  /// else max_distance. The default bisects bodyAt between the point and the
  /// end of the segment (accuracy ~1e-12 max_distance): it needs the end point
  /// to be solid (as the solver's solid neighbour nodes are) and assumes one crossing.
  virtual double distanceAlong(double x, double y, int axis, int sign, double max_distance) const;
  virtual int bodies() const = 0;
  /// Reference point of a body (torques are taken about it), metres.
  virtual Eigen::Vector2d centre(int body) const = 0;
};

struct Circle {
  double x = 0, y = 0, radius = 0;  ///< metres
};

/// Circles; with period_x / period_y > 0 every circle repeats with that period
/// (periodic arrays), so the shape is the same in every periodic image.
class Circles final : public Shape {
 public:
  explicit Circles(std::vector<Circle> circles, double period_x = 0, double period_y = 0);
  int bodyAt(double x, double y) const override;
  double distanceAlong(double x, double y, int axis, int sign, double max_distance) const override;
  int bodies() const override { return static_cast<int>(m_circles.size()); }
  Eigen::Vector2d centre(int body) const override;

 private:
  std::vector<Circle> m_circles;
  double m_px, m_py;
};

/// A binary mask: solid(row, col) true for grain pixels; row 0 is the image's
/// top row, which sits at y = origin_y + rows * pixel (y up, x to the right).
/// All grain pixels form body 0. Outside the image is fluid; a point on its edge (the inlet's and
/// outlet's face nodes) reads the edge pixel, so a grain touching a port closes it.
class MaskShape final : public Shape {
 public:
  MaskShape(Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> solid, double pixel_m, double origin_x = 0, double origin_y = 0);
  int bodyAt(double x, double y) const override;
  double distanceAlong(double x, double y, int axis, int sign, double max_distance) const override;
  int bodies() const override { return 1; }
  Eigen::Vector2d centre(int body) const override;
  int rows() const { return static_cast<int>(m_solid.rows()); }
  int cols() const { return static_cast<int>(m_solid.cols()); }
  double pixel() const { return m_pixel; }
  double width() const { return cols() * m_pixel; }
  double height() const { return rows() * m_pixel; }
  const Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>& mask() const { return m_solid; }

 private:
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> m_solid;
  double m_pixel, m_ox, m_oy;
};

/// A grain boundary below pixel resolution, reconstructed from a binary mask: the mask
/// (1 grain, 0 pore at each pixel centre) smoothed by a Gaussian of sigma_px pixels, interpolated
/// by cubic convolution (Keys 1981, IEEE Trans. ASSP 29(6) 1153, a = -1/2: C1, exact for
/// quadratics); grains are where that field exceeds 1/2. The 1/2 level of a straight step lies on
/// the step, so pixel-aligned walls stay where the staircase puts them; slanted and curved walls
/// lose the staircase's corners, whose singular corner flows make the permeability of a staircase
/// converge at first order in the grid spacing. Every pixel centre is kept on its own side (a
/// pixel whose smoothed value crossed 1/2 is set just inside its side), so a one-pixel gap, grain or
/// wall survives any sigma; wider sigma rounds more and narrows gaps of 1-2 pixels. Same layout as
/// MaskShape (row 0 at the top); outside the image is fluid, its edge reads the edge pixels' field. Body 0.
class SmoothMaskShape final : public Shape {
 public:
  SmoothMaskShape(const Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>& solid, double pixel_m, double sigma_px, double origin_x = 0,
                  double origin_y = 0);
  int bodyAt(double x, double y) const override;
  /// The first crossing of the 1/2 level along the line: the field is sampled every 1/8 pixel
  /// and the crossing bisected to ~1e-12 pixel.
  double distanceAlong(double x, double y, int axis, int sign, double max_distance) const override;
  int bodies() const override { return 1; }
  Eigen::Vector2d centre(int body) const override;
  /// The smoothed, interpolated mask at (x, y) minus 1/2: > 0 in grains. Outside the image -1/2
  /// (a point on the edge, to 1e-9 pixel, is inside).
  double level(double x, double y) const;
  int rows() const { return m_rows; }
  int cols() const { return m_cols; }
  double pixel() const { return m_pixel; }
  double width() const { return m_cols * m_pixel; }
  double height() const { return m_rows * m_pixel; }

 private:
  Eigen::ArrayXXf m_field;  ///< smoothed mask minus 1/2, with a 2-pixel replicated border
  int m_rows, m_cols;
  double m_pixel, m_ox, m_oy;
};

/// Reads a grayscale image (PNG, TIFF, ... via OpenCV) and splits it by mmval's
/// mask rule (core/MaskRule.hpp: halfway between its darkest and brightest grey);
/// grains_dark selects which side is solid. Throws std::runtime_error
/// if the file cannot be read (callers wrap it into an InputError).
Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> readMask(const std::filesystem::path& file, bool grains_dark);

}  // namespace mmval::simulate
