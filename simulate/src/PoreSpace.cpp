#include "mmval/simulate/PoreSpace.hpp"

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

}  // namespace mmval::simulate
