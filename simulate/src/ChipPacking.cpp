// Random polydisperse disc packing of a micromodel pattern (see ChipPacking.hpp).
#include "mmval/simulate/ChipPacking.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <utility>
#include <stdexcept>

#include <fmt/format.h>

namespace mmval::simulate {

namespace {

/// Overlap (px) below which the relaxation counts the discs as separated: a tenth of a pixel
/// cannot change the rendered mask by more than a pixel here and there.
constexpr double kOverlapDonePx = 0.1;
/// Rendered gaps are lattice values (pixelSquareGap): a gap within this of the minimum keeps it
/// (a --min-throat-px of 3 is met by squares exactly 3 px apart despite rounding).
constexpr double kGapSlackPx = 1e-9;
/// Each push moves the pair a little beyond contact, so touching pairs do not re-touch at once.
constexpr double kOverPush = 1.02;
constexpr int kMaxSweeps = 3000;
constexpr double kGrowthStages[] = {0.8, 0.9, 0.95, 1.0};
constexpr int kMaxPorosityRounds = 12;
/// Positions a disc tries in random sequential addition before it is left to the jittered grid.
/// Near RSA saturation the free area falls steeply (as (theta_J - theta)^3 for discs, Pomeau 1980,
/// J. Phys. A 13, L193; Swendsen 1981, Phys. Rev. A 24, 504), so more attempts add little coverage
/// for much time.
constexpr int kRsaAttempts = 200;
/// Discs in a row that found no room: the pattern is saturated (the free area is below ~1 / 200
/// of it), and the rest go to the jittered grid without trying.
constexpr int kRsaStopFailures = 50;

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
  /// An empty grid over cols x rows px.
  CellList(double cell, int cols, int rows) : m_cell(cell) {
    m_nx = std::max(1, static_cast<int>(std::ceil(cols / cell)) + 1);
    m_ny = std::max(1, static_cast<int>(std::ceil(rows / cell)) + 1);
    m_bins.assign(static_cast<std::size_t>(m_nx) * m_ny, {});
  }
  CellList(const std::vector<ChipDisc>& d, double cell, int cols, int rows) : CellList(cell, cols, rows) {
    for (std::size_t i = 0; i < d.size(); ++i) insert(static_cast<int>(i), d[i].x, d[i].y);
  }
  void insert(int i, double x, double y) { m_bins[bin(x, y)].push_back(i); }
  /// Calls f(j) for every disc in the 3 x 3 cells around (x, y).
  template <class F>
  void around(double x, double y, F&& f) const {
    within(x, y, m_cell, f);
  }
  /// Calls f(j) for every disc in the cells that reach within `reach` of (x, y) (and a few more).
  template <class F>
  void within(double x, double y, double reach, F&& f) const {
    const int cx = clampX(x), cy = clampY(y), n = std::max(1, static_cast<int>(std::ceil(reach / m_cell)));
    for (int by = std::max(0, cy - n); by <= std::min(m_ny - 1, cy + n); ++by)
      for (int bx = std::max(0, cx - n); bx <= std::min(m_nx - 1, cx + n); ++bx)
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

/// Where a disc's centre may lie: clear of the ports, and the gap from the walls.
struct CentreRange {
  double x0, x1, y0, y1;
};
CentreRange centreRange(const ChipDisc& c, const ChipPackingSpec& s) {
  // Mirror sides (wall_px 0): half the gap from the edge, so the throat to the disc's own mirror
  // image is the gap, and every other disc's image is at least the gap away too (both centres
  // are at least r + gap / 2 from the plane).
  const double edge = s.wall_px > 0 ? s.wall_px + s.min_gap_px : 0.5 * s.min_gap_px;
  return {s.port_px + c.r, s.cols - s.port_px - c.r, edge + c.r, s.rows - edge - c.r};
}

/// Keeps a disc inside the pattern: clear of the ports, and `gap` from the walls.
void clampDisc(ChipDisc& c, const ChipPackingSpec& s) {
  const CentreRange r = centreRange(c, s);
  c.x = r.x1 > r.x0 ? std::clamp(c.x, r.x0, r.x1) : 0.5 * (r.x0 + r.x1);
  c.y = r.y1 > r.y0 ? std::clamp(c.y, r.y0, r.y1) : 0.5 * (r.y0 + r.y1);
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

/// Discs of lognormal diameter, drawn until they cover `grain_area` px^2, each with a position
/// uniform at random in the pattern (the Poisson start; the uniform start replaces the positions).
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

/// Random sequential addition, largest disc first: each disc tries up to kRsaAttempts uniform
/// positions and keeps the first at least the gap from every disc placed so far. A disc that finds
/// none is left to the jittered grid (smaller discs after it may still fit); after
/// kRsaStopFailures such discs in a row the pattern is saturated and every disc left goes to the
/// grid. Both rules are per disc, so the share placed by RSA does not depend on the chip's size.
/// Returns the discs left over, in `order`'s order.
std::vector<int> placeBySequentialAddition(std::vector<ChipDisc>& d, const std::vector<int>& order, const ChipPackingSpec& s, std::mt19937_64& rng) {
  const double rmax = maxRadius(d);
  double mean_r = 0;
  for (const auto& c : d) mean_r += c.r / static_cast<double>(d.size());
  // Cells of one mean inflated diameter: a query scans the cells within its reach (r + rmax + gap).
  CellList grid(2 * mean_r + s.min_gap_px, s.cols, s.rows);
  std::vector<int> left;
  int failures_in_a_row = 0;
  for (const int i : order) {
    ChipDisc& c = d[static_cast<std::size_t>(i)];
    if (failures_in_a_row >= kRsaStopFailures) {
      left.push_back(i);
      continue;
    }
    const CentreRange cr = centreRange(c, s);
    const double reach = c.r + rmax + s.min_gap_px;
    bool found = false;
    for (int attempt = 0; attempt < kRsaAttempts && !found; ++attempt) {
      const double x = cr.x0 + uniform01(rng) * std::max(0.0, cr.x1 - cr.x0), y = cr.y0 + uniform01(rng) * std::max(0.0, cr.y1 - cr.y0);
      bool clear = true;
      grid.within(x, y, reach, [&](int j) {
        if (!clear) return;
        const double need = c.r + d[static_cast<std::size_t>(j)].r + s.min_gap_px;
        const double dx = x - d[static_cast<std::size_t>(j)].x, dy = y - d[static_cast<std::size_t>(j)].y;
        if (dx * dx + dy * dy < need * need) clear = false;
      });
      if (clear) {
        c.x = x;
        c.y = y;
        grid.insert(i, x, y);
        found = true;
      }
    }
    failures_in_a_row = found ? 0 : failures_in_a_row + 1;
    if (!found) left.push_back(i);
  }
  return left;
}

/// The discs RSA could not place, one per cell of a jittered grid over the pattern (stratified
/// sampling: one disc per cell of equal area, at a uniform position inside it), the cells chosen
/// at random when there are more cells than discs. The relaxation then separates them.
void placeOnJitteredGrid(std::vector<ChipDisc>& d, const std::vector<int>& rest, const ChipPackingSpec& s, std::mt19937_64& rng) {
  if (rest.empty()) return;
  const double w = s.cols - 2 * s.port_px, h = s.rows - 2 * s.wall_px;
  const auto m = static_cast<double>(rest.size());
  const int nx = std::max(1, static_cast<int>(std::lround(std::sqrt(m * w / h))));
  const int ny = std::max(1, static_cast<int>(std::ceil(m / nx)));
  std::vector<int> cells(static_cast<std::size_t>(nx) * ny);
  for (std::size_t k = 0; k < cells.size(); ++k) cells[k] = static_cast<int>(k);
  // Fisher-Yates with our own uniform numbers (std::shuffle is implementation-defined).
  for (std::size_t k = cells.size(); k > 1; --k)
    std::swap(cells[k - 1], cells[std::min(k - 1, static_cast<std::size_t>(uniform01(rng) * static_cast<double>(k)))]);
  for (std::size_t k = 0; k < rest.size(); ++k) {
    ChipDisc& c = d[static_cast<std::size_t>(rest[k])];
    const int cx = cells[k] % nx, cy = cells[k] / nx;
    c.x = s.port_px + (cx + uniform01(rng)) * w / nx;
    c.y = s.wall_px + (cy + uniform01(rng)) * h / ny;
  }
}

/// The uniform start: random sequential addition of the discs, largest first, with the gap rule,
/// then the rest on a jittered grid (see ChipPacking.hpp for why). Returns the discs RSA placed.
std::size_t placeUniformly(std::vector<ChipDisc>& d, const ChipPackingSpec& s, std::mt19937_64& rng) {
  std::vector<int> order(d.size());
  for (std::size_t i = 0; i < d.size(); ++i) order[i] = static_cast<int>(i);
  // Largest first, ties by index: a total order, so the same on every standard library.
  std::sort(order.begin(), order.end(), [&d](int a, int b) {
    const double ra = d[static_cast<std::size_t>(a)].r, rb = d[static_cast<std::size_t>(b)].r;
    return ra > rb || (ra == rb && a < b);
  });
  const std::vector<int> left = placeBySequentialAddition(d, order, s, rng);
  placeOnJitteredGrid(d, left, s, rng);
  return d.size() - left.size();
}

double inflatedFraction(const std::vector<ChipDisc>& d, const ChipPackingSpec& s) {
  double a = 0;
  for (const auto& c : d) a += M_PI * (c.r + 0.5 * s.min_gap_px) * (c.r + 0.5 * s.min_gap_px);
  return a / ((s.cols - 2 * s.port_px) * (s.rows - 2 * s.wall_px));
}

double porosityOf(const BoolArray& solid) { return 1.0 - static_cast<double>(solid.count()) / static_cast<double>(solid.size()); }

}  // namespace

double pixelSquareGap(int di, int dj) {
  return std::hypot(std::max(0, std::abs(di) - 1), std::max(0, std::abs(dj) - 1));
}

namespace {

/// Offsets (di, dj) to the pixels whose squares are closer than `gap` to a pixel's (itself excluded).
std::vector<std::pair<int, int>> offsetsCloserThan(double gap) {
  std::vector<std::pair<int, int>> out;
  const int reach = static_cast<int>(std::ceil(gap)) + 1;
  for (int dj = -reach; dj <= reach; ++dj)
    for (int di = -reach; di <= reach; ++di)
      if ((di != 0 || dj != 0) && pixelSquareGap(di, dj) < gap - kGapSlackPx) out.emplace_back(di, dj);
  return out;
}

/// Whether grain pixel row j is closer than `gap` to a wall row (wall_px > 0) or, with mirror
/// sides, closer than gap / 2 to an edge (its gap to its own image is twice that).
bool tooNearSide(int j, int rows, int wall_px, double gap) {
  if (wall_px > 0) return j - wall_px < gap - kGapSlackPx || (rows - wall_px) - (j + 1) < gap - kGapSlackPx;
  return 2.0 * j < gap - kGapSlackPx || 2.0 * (rows - 1 - j) < gap - kGapSlackPx;
}

}  // namespace

ChipLabels renderChipLabels(const std::vector<ChipDisc>& discs, int cols, int rows, int wall_px, double min_gap_px, double grow_px, int* cleared) {
  ChipLabels label = ChipLabels::Constant(rows, cols, -1);
  for (std::size_t k = 0; k < discs.size(); ++k) {
    const ChipDisc& c = discs[k];
    const double r = c.r + grow_px;
    const int i0 = std::max(0, static_cast<int>(std::floor(c.x - r))), i1 = std::min(cols - 1, static_cast<int>(std::ceil(c.x + r)));
    const int j0 = std::max(0, static_cast<int>(std::floor(c.y - r))), j1 = std::min(rows - 1, static_cast<int>(std::ceil(c.y + r)));
    for (int j = j0; j <= j1; ++j)
      for (int i = i0; i <= i1; ++i) {
        const double dx = i + 0.5 - c.x, dy = j + 0.5 - c.y;
        if (dx * dx + dy * dy < r * r) label(j, i) = static_cast<int>(k);
      }
  }
  int n_cleared = 0;
  if (min_gap_px > 0) {
    const auto offsets = offsetsCloserThan(min_gap_px);
    const auto depth = [&](int i, int j) {
      const ChipDisc& c = discs[static_cast<std::size_t>(label(j, i))];
      return c.r - std::hypot(i + 0.5 - c.x, j + 0.5 - c.y);
    };
    // Clearing only removes grain, so a gap once kept stays kept; each pass clears at least one
    // pixel or finds none to clear, and the passes end.
    for (bool changed = true; changed;) {
      changed = false;
      for (int i = 0; i < cols; ++i)
        for (int j = 0; j < rows; ++j) {
          const int a = label(j, i);
          if (a < 0) continue;
          if (tooNearSide(j, rows, wall_px, min_gap_px)) {
            label(j, i) = -1, ++n_cleared, changed = true;
            continue;
          }
          for (const auto& [di, dj] : offsets) {
            const int i2 = i + di, j2 = j + dj;
            if (i2 < 0 || i2 >= cols || j2 < 0 || j2 >= rows) continue;
            const int b = label(j2, i2);
            if (b < 0 || b == a) continue;
            const double da = depth(i, j), db = depth(i2, j2);
            // The shallower pixel goes; on a tie the later one in column-major order.
            const bool clear_self = da < db || (da == db && (i > i2 || (i == i2 && j > j2)));
            ++n_cleared, changed = true;
            if (clear_self) {
              label(j, i) = -1;
              break;
            }
            label(j2, i2) = -1;
          }
        }
    }
  }
  if (cleared) *cleared = n_cleared;
  return label;
}

namespace {
BoolArray solidOf(const ChipLabels& label, int wall_px) {
  const int rows = static_cast<int>(label.rows());
  BoolArray solid = label >= 0;
  solid.topRows(std::min(rows, wall_px)).setConstant(true);
  solid.bottomRows(std::min(rows, wall_px)).setConstant(true);
  return solid;
}
}  // namespace

BoolArray renderChip(const std::vector<ChipDisc>& discs, int cols, int rows, int wall_px, double min_gap_px, double grow_px) {
  return solidOf(renderChipLabels(discs, cols, rows, wall_px, min_gap_px, grow_px), wall_px);
}

int renderedGapViolations(const ChipLabels& label, int wall_px, double min_gap_px) {
  const int rows = static_cast<int>(label.rows()), cols = static_cast<int>(label.cols());
  const auto offsets = offsetsCloserThan(min_gap_px);
  std::set<std::pair<int, int>> pairs;
  for (int i = 0; i < cols; ++i)
    for (int j = 0; j < rows; ++j) {
      const int a = label(j, i);
      if (a < 0) continue;
      if (tooNearSide(j, rows, wall_px, min_gap_px)) pairs.emplace(a, 2 * j < rows ? kThroatTopWall : kThroatBottomWall);
      for (const auto& [di, dj] : offsets) {
        const int i2 = i + di, j2 = j + dj;
        if (i2 < 0 || i2 >= cols || j2 < 0 || j2 >= rows) continue;
        if (const int b = label(j2, i2); b >= 0 && b > a) pairs.emplace(a, b);
      }
    }
  return static_cast<int>(pairs.size());
}

namespace {
/// Bisection steps on the growth; the porosity moves by whole pixels, so it settles well before.
constexpr int kGrowSteps = 16;
/// Growth searched, px: a pixel square reaches at most 0.71 px past its disc, so clearing never
/// removes more than a growth of that order puts back.
constexpr double kMaxGrowPx = 1.0;

/// The final rendering: pixel centres within r + grow_px of a disc, then the pixels that break the
/// minimum gap cleared (renderChipLabels), with grow_px >= 0 the smallest the bisection finds
/// whose porosity is nearest the target (clearing opens pores; the growth closes as many
/// elsewhere, so the discs need no rescaling and no second relaxation).
void renderKeepingTheGap(ChipPacking& out, const ChipPackingSpec& s) {
  const auto at = [&](double grow, ChipPacking& p) {
    p.labels = renderChipLabels(p.discs, s.cols, s.rows, s.wall_px, s.min_gap_px, grow, &p.cleared_px);
    p.solid = solidOf(p.labels, s.wall_px);
    p.porosity_total = porosityOf(p.solid);
    p.render_grow_px = grow;
  };
  at(0, out);
  if (out.porosity_total <= s.porosity) return;
  // The rendering is a function of the growth alone: the best one is kept as its growth and
  // rendered again at the end if the search moved past it (no copies of the chip-sized arrays).
  double best_grow = 0, best_error = std::abs(out.porosity_total - s.porosity);
  double lo = 0, hi = kMaxGrowPx;
  for (int step = 0; step < kGrowSteps && best_error > 0.1 * s.porosity_tolerance; ++step) {
    const double mid = 0.5 * (lo + hi);
    at(mid, out);
    if (const double e = std::abs(out.porosity_total - s.porosity); e < best_error) best_grow = mid, best_error = e;
    (out.porosity_total > s.porosity ? lo : hi) = mid;
  }
  if (out.render_grow_px != best_grow) at(best_grow, out);
}
}  // namespace

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
  out.sequentially_added = s.placement == ChipPlacement::uniform ? static_cast<int>(placeUniformly(out.discs, s, rng)) : 0;
  for (int round = 1; round <= kMaxPorosityRounds; ++round) {
    if (const double f = inflatedFraction(out.discs, s); f > kMaxInflatedFraction)
      throw std::invalid_argument(fmt::format("grains inflated by half the minimum gap cover {:.3f} of the pattern (at most {:.2f} can be separated)", f,
                                              kMaxInflatedFraction));
    for (auto& c : out.discs) clampDisc(c, s);
    out.relax_sweeps = relax(out.discs, s);
    // The discs' scale is set on the centre rule alone (the rendering before the gap is kept);
    // then the kept-gap rendering meets the porosity by its growth (renderKeepingTheGap).
    out.porosity_total = porosityOf(renderChip(out.discs, s.cols, s.rows, s.wall_px));
    out.porosity_rounds = round;
    if (std::abs(out.porosity_total - s.porosity) <= s.porosity_tolerance) {
      renderKeepingTheGap(out, s);
      if (std::abs(out.porosity_total - s.porosity) > s.porosity_tolerance)
        throw std::invalid_argument(fmt::format("the porosity {:.4f} of the rendering that keeps the minimum gap could not be brought within {:g} of {:g}",
                                                out.porosity_total, s.porosity_tolerance, s.porosity));
      out.homogeneity = windowPorosity(out.solid, out.discs, s, static_cast<int>(std::lround(kHomogeneityWindowDiameters * s.mean_diameter_px)));
      return out;
    }
    // Grain pixels scale with r^2: one multiplicative correction of every radius.
    const double grain_px = (1 - out.porosity_total) * total - wall_area;
    const double scale = std::sqrt(grain_area / std::max(1.0, grain_px));
    for (auto& c : out.discs) c.r *= scale;
  }
  throw std::invalid_argument(fmt::format("the porosity {:.4f} could not be brought within {:g} of {:g}", out.porosity_total, s.porosity_tolerance, s.porosity));
}

ChipWindowPorosity windowPorosity(const BoolArray& solid, const std::vector<ChipDisc>& discs, const ChipPackingSpec& s, int side_px) {
  ChipWindowPorosity w;
  w.side_px = side_px;
  const int x_lo = static_cast<int>(std::ceil(s.port_px)), x_hi = static_cast<int>(solid.cols()) - x_lo;
  const int y_lo = s.wall_px, y_hi = static_cast<int>(solid.rows()) - s.wall_px;
  if (side_px < 1 || x_hi - x_lo < side_px || y_hi - y_lo < side_px) return w;
  const int nx = (x_hi - x_lo) / side_px, ny = (y_hi - y_lo) / side_px;
  const int x0 = x_lo + (x_hi - x_lo - nx * side_px) / 2, y0 = y_lo + (y_hi - y_lo - ny * side_px) / 2;
  const double area = static_cast<double>(side_px) * side_px;
  std::vector<double> phi;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) phi.push_back(1.0 - static_cast<double>(solid.block(y0 + j * side_px, x0 + i * side_px, side_px, side_px).count()) / area);
  w.count = static_cast<int>(phi.size());
  w.min = *std::min_element(phi.begin(), phi.end());
  w.max = *std::max_element(phi.begin(), phi.end());
  for (const double v : phi) w.mean += v / w.count;
  for (const double v : phi) w.sd += (v - w.mean) * (v - w.mean);
  w.sd = w.count > 1 ? std::sqrt(w.sd / (w.count - 1)) : 0.0;
  const double p = area / (static_cast<double>(x_hi - x_lo) * (y_hi - y_lo));
  double sum_a2 = 0;
  for (const auto& c : discs) sum_a2 += std::pow(M_PI * c.r * c.r, 2);
  w.poisson_sd = std::sqrt(p * (1 - p) * sum_a2) / area;
  return w;
}

namespace {
/// chipThroats with mirror sides: the throats between the discs and the mirror images of those
/// near the edges, a disc's own image included (twice its distance to the edge), with the
/// midpoint within the pattern (the mirrored pair of a throat across a plane is counted once).
std::vector<ChipThroat> mirrorThroats(const std::vector<ChipDisc>& d, int rows, double max_width_px) {
  std::vector<ChipThroat> out;
  const double rmax = maxRadius(d), near = 2 * rmax + max_width_px;
  std::vector<ChipDisc> e = d;
  std::vector<int> origin(d.size()), side(d.size(), 0);
  for (std::size_t i = 0; i < d.size(); ++i) origin[i] = static_cast<int>(i);
  for (std::size_t i = 0; i < d.size(); ++i) {
    if (d[i].y < near) e.push_back({d[i].x, -d[i].y, d[i].r}), origin.push_back(static_cast<int>(i)), side.push_back(-1);
    if (rows - d[i].y < near) e.push_back({d[i].x, 2.0 * rows - d[i].y, d[i].r}), origin.push_back(static_cast<int>(i)), side.push_back(1);
  }
  const auto n = static_cast<int>(d.size());
  int cols = 0;
  for (const auto& c : d) cols = std::max(cols, static_cast<int>(std::ceil(c.x + c.r)));
  const CellList cl(e, 2 * rmax + max_width_px, cols + 1, rows);  // images fall in the edge bins (clamped)
  const auto clear = [&](double mx, double my, double half, int a, int b) {
    bool ok = true;
    cl.around(mx, my, [&](int k) {
      if (k == a || k == b || !ok) return;
      if (std::hypot(mx - e[k].x, my - e[k].y) - e[k].r < half - 1e-9) ok = false;
    });
    return ok;
  };
  for (int a = 0; a < n; ++a)
    cl.around(e[a].x, e[a].y, [&](int b) {
      if (b == a || (b < n && b < a)) return;  // each pair once; a disc with an image as often as it has one
      const double dx = e[b].x - e[a].x, dy = e[b].y - e[a].y, dist = std::hypot(dx, dy);
      const double gap = dist - e[a].r - e[b].r;
      if (gap <= 0 || gap > max_width_px) return;
      const double t = (e[a].r + 0.5 * gap) / dist;
      const double mx = e[a].x + t * dx, my = e[a].y + t * dy;
      // Across a plane: the disc with its own image (midpoint on the plane), or with another's
      // image, counted where the midpoint lies inside (its mirror pair's lies outside).
      if (b >= n && origin[static_cast<std::size_t>(b)] != a && !(my > 0 && my < rows)) return;
      if (clear(mx, my, 0.5 * gap, a, b)) out.push_back({gap, mx, my, a, origin[static_cast<std::size_t>(b)], side[static_cast<std::size_t>(b)]});
    });
  return out;
}
}  // namespace

std::vector<ChipThroat> chipThroats(const std::vector<ChipDisc>& d, int rows, int wall_px, double max_width_px) {
  std::vector<ChipThroat> out;
  if (d.empty()) return out;
  if (wall_px == 0) return mirrorThroats(d, rows, max_width_px);
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
      if (clear(mx, my, 0.5 * gap, a, j, 0)) out.push_back({gap, mx, my, a, j, 0});
    });
    for (const double wall_y : {top, bottom}) {
      const double gap = std::abs(d[i].y - wall_y) - d[i].r;
      if (gap <= 0 || gap > max_width_px) continue;
      const double my = wall_y + (d[i].y > wall_y ? 0.5 * gap : -0.5 * gap);
      if (clear(d[i].x, my, 0.5 * gap, a, -1, wall_y == top ? 1 : 2))
        out.push_back({gap, d[i].x, my, a, wall_y == top ? kThroatTopWall : kThroatBottomWall, 0});
    }
  }
  return out;
}

