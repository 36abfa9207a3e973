#include "mmval/particles/DepositGrid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>

namespace mmval::particles {

DepositGrid::DepositGrid(const PixelMask& grains, double pixel, double depth, double fill_fraction)
    : m_grains(grains), m_closed(PixelMask::Constant(grains.rows(), grains.cols(), false)), m_pixel(pixel),
      m_capacity(fill_fraction * pixel * pixel * depth), m_volume(static_cast<std::size_t>(grains.size()), 0.0) {
  if (!(pixel > 0) || !(depth > 0) || !(fill_fraction > 0) || fill_fraction > 1)
    throw std::invalid_argument("DepositGrid: pixel and depth must be > 0, fill_fraction in (0, 1]");
}

int DepositGrid::add(double x, double y, double volume) {
  if (!(volume > 0)) return 0;
  m_total += volume;
  const int rows = static_cast<int>(m_grains.rows()), cols = static_cast<int>(m_grains.cols());
  const int c0 = std::clamp(static_cast<int>(std::floor(x / m_pixel)), 0, cols - 1);
  const int r0 = std::clamp(rows - 1 - static_cast<int>(std::floor(y / m_pixel)), 0, rows - 1);
  double left = volume;
  int closed = 0;
  // Rings of growing Chebyshev radius; inside a ring the nearest pixels fill
  // first (ties by index, so the result does not depend on anything but input).
  const int max_ring = std::max(rows, cols);
  std::vector<std::tuple<int, int, int>> ring;  // (distance^2, row, col)
  for (int R = 0; R <= max_ring && left > 0; ++R) {
    ring.clear();
    for (int r = r0 - R; r <= r0 + R; ++r)
      for (int c = c0 - R; c <= c0 + R; ++c) {
        if (std::max(std::abs(r - r0), std::abs(c - c0)) != R) continue;
        if (r < 0 || r >= rows || c < 0 || c >= cols || m_grains(r, c) || m_closed(r, c)) continue;
        ring.emplace_back((r - r0) * (r - r0) + (c - c0) * (c - c0), r, c);
      }
    std::sort(ring.begin(), ring.end());
    for (const auto& [d2, r, c] : ring) {
      double& v = m_volume[static_cast<std::size_t>(r) * cols + c];
      const double take = std::min(left, m_capacity - v);
      v += take;
      left -= take;
      if (v >= m_capacity * (1 - 1e-12)) {
        m_closed(r, c) = true;
        ++m_closed_count;
        ++closed;
      }
      if (left <= 0) break;
    }
  }
  return closed;  // volume beyond a completely filled medium is dropped (the run stops long before)
}

void DepositGrid::save(CheckpointWriter& w) const {
  w.put(m_total);
  w.put(m_closed_count);
  w.putVector(m_volume);
  std::vector<std::uint8_t> c(static_cast<std::size_t>(m_closed.size()));
  for (Eigen::Index k = 0; k < m_closed.size(); ++k) c[static_cast<std::size_t>(k)] = m_closed(k) ? 1 : 0;
  w.putVector(c);
}

void DepositGrid::load(CheckpointReader& r) {
  m_total = r.get<double>();
  m_closed_count = r.get<std::int64_t>();
  auto v = r.getVector<double>();
  auto c = r.getVector<std::uint8_t>();
  if (v.size() != m_volume.size() || c.size() != m_volume.size()) throw std::runtime_error("checkpoint " + r.name() + ": deposit grid of another size");
  m_volume = std::move(v);
  for (Eigen::Index k = 0; k < m_closed.size(); ++k) m_closed(k) = c[static_cast<std::size_t>(k)] != 0;
}

}  // namespace mmval::particles
