// Random polydisperse disc packing of a micromodel pattern (see ChipPacking.hpp).
#include "mmval/simulate/ChipPacking.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include <fmt/format.h>

namespace mmval::simulate {

namespace {

/// Overlap (px) below which the relaxation counts the discs as separated: a tenth of a pixel
/// cannot change the rendered mask by more than a pixel here and there.
constexpr double kOverlapDonePx = 0.1;
/// Each push moves the pair a little beyond contact, so touching pairs do not re-touch at once.
constexpr double kOverPush = 1.02;
constexpr int kMaxSweeps = 3000;
constexpr double kGrowthStages[] = {0.8, 0.9, 0.95, 1.0};
constexpr int kMaxPorosityRounds = 12;

/// Uniform in [0, 1) from the top 53 bits: the same numbers on every standard library (the
/// std:: distributions are implementation-defined, which would break "same seed, same bytes").
double uniform01(std::mt19937_64& rng) { return static_cast<double>(rng() >> 11) * 0x1.0p-53; }

/// Standard normal by Box-Muller (one value per call: simpler, and the cost is nothing here).
double normal01(std::mt19937_64& rng) {
  const double u1 = 1.0 - uniform01(rng), u2 = uniform01(rng);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
}

/// Buckets of disc indices on a square grid of cell size `cell`.
class CellList {
 public:
  CellList(const std::vector<ChipDisc>& d, double cell, int cols, int rows) : m_cell(cell) {
    m_nx = std::max(1, static_cast<int>(std::ceil(cols / cell)) + 1);
    m_ny = std::max(1, static_cast<int>(std::ceil(rows / cell)) + 1);
    m_bins.assign(static_cast<std::size_t>(m_nx) * m_ny, {});
    for (std::size_t i = 0; i < d.size(); ++i) m_bins[bin(d[i].x, d[i].y)].push_back(static_cast<int>(i));
  }
  /// Calls f(j) for every disc in the 3 x 3 cells around (x, y).
  template <class F>
  void around(double x, double y, F&& f) const {
    const int cx = clampX(x), cy = clampY(y);
    for (int by = std::max(0, cy - 1); by <= std::min(m_ny - 1, cy + 1); ++by)
      for (int bx = std::max(0, cx - 1); bx <= std::min(m_nx - 1, cx + 1); ++bx)
        for (const int j : m_bins[static_cast<std::size_t>(by) * m_nx + bx]) f(j);
  }

