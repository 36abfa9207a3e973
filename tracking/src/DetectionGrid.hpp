// Uniform grids for radius queries over one frame's detections: DetectionGrid
// over a fixed set (the linker's candidates, the joint spot fit's neighbours), O(N)
// to build, no per-cell allocations; GrowingGrid for a set that grows point by point
// (spots found one after another), O(1) per point added, never rebuilt.
#pragma once
#include <algorithm>
#include <cmath>
#include <vector>

#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking::detail {

/// Uniform grid over detections for radius queries: cells over the detections' bounding
/// box, filled by a counting sort into one flat array (no per-cell allocations).
class DetectionGrid {
 public:
  DetectionGrid(const std::vector<Detection>& d, double cell) : m_d(d), m_cell(std::max(cell, 1e-9)) {
    if (d.empty()) return;
    double x0 = d[0].x, y0 = d[0].y, x1 = x0, y1 = y0;
    for (const auto& p : d) {
      x0 = std::min(x0, p.x);
      y0 = std::min(y0, p.y);
      x1 = std::max(x1, p.x);
      y1 = std::max(y1, p.y);
    }
    m_x0 = x0;
    m_y0 = y0;
    m_w = static_cast<long>((x1 - x0) / m_cell) + 1;
    m_h = static_cast<long>((y1 - y0) / m_cell) + 1;
    m_start.assign(static_cast<std::size_t>(m_w * m_h + 1), 0);
    std::vector<long> c(d.size());
    for (std::size_t i = 0; i < d.size(); ++i) {
      c[i] = cy(d[i].y) * m_w + cx(d[i].x);
      ++m_start[c[i] + 1];
    }
    for (std::size_t k = 1; k < m_start.size(); ++k) m_start[k] += m_start[k - 1];
    m_items.resize(d.size());
    std::vector<int> fill(m_start.begin(), m_start.end() - 1);
    for (std::size_t i = 0; i < d.size(); ++i) m_items[fill[c[i]]++] = static_cast<int>(i);
  }
  template <class F>
  void near(double x, double y, double r, F&& f) const {
    if (m_d.empty()) return;
    const long gx0 = std::max(0L, cx(x - r)), gx1 = std::min(m_w - 1, cx(x + r));
    const long gy0 = std::max(0L, cy(y - r)), gy1 = std::min(m_h - 1, cy(y + r));
    for (long gy = gy0; gy <= gy1; ++gy)
      for (long gx = gx0; gx <= gx1; ++gx)
        for (int k = m_start[gy * m_w + gx]; k < m_start[gy * m_w + gx + 1]; ++k) {
          const int i = m_items[k];
          const double dx = m_d[i].x - x, dy = m_d[i].y - y;
          if (dx * dx + dy * dy <= r * r) f(i, std::sqrt(dx * dx + dy * dy));
        }
  }

 private:
  long cx(double v) const { return std::clamp(static_cast<long>(std::floor((v - m_x0) / m_cell)), -1L, m_w); }
  long cy(double v) const { return std::clamp(static_cast<long>(std::floor((v - m_y0) / m_cell)), -1L, m_h); }
  const std::vector<Detection>& m_d;
  double m_cell, m_x0 = 0, m_y0 = 0;
  long m_w = 0, m_h = 0;
  std::vector<int> m_start, m_items;
};

/// Uniform grid over the rectangle [0, width) x [0, height) that grows point by point:
/// add() is O(1) (a cell's points are chained, newest first), near() visits the points
/// within r. Points outside the rectangle go to its border cells, so every point is found.
/// Built once per image: a search that adds spots as it finds them queries it without
/// rebuilding (a rebuild per spot made it quadratic in the spots).
class GrowingGrid {
 public:
  GrowingGrid(double width, double height, double cell)
      : m_cell(std::max(cell, 1e-9)),
        m_w(std::max(1L, static_cast<long>(std::ceil(std::max(width, 0.0) / m_cell)))),
        m_h(std::max(1L, static_cast<long>(std::ceil(std::max(height, 0.0) / m_cell)))),
        m_head(static_cast<std::size_t>(m_w * m_h), -1) {}
  void add(int item, double x, double y) {
    const long c = cy(y) * m_w + cx(x);
    m_points.push_back({x, y, item, m_head[static_cast<std::size_t>(c)]});
    m_head[static_cast<std::size_t>(c)] = static_cast<int>(m_points.size()) - 1;
  }
  /// f(item, distance) for every point within r of (x, y).
  template <class F>
  void near(double x, double y, double r, F&& f) const {
    const long gx0 = cx(x - r), gx1 = cx(x + r), gy0 = cy(y - r), gy1 = cy(y + r);
    for (long gy = gy0; gy <= gy1; ++gy)
      for (long gx = gx0; gx <= gx1; ++gx)
        for (int k = m_head[static_cast<std::size_t>(gy * m_w + gx)]; k >= 0; k = m_points[static_cast<std::size_t>(k)].next) {
          const Point& p = m_points[static_cast<std::size_t>(k)];
          const double dx = p.x - x, dy = p.y - y;
          if (dx * dx + dy * dy <= r * r) f(p.item, std::sqrt(dx * dx + dy * dy));
        }
  }

 private:
  struct Point {
    double x, y;
    int item, next;
  };
  // NaN goes to cell 0 (the comparisons it fails then leave it unmatched).
  long cx(double v) const { return v >= 0 ? std::min(m_w - 1, static_cast<long>(std::min(v / m_cell, 1e15))) : 0L; }
  long cy(double v) const { return v >= 0 ? std::min(m_h - 1, static_cast<long>(std::min(v / m_cell, 1e15))) : 0L; }
  double m_cell;
  long m_w, m_h;
  std::vector<int> m_head;
  std::vector<Point> m_points;
};

}  // namespace mmval::tracking::detail
