#include "mmval/simulate/Geometry.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "mmval/core/MaskRule.hpp"

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

namespace {
/// Pixels: a point this close to the image's edge lies on it (x = width is cols * pixel / pixel).
constexpr double kOnEdge = 1e-9;

/// The pixel index of coordinate u (pixel edges at integers) among n, a point on the image's
/// edge (u = 0 or n, to kOnEdge) taking the edge pixel; -1 outside the image.
double pixelIndex(double u, int n) {
  if (u >= -kOnEdge && u < 0) return 0;
  if (u >= n && u <= n + kOnEdge) return n - 1;
  const double i = std::floor(u);
  return i < 0 || i >= n ? -1 : i;
}
}  // namespace

int MaskShape::bodyAt(double x, double y) const {
  // On the image's edge the edge pixel counts: the outlet's face nodes lie on x = width, and a grain
  // touching the outlet must close them (reading the fluid beyond opened it: 1 % more flux through
  // a channel whose walls reach the outlet).
  const double c = pixelIndex((x - m_ox) / m_pixel, cols());
  const double r = pixelIndex((m_oy + height() - y) / m_pixel, rows());
  if (c < 0 || r < 0) return -1;
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

namespace {

/// How far inside its own side the smoothed field keeps each pixel centre (of the 0 .. 1 range).
constexpr double kKeepMargin = 0.02;

/// Cubic convolution kernel of Keys (1981) with a = -1/2.
double keys(double t) {
  t = std::abs(t);
  if (t < 1) return (1.5 * t - 2.5) * t * t + 1;
  if (t < 2) return ((-0.5 * t + 2.5) * t - 4) * t + 2;
  return 0;
}

/// 1-D Gaussian weights of standard deviation sigma (pixels), radius ceil(3 sigma), summing to 1.
std::vector<double> gaussian(double sigma) {
  if (!(sigma > 0)) return {1.0};
  const int r = static_cast<int>(std::ceil(3 * sigma));
  std::vector<double> w(static_cast<std::size_t>(2 * r + 1));
  double sum = 0;
  for (int k = -r; k <= r; ++k) sum += w[static_cast<std::size_t>(k + r)] = std::exp(-0.5 * k * k / (sigma * sigma));
  for (auto& v : w) v /= sum;
  return w;
}

}  // namespace

SmoothMaskShape::SmoothMaskShape(const Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>& solid, double pixel_m, double sigma_px, double origin_x,
                                 double origin_y)
    : m_rows(static_cast<int>(solid.rows())), m_cols(static_cast<int>(solid.cols())), m_pixel(pixel_m), m_ox(origin_x), m_oy(origin_y) {
  if (solid.size() == 0 || !(pixel_m > 0)) throw std::invalid_argument("a mask needs pixels and a positive pixel size");
  if (!(sigma_px >= 0) || sigma_px > 8) throw std::invalid_argument("the smoothing width must be in [0, 8] pixels");
  // Separable Gaussian with the border replicated (an edge grain continues beyond the image).
  const std::vector<double> w = gaussian(sigma_px);
  const int r = static_cast<int>(w.size() / 2);
  auto clampi = [](int i, int n) { return std::clamp(i, 0, n - 1); };
  Eigen::ArrayXXd rowpass(m_rows, m_cols);
  for (int i = 0; i < m_rows; ++i)
    for (int j = 0; j < m_cols; ++j) {
      double s = 0;
      for (int k = -r; k <= r; ++k) s += w[static_cast<std::size_t>(k + r)] * (solid(i, clampi(j + k, m_cols)) ? 1.0 : 0.0);
      rowpass(i, j) = s;
    }
  Eigen::ArrayXXd blurred(m_rows, m_cols);
  for (int i = 0; i < m_rows; ++i)
    for (int j = 0; j < m_cols; ++j) {
      double s = 0;
      for (int k = -r; k <= r; ++k) s += w[static_cast<std::size_t>(k + r)] * rowpass(clampi(i + k, m_rows), j);
      // Every pixel centre stays on its side of the boundary: the smoothing rounds the staircase
      // but never closes a one-pixel gap or removes a one-pixel grain or wall.
      blurred(i, j) = solid(i, j) ? std::max(s, 0.5 + kKeepMargin) : std::min(s, 0.5 - kKeepMargin);
    }
  m_field.resize(m_rows + 4, m_cols + 4);
  for (int i = -2; i < m_rows + 2; ++i)
    for (int j = -2; j < m_cols + 2; ++j) m_field(i + 2, j + 2) = static_cast<float>(blurred(clampi(i, m_rows), clampi(j, m_cols)) - 0.5);
}

double SmoothMaskShape::level(double x, double y) const {
  double u = (x - m_ox) / m_pixel, v = (m_oy + height() - y) / m_pixel;  // column, row coordinates (pixel edges at integers)
  // A point on the image's edge (to kOnEdge, the rounding of width / pixel) reads the edge's field.
  if (u < -kOnEdge || v < -kOnEdge || u > m_cols + kOnEdge || v > m_rows + kOnEdge) return -0.5;
  u = std::clamp(u, 0.0, static_cast<double>(m_cols));
  v = std::clamp(v, 0.0, static_cast<double>(m_rows));
  const double cu = u - 0.5, cv = v - 0.5;  // pixel centres at integers
  const int i0 = static_cast<int>(std::floor(cv)), j0 = static_cast<int>(std::floor(cu));
  const double ti = cv - i0, tj = cu - j0;
  double wi[4], wj[4];
  for (int k = 0; k < 4; ++k) {
    wi[k] = keys(ti - (k - 1));
    wj[k] = keys(tj - (k - 1));
  }
  double s = 0;
  for (int a = 0; a < 4; ++a) {
    const int ri = std::clamp(i0 + a - 1 + 2, 0, m_rows + 3);
    double row = 0;
    for (int b = 0; b < 4; ++b) row += wj[b] * m_field(ri, std::clamp(j0 + b - 1 + 2, 0, m_cols + 3));
    s += wi[a] * row;
  }
  return s;
}

int SmoothMaskShape::bodyAt(double x, double y) const { return level(x, y) > 0 ? 0 : -1; }

double SmoothMaskShape::distanceAlong(double x, double y, int axis, int sign, double max_distance) const {
  auto at = [&](double t) { return axis == 0 ? level(x + sign * t, y) : level(x, y + sign * t); };
  const double step = m_pixel / 8;
  double lo = 0;
  for (;;) {
    const double hi = std::min(lo + step, max_distance);
    if (at(hi) > 0) {
      double a = lo, b = hi;
      for (int k = 0; k < 50 && b - a > 1e-12 * m_pixel; ++k) {
        const double mid = 0.5 * (a + b);
        (at(mid) > 0 ? b : a) = mid;
      }
      return 0.5 * (a + b);
    }
    if (hi >= max_distance) return max_distance;
    lo = hi;
  }
}

Eigen::Vector2d SmoothMaskShape::centre(int) const { return {m_ox + 0.5 * width(), m_oy + 0.5 * height()}; }

Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> readMask(const std::filesystem::path& file, bool grains_dark) {
  const cv::Mat img = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw std::runtime_error("cannot read image '" + file.string() + "' (missing, or not an image OpenCV can decode)");
  const cv::Mat grey = img.isContinuous() ? img : img.clone();
  const double split = maskSplit(grey.ptr<std::uint8_t>(), grey.total());
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> m(img.rows, img.cols);
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c) m(r, c) = isGrain(grey.at<std::uint8_t>(r, c), split, grains_dark);
  return m;
}

}  // namespace mmval::simulate