 private:
  int clampX(double x) const { return std::clamp(static_cast<int>(std::floor(x / m_cell)), 0, m_nx - 1); }
  int clampY(double y) const { return std::clamp(static_cast<int>(std::floor(y / m_cell)), 0, m_ny - 1); }
  std::size_t bin(double x, double y) const { return static_cast<std::size_t>(clampY(y)) * m_nx + clampX(x); }
  double m_cell;
  int m_nx = 1, m_ny = 1;
  std::vector<std::vector<int>> m_bins;
};

double maxRadius(const std::vector<ChipDisc>& d) {
  double r = 0;
  for (const auto& c : d) r = std::max(r, c.r);
  return r;
}

/// Keeps a disc inside the pattern: clear of the ports, and `gap` from the walls.
void clampDisc(ChipDisc& c, const ChipPackingSpec& s) {
  const double x0 = s.port_px + c.r, x1 = s.cols - s.port_px - c.r;
  const double y0 = s.wall_px + s.min_gap_px + c.r, y1 = s.rows - s.wall_px - s.min_gap_px - c.r;
  c.x = x1 > x0 ? std::clamp(c.x, x0, x1) : 0.5 * (x0 + x1);
  c.y = y1 > y0 ? std::clamp(c.y, y0, y1) : 0.5 * (y0 + y1);
}

/// Gauss-Seidel overlap removal of the discs inflated by half the gap at their current radii;
/// returns the sweeps used, or -1 without convergence.
int relaxOnce(std::vector<ChipDisc>& d, const ChipPackingSpec& s) {
  const double half_gap = 0.5 * s.min_gap_px;
  const double cell = 2 * (maxRadius(d) + half_gap);
  for (int sweep = 1; sweep <= kMaxSweeps; ++sweep) {
    const CellList cl(d, cell, s.cols, s.rows);
    double worst = 0;
    for (std::size_t i = 0; i < d.size(); ++i) {
      cl.around(d[i].x, d[i].y, [&](int j) {
        if (static_cast<std::size_t>(j) <= i) return;
        double dx = d[j].x - d[i].x, dy = d[j].y - d[i].y;
        double dist = std::hypot(dx, dy);
        const double need = d[i].r + d[j].r + s.min_gap_px;
        if (dist >= need) return;
        if (dist < 1e-9) {  // coincident centres: a direction from the index, deterministic
          dx = std::cos(2.399963 * static_cast<double>(i));
          dy = std::sin(2.399963 * static_cast<double>(i));
          dist = 1;
        }
        const double push = 0.5 * (need - std::hypot(d[j].x - d[i].x, d[j].y - d[i].y)) * kOverPush / dist;
        worst = std::max(worst, need - std::hypot(d[j].x - d[i].x, d[j].y - d[i].y));
        d[i].x -= push * dx;
        d[i].y -= push * dy;
        d[j].x += push * dx;
        d[j].y += push * dy;
        clampDisc(d[i], s);
        clampDisc(d[j], s);
      });
    }
    if (worst < kOverlapDonePx) return sweep;
  }
  return -1;
}

/// Overlap removal with the radii grown in stages (as in Lubachevsky-Stillinger compression,
/// Lubachevsky & Stillinger 1990, J. Stat. Phys. 60, 561): from random positions, separating
/// slightly smaller discs first converges in far fewer sweeps near dense packing.
int relax(std::vector<ChipDisc>& d, const ChipPackingSpec& s) {
  int total = 0;
  for (const double f : kGrowthStages) {
    std::vector<ChipDisc> grown = d;
    for (auto& c : grown) c.r *= f;
    for (auto& c : grown) clampDisc(c, s);
    const int n = relaxOnce(grown, s);
    if (n < 0) throw std::invalid_argument(fmt::format("the grains could not be separated by the minimum gap of {:g} px in {} sweeps", s.min_gap_px, kMaxSweeps));
    total += n;
    for (std::size_t i = 0; i < d.size(); ++i) d[i].x = grown[i].x, d[i].y = grown[i].y;
  }
  return total;
}

/// Discs of lognormal diameter, drawn until they cover `grain_area` px^2, at random positions.
std::vector<ChipDisc> drawDiscs(const ChipPackingSpec& s, double grain_area, std::mt19937_64& rng) {
  const double sig2 = std::log(1 + s.diameter_cv * s.diameter_cv);
  const double mu = std::log(s.mean_diameter_px) - 0.5 * sig2;
  std::vector<ChipDisc> d;
  double area = 0;
  while (area < grain_area) {
    const double dia = std::clamp(std::exp(mu + std::sqrt(sig2) * normal01(rng)), kMinDiameterFactor * s.mean_diameter_px,
                                  kMaxDiameterFactor * s.mean_diameter_px);
    ChipDisc c;
    c.r = 0.5 * dia;
    c.x = s.port_px + uniform01(rng) * (s.cols - 2 * s.port_px);
    c.y = s.wall_px + uniform01(rng) * (s.rows - 2 * s.wall_px);
    area += M_PI * c.r * c.r;
    d.push_back(c);
  }
  return d;
}

double inflatedFraction(const std::vector<ChipDisc>& d, const ChipPackingSpec& s) {
  double a = 0;
  for (const auto& c : d) a += M_PI * (c.r + 0.5 * s.min_gap_px) * (c.r + 0.5 * s.min_gap_px);
  return a / ((s.cols - 2 * s.port_px) * (s.rows - 2 * s.wall_px));
}

double porosityOf(const BoolArray& solid) { return 1.0 - static_cast<double>(solid.count()) / static_cast<double>(solid.size()); }

}  // namespace

BoolArray renderChip(const std::vector<ChipDisc>& discs, int cols, int rows, int wall_px) {
  BoolArray solid = BoolArray::Constant(rows, cols, false);
  solid.topRows(std::min(rows, wall_px)).setConstant(true);
  solid.bottomRows(std::min(rows, wall_px)).setConstant(true);
  for (const auto& c : discs) {
    const int i0 = std::max(0, static_cast<int>(std::floor(c.x - c.r))), i1 = std::min(cols - 1, static_cast<int>(std::ceil(c.x + c.r)));
    const int j0 = std::max(0, static_cast<int>(std::floor(c.y - c.r))), j1 = std::min(rows - 1, static_cast<int>(std::ceil(c.y + c.r)));
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const double dx = i + 0.5 - c.x, dy = j + 0.5 - c.y;
        if (dx * dx + dy * dy < c.r * c.r) solid(j, i) = true;
      }
  }
  return solid;
}

