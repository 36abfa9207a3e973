// Uniform grid over one frame's detections for radius queries (the linker's
// candidates, the joint spot fit's neighbours): O(N) to build, no per-cell
// allocations.
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

}  // namespace mmval::tracking::detail
