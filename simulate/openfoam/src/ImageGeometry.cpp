#include "mmval/openfoam/ImageGeometry.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"

namespace mmval::openfoam {

MaskGeometry loadMask(const std::filesystem::path& file, double pixel, bool grain_dark) {
  // From the header first: a small file can hold a huge image (12 B per pixel: image, labels, masks).
  requireImageWithin(file, {file.string(), 0, 0, "geometry.mask"}, defaultMaxMemoryBytes(), 12, "a smaller image: crop or downscale it");
  const cv::Mat img = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw InputError({file.string(), 0, 0, "geometry.mask"}, "cannot read the mask image", {}, "a PNG or TIFF image");
  MaskGeometry g;
  g.pixel = pixel;
  cv::threshold(img, g.fluid, 127, 255, grain_dark ? cv::THRESH_BINARY : cv::THRESH_BINARY_INV);
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

std::string grainStl(const MaskGeometry& g, double z0, double z1, double tolerance_px) {
  constexpr int kPad = 4;
  cv::Mat grains;
  cv::bitwise_not(g.fluid, grains);
  cv::Mat padded;
  cv::copyMakeBorder(grains, padded, kPad, kPad, kPad, kPad, cv::BORDER_REPLICATE);
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(padded, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  std::string out = "solid grains\n";
  auto facet = [&](cv::Point3d a, cv::Point3d b, cv::Point3d c) {
    const cv::Point3d n = (b - a).cross(c - a);
    const double len = std::sqrt(n.dot(n));
    if (len <= 0) return;
    out += fmt::format("facet normal {:.9g} {:.9g} {:.9g}\n outer loop\n", n.x / len, n.y / len, n.z / len);
    for (const auto& p : {a, b, c}) out += fmt::format("  vertex {:.9g} {:.9g} {:.9g}\n", p.x, p.y, p.z);
    out += " endloop\nendfacet\n";
  };
  for (const auto& contour : contours) {
    std::vector<cv::Point> simple;
    cv::approxPolyDP(contour, simple, tolerance_px, true);
    if (simple.size() < 3 || cv::contourArea(simple) < 1.0) continue;
    // Pixel corners -> metres, y up; contour points are pixel centres of boundary pixels,
    // so push them half a pixel outward by using the centre coordinates (+0.5).
    std::vector<cv::Point2d> poly;
    for (const auto& p : simple)
      poly.push_back({(p.x - kPad + 0.5) * g.pixel, (g.fluid.rows - (p.y - kPad) - 0.5) * g.pixel});
    double area = 0;
    for (std::size_t i = 0; i < poly.size(); ++i) area += poly[i].x * poly[(i + 1) % poly.size()].y - poly[(i + 1) % poly.size()].x * poly[i].y;
    if (area < 0) std::reverse(poly.begin(), poly.end());  // counter-clockwise: side normals point out of the grain
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

}  // namespace mmval::openfoam