ChipPacking packChip(const ChipPackingSpec& s) {
  if (s.cols < 8 || s.rows < 2 * s.wall_px + 8) throw std::invalid_argument("the chip is too small for a pattern");
  const double total = static_cast<double>(s.cols) * s.rows;
  const double wall_area = 2.0 * s.wall_px * s.cols;
  const double grain_area = (1 - s.porosity) * total - wall_area;
  if (grain_area <= 0) throw std::invalid_argument(fmt::format("the walls alone leave porosity {:.4f}", 1 - wall_area / total));
  if (kMaxDiameterFactor * s.mean_diameter_px + 2 * s.min_gap_px > s.rows - 2 * s.wall_px)
    throw std::invalid_argument("the largest grains do not fit between the walls");
  std::mt19937_64 rng(s.seed);
  ChipPacking out;
  out.discs = drawDiscs(s, grain_area, rng);
  for (int round = 1; round <= kMaxPorosityRounds; ++round) {
    if (const double f = inflatedFraction(out.discs, s); f > kMaxInflatedFraction)
      throw std::invalid_argument(fmt::format("grains inflated by half the minimum gap cover {:.3f} of the pattern (at most {:.2f} can be separated)", f,
                                              kMaxInflatedFraction));
    for (auto& c : out.discs) clampDisc(c, s);
    out.relax_sweeps = relax(out.discs, s);
    out.solid = renderChip(out.discs, s.cols, s.rows, s.wall_px);
    out.porosity_total = porosityOf(out.solid);
    out.porosity_rounds = round;
    if (std::abs(out.porosity_total - s.porosity) <= s.porosity_tolerance) return out;
    // Grain pixels scale with r^2: one multiplicative correction of every radius.
    const double grain_px = (1 - out.porosity_total) * total - wall_area;
    const double scale = std::sqrt(grain_area / std::max(1.0, grain_px));
    for (auto& c : out.discs) c.r *= scale;
  }
  throw std::invalid_argument(fmt::format("the porosity {:.4f} could not be brought within {:g} of {:g}", out.porosity_total, s.porosity_tolerance, s.porosity));
}

std::vector<ChipThroat> chipThroats(const std::vector<ChipDisc>& d, int rows, int wall_px, double max_width_px) {
  std::vector<ChipThroat> out;
  if (d.empty()) return out;
  const double rmax = maxRadius(d);
  const double cell = 2 * rmax + max_width_px;
  int cols = 0;
  for (const auto& c : d) cols = std::max(cols, static_cast<int>(std::ceil(c.x + c.r)));
  const CellList cl(d, cell, cols + 1, rows);
  const double top = wall_px, bottom = rows - wall_px;
  // A throat's midpoint must be nearer to its own two solids than to any other grain or wall.
  // own_wall: 0 none, 1 the top wall, 2 the bottom wall is one of the two solids.
  auto clear = [&](double mx, double my, double half, int a, int b, int own_wall) {
    if (own_wall != 1 && my - top < half - 1e-9) return false;
    if (own_wall != 2 && bottom - my < half - 1e-9) return false;
    bool ok = true;
    cl.around(mx, my, [&](int k) {
      if (k == a || k == b || !ok) return;
      if (std::hypot(mx - d[k].x, my - d[k].y) - d[k].r < half - 1e-9) ok = false;
    });
    return ok;
  };
  for (std::size_t i = 0; i < d.size(); ++i) {
    const int a = static_cast<int>(i);
    cl.around(d[i].x, d[i].y, [&](int j) {
      if (j <= a) return;
      const double dx = d[j].x - d[i].x, dy = d[j].y - d[i].y, dist = std::hypot(dx, dy);
      const double gap = dist - d[i].r - d[j].r;
      if (gap <= 0 || gap > max_width_px) return;
      const double t = (d[i].r + 0.5 * gap) / dist;
      const double mx = d[i].x + t * dx, my = d[i].y + t * dy;
      if (clear(mx, my, 0.5 * gap, a, j, 0)) out.push_back({gap, mx, my});
    });
    for (const double wall_y : {top, bottom}) {
      const double gap = std::abs(d[i].y - wall_y) - d[i].r;
      if (gap <= 0 || gap > max_width_px) continue;
      const double my = wall_y + (d[i].y > wall_y ? 0.5 * gap : -0.5 * gap);
      if (clear(d[i].x, my, 0.5 * gap, a, -1, wall_y == top ? 1 : 2)) out.push_back({gap, d[i].x, my});
    }
  }
  return out;
}

}  // namespace mmval::simulate
