#include "mmval/particles/DepositGrid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <tuple>

namespace mmval::particles {

namespace {
constexpr double kFull = 1 - 1e-12;  // a pixel this close to its limit counts as full (round-off of the volume sums)
}

DepositGrid::DepositGrid(const PixelMask& grains, double pixel, double depth, double fill_fraction, DepositLayerModel layer)
    : m_grains(grains), m_closed(PixelMask::Constant(grains.rows(), grains.cols(), false)), m_pixel(pixel), m_depth(depth),
      m_capacity(fill_fraction * pixel * pixel * depth), m_layer_model(layer), m_volume(static_cast<std::size_t>(grains.size()), 0.0),
      m_layer(static_cast<std::size_t>(grains.size()), 0.0) {
  if (!(pixel > 0) || !(depth > 0) || !(fill_fraction > 0) || fill_fraction > 1)
    throw std::invalid_argument("DepositGrid: pixel and depth must be > 0, fill_fraction in (0, 1]");
  if (!(layer.packing > 0) || layer.packing > 1 || !(layer.min_aperture >= 0) || !(layer.min_aperture < depth))
    throw std::invalid_argument("DepositGrid: layer packing must be in (0, 1] and the minimum aperture in [0, depth)");
}

void DepositGrid::close(std::size_t k) {
  const auto cols = static_cast<std::size_t>(m_grains.cols());
  const double thickness = m_layer[k] / (m_layer_model.packing * m_pixel * m_pixel);
  m_lost += 1.0 - std::min(thickness / m_depth, 1.0);  // the aperture left before closing
  m_closed(static_cast<Eigen::Index>(k / cols), static_cast<Eigen::Index>(k % cols)) = true;
  ++m_closed_count;
}

template <class Take>
int DepositGrid::spread(double x, double y, double volume, Take take) {
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
      const std::size_t k = static_cast<std::size_t>(r) * cols + c;
      const auto [taken, full] = take(k, left);
      left -= taken;
      if (full) {
        close(k);
        ++closed;
      }
      if (left <= 0) break;
    }
  }
  return closed;  // volume beyond a completely filled medium is dropped (the run stops long before)
}

int DepositGrid::add(double x, double y, double volume) {
  return spread(x, y, volume, [&](std::size_t k, double left) {
    double& v = m_volume[k];
    const double take = std::min(left, m_capacity - v);
    v += take;
    return std::pair<double, bool>(take, v >= m_capacity * kFull);
  });
}

int DepositGrid::addLayer(double x, double y, double volume, double max_layer) {
  if (!(max_layer > 0)) throw std::invalid_argument("DepositGrid::addLayer: the largest layer step must be > 0");
  const double per_m = m_layer_model.packing * m_pixel * m_pixel;  // solid volume per metre of layer thickness
  const double limit = per_m * (m_depth - m_layer_model.min_aperture), step = per_m * max_layer;
  return spread(x, y, volume, [&](std::size_t k, double left) {
    double& v = m_layer[k];
    const double take = std::min({left, step, limit - v});
    v += take;
    m_lost += take / per_m / m_depth;
    return std::pair<double, bool>(take, v >= limit * kFull);
  });
}

std::vector<double> DepositGrid::aperture() const {
  std::vector<double> a(m_layer.size(), m_depth);
  const double per_m = m_layer_model.packing * m_pixel * m_pixel;
  for (std::size_t k = 0; k < a.size(); ++k) {
    if (m_grains(static_cast<Eigen::Index>(k / m_grains.cols()), static_cast<Eigen::Index>(k % m_grains.cols()))) continue;
    if (m_closed(static_cast<Eigen::Index>(k / m_grains.cols()), static_cast<Eigen::Index>(k % m_grains.cols()))) a[k] = 0.0;
    else a[k] = std::max(m_depth - m_layer[k] / per_m, 0.0);
  }
  return a;
}

void DepositGrid::save(CheckpointWriter& w) const {
  w.put(m_total);
  w.put(m_lost);
  w.put(m_closed_count);
  w.putVector(m_volume);
  w.putVector(m_layer);
  std::vector<std::uint8_t> c(static_cast<std::size_t>(m_closed.size()));
  for (Eigen::Index k = 0; k < m_closed.size(); ++k) c[static_cast<std::size_t>(k)] = m_closed(k) ? 1 : 0;
  w.putVector(c);
}

void DepositGrid::load(CheckpointReader& r) {
  m_total = r.get<double>();
  m_lost = r.get<double>();
  m_closed_count = r.get<std::int64_t>();
  auto v = r.getVector<double>();
  auto l = r.getVector<double>();
  auto c = r.getVector<std::uint8_t>();
  if (v.size() != m_volume.size() || l.size() != m_volume.size() || c.size() != m_volume.size())
    throw std::runtime_error("checkpoint " + r.name() + ": deposit grid of another size");
  m_volume = std::move(v);
  m_layer = std::move(l);
  for (Eigen::Index k = 0; k < m_closed.size(); ++k) m_closed(k) = c[static_cast<std::size_t>(k)] != 0;
}

}  // namespace mmval::particles
