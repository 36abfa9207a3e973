#include "mmval/openfoam/ImageGeometry.hpp"

#include <algorithm>
#include <memory>
#include <cmath>
#include <stdexcept>
#include <unordered_map>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/MaskRule.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/openfoam/DirectMesh.hpp"
#include "mmval/simulate/Geometry.hpp"

namespace mmval::openfoam {

MaskGeometry loadMask(const std::filesystem::path& file, double pixel, bool grain_dark) {
  // From the header first: a small file can hold a huge image (12 B per pixel: image, labels, masks).
  requireImageWithin(file, {file.string(), 0, 0, "geometry.mask"}, defaultMaxMemoryBytes(), 12, "a smaller image: crop or downscale it");
  const cv::Mat img = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw InputError({file.string(), 0, 0, "geometry.mask"}, "cannot read the mask image", {}, "a PNG or TIFF image");
  MaskGeometry g;
  g.pixel = pixel;
  // mmval's mask rule (core/MaskRule.hpp): bright is above the split, fluid the side that is not grain.
  cv::threshold(img, g.fluid, maskSplit(img.ptr<std::uint8_t>(), img.total()), 255, grain_dark ? cv::THRESH_BINARY : cv::THRESH_BINARY_INV);
  g.porosity_total = static_cast<double>(cv::countNonZero(g.fluid)) / static_cast<double>(img.total());
  cv::Mat labels;
  const int n = cv::connectedComponents(g.fluid, labels, 4, CV_32S);
  std::vector<char> left(n, 0), right(n, 0);
  for (int r = 0; r < labels.rows; ++r) {
    left[labels.at<int>(r, 0)] = 1;
    right[labels.at<int>(r, labels.cols - 1)] = 1;
  }
  cv::Mat connected = cv::Mat::zeros(labels.size(), CV_8U);
  for (int r = 0; r < labels.rows; ++r)
    for (int c = 0; c < labels.cols; ++c) {
      const int l = labels.at<int>(r, c);
      if (l > 0 && left[l] && right[l]) connected.at<unsigned char>(r, c) = 255;
    }
  const int nc = cv::countNonZero(connected);
  if (nc == 0)
    throw InputError({file.string(), 0, 0, "geometry.mask"}, "no pore path connects the left (inlet) and right (outlet) edges", {},
                     "a mask with a connected pore space (check the polarity: grain_dark)");
  g.porosity_connected = static_cast<double>(nc) / static_cast<double>(img.total());
  // Isolated pores carry no flow: they become grain for meshing.
  g.fluid = connected;
  cv::Mat dist;
  cv::distanceTransform(connected, dist, cv::DIST_L2, 3);
  cv::Point best;
  cv::minMaxLoc(dist, nullptr, nullptr, nullptr, &best);
  g.inside = {(best.x + 0.5) * pixel, (img.rows - best.y - 0.5) * pixel};
  return g;
}

std::vector<std::array<int, 3>> triangulate(const std::vector<cv::Point2d>& poly) {
  const int n = static_cast<int>(poly.size());
  std::vector<std::array<int, 3>> tris;
  if (n < 3) return tris;
  double area = 0;
  for (int i = 0; i < n; ++i) area += poly[i].x * poly[(i + 1) % n].y - poly[(i + 1) % n].x * poly[i].y;
  std::vector<int> idx(n);
  for (int i = 0; i < n; ++i) idx[i] = area > 0 ? i : n - 1 - i;  // make it counter-clockwise
  auto cross = [](cv::Point2d a, cv::Point2d b, cv::Point2d c) { return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x); };
  int guard = 0;
  while (idx.size() > 3 && guard < 10 * n * n) {
    bool clipped = false;
    const int m = static_cast<int>(idx.size());
    for (int i = 0; i < m; ++i) {
      const int a = idx[(i + m - 1) % m], b = idx[i], c = idx[(i + 1) % m];
      if (cross(poly[a], poly[b], poly[c]) <= 1e-30) continue;  // reflex or degenerate
      bool empty = true;
      for (int j = 0; j < m && empty; ++j) {
        const int p = idx[j];
        if (p == a || p == b || p == c) continue;
        if (cross(poly[a], poly[b], poly[p]) >= 0 && cross(poly[b], poly[c], poly[p]) >= 0 && cross(poly[c], poly[a], poly[p]) >= 0) empty = false;
      }
      if (!empty) continue;
      tris.push_back({a, b, c});
      idx.erase(idx.begin() + i);
      clipped = true;
      break;
    }
    if (!clipped) {
      // Degenerate remainder (collinear points): drop the middle point.
      tris.push_back({idx[0], idx[1], idx[2]});
      idx.erase(idx.begin() + 1);
    }
    ++guard;
  }
  if (idx.size() == 3) tris.push_back({idx[0], idx[1], idx[2]});
  return tris;
}

