#include "mmval/simulate/Geometry.hpp"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>

namespace mmval::simulate {

double Shape::distanceAlong(double x, double y, int axis, int sign, double max_distance) const {
  auto at = [&](double t) { return axis == 0 ? solid(x + sign * t, y) : solid(x, y + sign * t); };
  if (!at(max_distance)) return max_distance;
  double lo = 0, hi = max_distance;
  for (int k = 0; k < 40; ++k) {
    const double mid = 0.5 * (lo + hi);
    (at(mid) ? hi : lo) = mid;
  }
  return 0.5 * (lo + hi);
}

Circles::Circles(std::vector<Circle> circles, double period_x, double period_y)
    : m_circles(std::move(circles)), m_px(period_x), m_py(period_y) {
  for (const auto& c : m_circles)
    if (!(c.radius > 0)) throw std::invalid_argument("a circle needs a positive radius");
}

namespace {
double wrap(double d, double period) { return period > 0 ? d - period * std::round(d / period) : d; }
}  // namespace

int Circles::bodyAt(double x, double y) const {
  for (std::size_t k = 0; k < m_circles.size(); ++k) {
    const auto& c = m_circles[k];
    const double dx = wrap(x - c.x, m_px), dy = wrap(y - c.y, m_py);
    if (dx * dx + dy * dy < c.radius * c.radius) return static_cast<int>(k);
  }
  return -1;
}

double Circles::distanceAlong(double x, double y, int axis, int sign, double max_distance) const {
  double best = max_distance;
  for (const auto& c : m_circles) {
    // Along the line p + s t e_axis, the nearest periodic image of the centre
    // in the transverse direction is the only one that can be hit within a
    // period; in the line direction take the image nearest to the point.
    const double dx = wrap(c.x - x, m_px), dy = wrap(c.y - y, m_py);
    const double along = sign * (axis == 0 ? dx : dy), across = axis == 0 ? dy : dx;
    const double period = axis == 0 ? m_px : m_py;
    const double disc = c.radius * c.radius - across * across;
    if (disc <= 0) continue;
    // Entry points of the nearest image and, on a periodic axis, of the next one ahead.
    for (double a : {along, along + period}) {
      const double t = a - std::sqrt(disc);
      if (t >= 0 && t < best) best = t;
      if (period <= 0) break;
    }
  }
  return best;
}

Eigen::Vector2d Circles::centre(int body) const {
  const auto& c = m_circles.at(static_cast<std::size_t>(body));
  return {c.x, c.y};
}

MaskShape::MaskShape(Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> solid, double pixel_m, double origin_x, double origin_y)
    : m_solid(std::move(solid)), m_pixel(pixel_m), m_ox(origin_x), m_oy(origin_y) {
  if (m_solid.size() == 0 || !(pixel_m > 0)) throw std::invalid_argument("a mask needs pixels and a positive pixel size");
}

int MaskShape::bodyAt(double x, double y) const {
  const double c = std::floor((x - m_ox) / m_pixel);
  const double r = std::floor((m_oy + height() - y) / m_pixel);
  if (c < 0 || r < 0 || c >= cols() || r >= rows()) return -1;
  return m_solid(static_cast<Eigen::Index>(r), static_cast<Eigen::Index>(c)) ? 0 : -1;
}

double MaskShape::distanceAlong(double x, double y, int axis, int sign, double max_distance) const {
  // Walk pixel edges along the line: the surface is the first edge into a grain pixel.
  const double pos = axis == 0 ? (x - m_ox) / m_pixel : (y - m_oy) / m_pixel;
  double edge = sign > 0 ? std::floor(pos) + 1 : std::ceil(pos) - 1;
  for (;;) {
    const double t = std::abs(edge - pos) * m_pixel;
    if (t >= max_distance) return max_distance;
    const double probe = edge + sign * 0.5;  // centre of the pixel beyond the edge
    const double px = axis == 0 ? m_ox + probe * m_pixel : x;
    const double py = axis == 0 ? y : m_oy + probe * m_pixel;
    if (bodyAt(px, py) >= 0) return t;
    edge += sign;
  }
}

Eigen::Vector2d MaskShape::centre(int) const { return {m_ox + 0.5 * width(), m_oy + 0.5 * height()}; }

Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> readMask(const std::filesystem::path& file, bool grains_dark) {
  const cv::Mat img = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw std::runtime_error("cannot read image '" + file.string() + "' (missing, or not an image OpenCV can decode)");
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> m(img.rows, img.cols);
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) {
      const bool dark = img.at<unsigned char>(r, c) < 128;
      m(r, c) = grains_dark ? dark : !dark;
    }
  return m;
}

}  // namespace mmval::simulate
