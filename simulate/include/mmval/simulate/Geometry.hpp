// Solid geometry for the immersed-boundary fluid solver.
//
// A Shape answers three questions in physical coordinates (metres): which
// body (if any) covers a point, how far a grid line travels from a fluid
// point before it hits a solid surface (for the sharp treatment), and the
// body's reference point (for torques). Analytic circles (single, or
// repeated periodically for arrays) answer exactly; a binary mask answers at
// pixel resolution (its surface is the pixel staircase, which is what the
// image says).
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
/// All grain pixels form body 0.
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

/// Reads a grayscale image (PNG, TIFF, ... via OpenCV) and thresholds it at
/// mid-grey: grains_dark selects which side is solid. Throws std::runtime_error
/// if the file cannot be read (callers wrap it into an InputError).
Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> readMask(const std::filesystem::path& file, bool grains_dark);

}  // namespace mmval::simulate