double polygonArea(const Polygon& p) {
  double twice = 0;
  for (std::size_t i = 0; i < p.size(); ++i) twice += p[i].x * p[(i + 1) % p.size()].y - p[(i + 1) % p.size()].x * p[i].y;
  return 0.5 * twice;
}

std::vector<Polygon> pixelGrainPolygons(const MaskGeometry& g, double tolerance_px) {
  constexpr int kPad = 4;
  cv::Mat grains;
  cv::bitwise_not(g.fluid, grains);
  cv::Mat padded;
  cv::copyMakeBorder(grains, padded, kPad, kPad, kPad, kPad, cv::BORDER_REPLICATE);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(padded, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  std::vector<Polygon> out;
  for (const auto& contour : contours) {
    std::vector<cv::Point> simple;
    cv::approxPolyDP(contour, simple, tolerance_px, true);
    if (simple.size() < 3 || cv::contourArea(simple) < 1.0) continue;
    // Contour points are the centres of the boundary pixels (+0.5 to the pixel's centre in metres).
    Polygon poly;
    for (const auto& p : simple) poly.push_back({(p.x - kPad + 0.5) * g.pixel, (g.fluid.rows - (p.y - kPad) - 0.5) * g.pixel});
    if (polygonArea(poly) < 0) std::reverse(poly.begin(), poly.end());  // counter-clockwise: side normals point out of the grain
    out.push_back(std::move(poly));
  }
  return out;
}

namespace {

/// The smooth field of the connected-pore mask, as mmval's solver builds it.
simulate::SmoothMaskShape smoothField(const MaskGeometry& g, double sigma_px) {
  Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> solid(g.fluid.rows, g.fluid.cols);
  for (int r = 0; r < g.fluid.rows; ++r)
    for (int c = 0; c < g.fluid.cols; ++c) solid(r, c) = g.fluid.at<unsigned char>(r, c) == 0;
  return simulate::SmoothMaskShape(solid, g.pixel, sigma_px);
}

/// Marching squares on a node lattice over the image plus a margin. Node (i, j) sits at pixel
/// coordinates (u, v) = (j / n - margin, i / n - margin), u rightward, v downward, pixel edges at
/// integers; the field is sampled at the nearest point of the image (so it continues straight out
/// beyond the edges), and the outermost ring of nodes is fluid so every outline closes.
class IsoLines {
 public:
  IsoLines(const MaskGeometry& g, const simulate::SmoothMaskShape& f, int n)
      : m_g(g), m_f(f), m_n(n), m_nu(static_cast<long long>(g.fluid.cols + 2 * kMargin) * n + 1),
        m_nv(static_cast<long long>(g.fluid.rows + 2 * kMargin) * n + 1), m_value(static_cast<std::size_t>(m_nu * m_nv)) {
    for (long long i = 0; i < m_nv; ++i)
      for (long long j = 0; j < m_nu; ++j) {
        const bool ring = i == 0 || j == 0 || i == m_nv - 1 || j == m_nu - 1;
        m_value[static_cast<std::size_t>(i * m_nu + j)] = ring ? -0.5 : levelAt(u(j), v(i));
      }
  }

  std::vector<Polygon> outlines() {
    // Segments oriented so the grain (value > 0) lies on their left in y-up coordinates; each
    // crossing point (a lattice edge) starts exactly one segment and ends exactly one.
    std::unordered_map<long long, long long> next;
    for (long long i = 0; i + 1 < m_nv; ++i)
      for (long long j = 0; j + 1 < m_nu; ++j) cellSegments(i, j, next);
    std::vector<Polygon> out;
    std::unordered_map<long long, char> used;
    for (const auto& [first, unused] : next) {
      if (used[first]) continue;
      std::vector<cv::Point2f> chain;  // pixel units for Douglas-Peucker
      for (long long e = first; !used[e]; e = next.at(e)) {
        used[e] = 1;
        const cv::Point2d p = crossing(e);
        chain.push_back({static_cast<float>(p.x), static_cast<float>(p.y)});
      }
      std::vector<cv::Point2f> simple;
      cv::approxPolyDP(chain, simple, kSimplifyPx, true);
      if (simple.size() < 3) continue;
      Polygon poly;
      for (const auto& p : simple) poly.push_back({p.x * m_g.pixel, (m_g.fluid.rows - p.y) * m_g.pixel});
      if (polygonArea(poly) > 0) out.push_back(std::move(poly));  // clockwise: a fluid hole inside a grain
    }
    return out;
  }

 private:
  static constexpr int kMargin = 2;             ///< pixels beyond the image where outlines close
  static constexpr double kSimplifyPx = 0.002;  ///< Douglas-Peucker tolerance, pixels

  double u(long long j) const { return static_cast<double>(j) / m_n - kMargin; }
  double v(long long i) const { return static_cast<double>(i) / m_n - kMargin; }
  double levelAt(double uu, double vv) const {
    uu = std::clamp(uu, 0.0, static_cast<double>(m_g.fluid.cols));
    vv = std::clamp(vv, 0.0, static_cast<double>(m_g.fluid.rows));
    return m_f.level(uu * m_g.pixel, (m_g.fluid.rows - vv) * m_g.pixel);
  }
  double node(long long i, long long j) const { return m_value[static_cast<std::size_t>(i * m_nu + j)]; }
  /// Lattice edge ids: 2 (i m_nu + j) for the edge from node (i, j) to (i, j + 1), + 1 for the one to (i + 1, j).
  long long edgeId(long long i, long long j, int vertical) const { return 2 * (i * m_nu + j) + vertical; }

  /// The crossing on edge `e`, pixel coordinates: bisection of the field between the edge's nodes.
  cv::Point2d crossing(long long e) const {
    const long long k = e / 2, i = k / m_nu, j = k % m_nu;
    const bool vertical = e % 2 == 1;
    const long long i1 = vertical ? i + 1 : i, j1 = vertical ? j : j + 1;
    double a = 0, b = 1;  // fraction along the edge; node (i, j) at 0
    const double fa = node(i, j), fb = node(i1, j1);
    const bool ring = i == 0 || j == 0 || i1 == m_nv - 1 || j1 == m_nu - 1;
    auto at = [&](double t) { return levelAt(u(j) + t * (u(j1) - u(j)), v(i) + t * (v(i1) - v(i))); };
    if (ring) {
      a = b = fa / (fa - fb);  // the forced ring is no field: linear
    } else {
      for (int it = 0; it < 32; ++it) {
        const double mid = 0.5 * (a + b);
        ((at(mid) > 0) == (fa > 0) ? a : b) = mid;
      }
    }
    const double t = 0.5 * (a + b);
    return {u(j) + t * (u(j1) - u(j)), v(i) + t * (v(i1) - v(i))};
  }

  void cellSegments(long long i, long long j, std::unordered_map<long long, long long>& next) const {
    // Corners in walk order top-left, top-right, bottom-right, bottom-left; edge k joins corner k to k + 1.
    const double c[4] = {node(i, j), node(i, j + 1), node(i + 1, j + 1), node(i + 1, j)};
    const long long edges[4] = {edgeId(i, j, 0), edgeId(i, j + 1, 1), edgeId(i + 1, j, 0), edgeId(i, j, 1)};
    long long into[2], outof[2];  // crossings where the walk enters / leaves the grain
    int n_in = 0, n_out = 0;
    for (int k = 0; k < 4; ++k) {
      const bool a = c[k] > 0, b = c[(k + 1) % 4] > 0;
      if (a == b) continue;
      (b ? into[n_in++] : outof[n_out++]) = edges[k];
    }
    if (n_in == 0) return;
    // The walk runs clockwise in y-up coordinates, so an outline from where it enters the grain
    // to where it next leaves has the grain on its left. For a saddle (two of each), the cell
    // centre decides: grain there joins the two grain corners, so each leave pairs with the enter
    // after it (the fluid corners are cut off); fluid there cuts off the grain corners, each
    // enter followed by its own leave.
    if (n_in == 1) {
      next[into[0]] = outof[0];
      return;
    }
    const bool centre_grain = levelAt(u(j) + 0.5 / m_n, v(i) + 0.5 / m_n) > 0;
    int pos_out[2];
    for (int k = 0, b = 0; k < 4; ++k)
      if (edges[k] == outof[0] || edges[k] == outof[1]) pos_out[b++] = k;
    for (int q = 0; q < 2; ++q) {
      // The leave at walk edge pos_out[q]: its partner enter is the next edge after it, or the one before it.
      const int partner = centre_grain ? (pos_out[q] + 1) % 4 : (pos_out[q] + 3) % 4;
      next[edges[partner]] = edges[pos_out[q]];
    }
  }

  const MaskGeometry& m_g;
  const simulate::SmoothMaskShape& m_f;
  int m_n;
  long long m_nu, m_nv;
  std::vector<double> m_value;
};

}  // namespace

std::vector<Polygon> smoothGrainPolygons(const MaskGeometry& g, double sigma_px, int samples_per_pixel) {
  if (samples_per_pixel < 2 || samples_per_pixel > 64)
    throw std::invalid_argument(fmt::format("smoothGrainPolygons: {} lattice nodes per pixel, expected 2 to 64", samples_per_pixel));
  const simulate::SmoothMaskShape f = smoothField(g, sigma_px);
  IsoLines lines(g, f, samples_per_pixel);
  return lines.outlines();
}

LevelFunction smoothLevel(const MaskGeometry& g, double sigma_px) {
  auto f = std::make_shared<const simulate::SmoothMaskShape>(smoothField(g, sigma_px));
  return [f](double x, double y) { return f->level(x, y); };
}

double smoothPoreFraction(const MaskGeometry& g, double sigma_px, int samples_per_pixel) {
  const simulate::SmoothMaskShape f = smoothField(g, sigma_px);
  const int n = std::max(1, samples_per_pixel);
  long long pore = 0;
  const long long nu = static_cast<long long>(g.fluid.cols) * n, nv = static_cast<long long>(g.fluid.rows) * n;
  for (long long i = 0; i < nv; ++i)
    for (long long j = 0; j < nu; ++j)
      if (f.level((j + 0.5) / n * g.pixel, (i + 0.5) / n * g.pixel) <= 0) ++pore;
  return static_cast<double>(pore) / static_cast<double>(nu * nv);
}

std::string extrudedStl(const std::vector<Polygon>& polygons, double z0, double z1) {
  std::string out = "solid grains\n";
  auto facet = [&](cv::Point3d a, cv::Point3d b, cv::Point3d c) {
    const cv::Point3d n = (b - a).cross(c - a);
    const double len = std::sqrt(n.dot(n));
    if (len <= 0) return;
    out += fmt::format("facet normal {:.9g} {:.9g} {:.9g}\n outer loop\n", n.x / len, n.y / len, n.z / len);
    for (const auto& p : {a, b, c}) out += fmt::format("  vertex {:.9g} {:.9g} {:.9g}\n", p.x, p.y, p.z);
    out += " endloop\nendfacet\n";
  };
  for (Polygon poly : polygons) {
    if (polygonArea(poly) < 0) std::reverse(poly.begin(), poly.end());  // counter-clockwise: side normals point out of the grain
    const std::size_t n = poly.size();
    for (std::size_t i = 0; i < n; ++i) {
      const auto& p = poly[i];
      const auto& q = poly[(i + 1) % n];
      facet({p.x, p.y, z0}, {q.x, q.y, z0}, {q.x, q.y, z1});
      facet({p.x, p.y, z0}, {q.x, q.y, z1}, {p.x, p.y, z1});
    }
    for (const auto& t : triangulate(poly)) {
      facet({poly[t[0]].x, poly[t[0]].y, z1}, {poly[t[1]].x, poly[t[1]].y, z1}, {poly[t[2]].x, poly[t[2]].y, z1});
      facet({poly[t[0]].x, poly[t[0]].y, z0}, {poly[t[2]].x, poly[t[2]].y, z0}, {poly[t[1]].x, poly[t[1]].y, z0});
    }
  }
  out += "endsolid grains\n";
  return out;
}

std::string grainStl(const MaskGeometry& g, double z0, double z1, double tolerance_px) {
  return extrudedStl(pixelGrainPolygons(g, tolerance_px), z0, z1);
}

}  // namespace mmval::openfoam
