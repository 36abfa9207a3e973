#include "mmval/simulate/PoreSpace.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include <fmt/format.h>

namespace mmval::simulate {

PoreSpaceReport analysePoreSpace(const BoolArray& solid, bool periodic_y) {
  const int rows = static_cast<int>(solid.rows()), cols = static_cast<int>(solid.cols());
  PoreSpaceReport rep;
  rep.solid_connected = solid;
  if (rows == 0 || cols == 0) throw NoFlowPath("the mask is empty");
  std::vector<int> label(static_cast<std::size_t>(rows) * cols, -1);
  auto at = [&](int r, int c) -> int& { return label[static_cast<std::size_t>(r) * cols + c]; };
  std::vector<int> stack;
  std::vector<char> spans;
  long long fluid = 0, connected = 0;
  for (int r0 = 0; r0 < rows; ++r0)
    for (int c0 = 0; c0 < cols; ++c0) {
      if (solid(r0, c0) || at(r0, c0) >= 0) continue;
      const int id = rep.components++;
      bool in = false, out = false;
      long long size = 0;
      stack.assign(1, r0 * cols + c0);
      at(r0, c0) = id;
      while (!stack.empty()) {
        const int k = stack.back();
        stack.pop_back();
        const int r = k / cols, c = k % cols;
        ++size;
        in = in || c == 0;
        out = out || c == cols - 1;
        const int nb[4][2] = {{r, c - 1}, {r, c + 1}, {r - 1, c}, {r + 1, c}};
        for (const auto& n : nb) {
          int rr = n[0];
          const int cc = n[1];
          if (cc < 0 || cc >= cols) continue;
          if (rr < 0 || rr >= rows) {
            if (!periodic_y) continue;
            rr = (rr + rows) % rows;
          }
          if (solid(rr, cc) || at(rr, cc) >= 0) continue;
          at(rr, cc) = id;
          stack.push_back(rr * cols + cc);
        }
      }
      fluid += size;
      spans.push_back(in && out ? 1 : 0);
      if (in && out) {
        connected += size;
        ++rep.spanning_components;
      }
    }
  const double n = static_cast<double>(rows) * cols;
  rep.porosity_total = fluid / n;
  rep.porosity_connected = connected / n;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      if (!solid(r, c) && !spans[static_cast<std::size_t>(at(r, c))]) rep.solid_connected(r, c) = true;
  if (rep.spanning_components == 0)
    throw NoFlowPath(fmt::format("no fluid path joins the inlet (left edge) to the outlet (right edge): {} pore component(s), porosity {:.3f}, none spans",
                                 rep.components, rep.porosity_total));
  return rep;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// Shortest fluid chord through every fluid pixel (see narrowestThroat), for pixels px x py.
std::vector<double> chordWidths(const BoolArray& solid, double px, double py, bool periodic_x, bool periodic_y, bool mirror_y) {
  const int rows = static_cast<int>(solid.rows()), cols = static_cast<int>(solid.cols());
  std::vector<double> width(static_cast<std::size_t>(rows) * cols, kInf);
  const auto inside = [&](int r, int c) { return r >= 0 && r < rows && c >= 0 && c < cols; };
  struct Dir {
    int dr, dc;
    double step;
    bool wrap;
  };
  const Dir dirs[] = {{0, 1, px, periodic_x}, {1, 0, py, periodic_y}, {1, 1, std::hypot(px, py), false}, {1, -1, std::hypot(px, py), false}};
  std::vector<std::pair<int, int>> line;
  for (const Dir& d : dirs) {
    // Every line of this direction starts at a pixel whose predecessor is outside the mask.
    for (int r0 = 0; r0 < rows; ++r0)
      for (int c0 = 0; c0 < cols; ++c0) {
        if (inside(r0 - d.dr, c0 - d.dc)) continue;
        line.clear();
        for (int r = r0, c = c0; inside(r, c); r += d.dr, c += d.dc) line.emplace_back(r, c);
        const std::size_t n = line.size();
        const auto fluid = [&](std::size_t k) { return !solid(line[k].first, line[k].second); };
        std::size_t first_solid = n;
        for (std::size_t k = 0; k < n; ++k)
          if (!fluid(k)) {
            first_solid = k;
            break;
          }
        if (first_solid == n) continue;  // all fluid: no chord ends on this line
        // Walk the line once (cyclically when it wraps, starting after a solid pixel), run by run.
        const std::size_t start = d.wrap ? first_solid + 1 : 0;
        std::size_t k = 0;
        while (k < n) {
          const std::size_t q = (start + k) % n;
          if (!fluid(q)) {
            ++k;
            continue;
          }
          std::size_t len = 0;
          while (k + len < n && fluid((start + k + len) % n)) ++len;
          // Reaching the mask's edge (not wrapped) means the chord is not closed by solid there, except
          // at a mirror side: the chord goes on to the solid's image, as long again.
          const bool open_start = !d.wrap && k == 0, open_end = !d.wrap && k + len == n;
          const auto mirrored = [&](std::size_t idx, int sign) {
            const int r = line[idx].first - sign * d.dr, c = line[idx].second - sign * d.dc;  // the pixel beyond the run's end
            return mirror_y && (r < 0 || r >= rows) && c >= 0 && c < cols;
          };
          double w = static_cast<double>(len) * d.step;
          if (open_start && open_end)
            w = kInf;
          else if (open_start || open_end)
            w = (open_start ? mirrored(start, 1) : mirrored((start + k + len - 1) % n, -1)) ? 2 * w : kInf;
          for (std::size_t m = 0; m < len; ++m) {
            const auto [r, c] = line[(start + k + m) % n];
            double& slot = width[static_cast<std::size_t>(r) * cols + c];
            slot = std::min(slot, w);
          }
          k += len;
        }
      }
  }
  return width;
}

Throat widestPath(const BoolArray& solid, double px, double py, bool periodic_x, bool periodic_y, double x0, double y_top, bool mirror_y = false) {
  const int rows = static_cast<int>(solid.rows()), cols = static_cast<int>(solid.cols());
  Throat t;
  if (rows == 0 || cols == 0) return t;
  const std::vector<double> width = chordWidths(solid, px, py, periodic_x, periodic_y, mirror_y);
  std::vector<int> order;
  for (int k = 0; k < rows * cols; ++k)
    if (!solid(k / cols, k % cols)) order.push_back(k);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return width[static_cast<std::size_t>(a)] > width[static_cast<std::size_t>(b)]; });
  // Union-find over the pixels switched on so far, widest first; a set records whether it touches
  // the inlet (bit 1) and the outlet (bit 2). The pixel that first joins both is the throat.
  std::vector<int> parent(static_cast<std::size_t>(rows) * cols, -1);
  std::vector<char> ends(parent.size(), 0);
  const auto find = [&](int k) {
    while (parent[static_cast<std::size_t>(k)] != k) {
      parent[static_cast<std::size_t>(k)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(k)])];
      k = parent[static_cast<std::size_t>(k)];
    }
    return k;
  };
  for (const int k : order) {
    const int r = k / cols, c = k % cols;
    parent[static_cast<std::size_t>(k)] = k;
    ends[static_cast<std::size_t>(k)] = static_cast<char>((c == 0 ? 1 : 0) | (c == cols - 1 ? 2 : 0));
    int root = k;
    const int nb[4][2] = {{r, c - 1}, {r, c + 1}, {r - 1, c}, {r + 1, c}};
    for (const auto& n : nb) {
      int rr = n[0];
      const int cc = n[1];
      if (cc < 0 || cc >= cols) continue;  // paths join the two x edges inside the mask
      if (rr < 0 || rr >= rows) {
        if (!periodic_y) continue;
        rr = (rr + rows) % rows;
      }
      const int m = rr * cols + cc;
      if (parent[static_cast<std::size_t>(m)] < 0) continue;
      const int other = find(m);
      if (other == root) continue;
      parent[static_cast<std::size_t>(other)] = root;
      ends[static_cast<std::size_t>(root)] = static_cast<char>(ends[static_cast<std::size_t>(root)] | ends[static_cast<std::size_t>(other)]);
    }
    if (ends[static_cast<std::size_t>(root)] == 3) {
      t.path = true;
      t.width_m = width[static_cast<std::size_t>(k)];
      t.x_m = x0 + (c + 0.5) * px;
      t.y_m = y_top - (r + 0.5) * py;
      return t;
    }
  }
  return t;
}

}  // namespace

Throat narrowestThroat(const BoolArray& solid, double pixel_m, bool periodic_x, bool periodic_y, double origin_x, double origin_y, bool mirror_y) {
  return widestPath(solid, pixel_m, pixel_m, periodic_x, periodic_y, origin_x, origin_y + static_cast<double>(solid.rows()) * pixel_m, mirror_y);
}

Throat narrowestThroat(const Shape& shape, double x0, double x1, double y0, double y1, double sample_m, bool periodic_x, bool periodic_y,
                       long long max_samples) {
  const double lx = x1 - x0, ly = y1 - y0;
  const double s = std::max(sample_m, std::sqrt(lx * ly / static_cast<double>(std::max(1LL, max_samples))));
  const int nx = std::max(1, static_cast<int>(std::lround(lx / s))), ny = std::max(1, static_cast<int>(std::lround(ly / s)));
  const double px = lx / nx, py = ly / ny;
  BoolArray solid(ny, nx);
  for (int r = 0; r < ny; ++r)
    for (int c = 0; c < nx; ++c) solid(r, c) = shape.solid(x0 + (c + 0.5) * px, y1 - (r + 0.5) * py);
  return widestPath(solid, px, py, periodic_x, periodic_y, x0, y1);
}

}  // namespace mmval::simulate