std::vector<double> renderedThroatWidths(const std::vector<ChipThroat>& throats, const ChipLabels& label, int wall_px) {
  const int rows = static_cast<int>(label.rows()), cols = static_cast<int>(label.cols());
  // Each grain's boundary pixels (a 4-neighbour not of the grain): the nearest point of a union of
  // squares to anything outside it lies on an edge of one of them.
  int n = 0;
  for (const auto& t : throats) n = std::max({n, t.a + 1, t.b + 1});
  std::vector<std::vector<std::pair<int, int>>> edge(static_cast<std::size_t>(n));
  const auto same = [&](int i, int j, int a) { return i >= 0 && i < cols && j >= 0 && j < rows && label(j, i) == a; };
  for (int i = 0; i < cols; ++i)
    for (int j = 0; j < rows; ++j) {
      const int a = label(j, i);
      if (a < 0 || a >= n) continue;
      if (!same(i - 1, j, a) || !same(i + 1, j, a) || !same(i, j - 1, a) || !same(i, j + 1, a)) edge[static_cast<std::size_t>(a)].emplace_back(i, j);
    }
  std::vector<double> out;
  out.reserve(throats.size());
  for (const auto& t : throats) {
    const auto& ea = edge[static_cast<std::size_t>(t.a)];
    double w = std::numeric_limits<double>::infinity();
    if (t.b == kThroatTopWall || t.b == kThroatBottomWall) {
      for (const auto& [i, j] : ea) w = std::min<double>(w, t.b == kThroatTopWall ? j - wall_px : (rows - wall_px) - (j + 1));
    } else {
      const auto& eb = edge[static_cast<std::size_t>(t.b)];
      for (const auto& [i1, j1] : ea)
        for (const auto& [i2, j2] : eb) {
          // An image across the top edge has row -1 - j2, across the bottom 2 rows - 1 - j2.
          const int j2_image = t.mirror < 0 ? -1 - j2 : t.mirror > 0 ? 2 * rows - 1 - j2 : j2;
          w = std::min(w, pixelSquareGap(i1 - i2, j1 - j2_image));
        }
    }
    out.push_back(std::isfinite(w) ? w : std::numeric_limits<double>::quiet_NaN());
  }
  return out;
}

}  // namespace mmval::simulate
