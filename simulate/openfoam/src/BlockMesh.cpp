#include "mmval/openfoam/BlockMesh.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/openfoam/FoamFile.hpp"

namespace mmval::openfoam {

long long BlockMeshDict::cellCount() const {
  long long n = 0;
  for (const auto& b : blocks) n += static_cast<long long>(b.cells[0]) * b.cells[1] * b.cells[2];
  return n;
}

std::string BlockMeshDict::text() const {
  std::string out = foamHeader("dictionary", "blockMeshDict", "system");
  out += "scale 1;\n\nvertices\n(\n";
  for (std::size_t i = 0; i < vertices.size(); ++i)
    out += fmt::format("    ({:.12g} {:.12g} {:.12g}) // {}\n", vertices[i].x, vertices[i].y, vertices[i].z, i);
  out += ");\n\nblocks\n(\n";
  for (const auto& b : blocks)
    out += fmt::format("    hex ({} {} {} {} {} {} {} {}) ({} {} {}) simpleGrading ({:.12g} {:.12g} {:.12g})\n", b.v[0], b.v[1],
                       b.v[2], b.v[3], b.v[4], b.v[5], b.v[6], b.v[7], b.cells[0], b.cells[1], b.cells[2], b.grading[0],
                       b.grading[1], b.grading[2]);
  out += ");\n\nedges\n(\n";
  for (const auto& e : arcs)
    out += fmt::format("    arc {} {} ({:.12g} {:.12g} {:.12g})\n", e.from, e.to, e.through.x, e.through.y, e.through.z);
  out += ");\n\nboundary\n(\n";
  for (const auto& p : patches) {
    out += fmt::format("    {}\n    {{\n        type {};\n", p.name, p.type);
    if (!p.neighbour.empty()) out += fmt::format("        neighbourPatch {};\n", p.neighbour);
    out += "        faces\n        (\n";
    for (const auto& f : p.faces) out += fmt::format("            ({} {} {} {})\n", f[0], f[1], f[2], f[3]);
    out += "        );\n    }\n";
  }
  out += ");\n\nmergePatchPairs\n(\n);\n";
  return out;
}

namespace {

/// Builds 2D block layouts: vertices are added in the z = 0 plane and
/// mirrored at z = depth; faces are given by their z = 0 edge.
class Builder {
 public:
  explicit Builder(double depth) : m_depth(depth) {}
  int vertex(double x, double y) {
    for (std::size_t i = 0; i < m_base.size(); ++i)
      if (std::abs(m_base[i].x - x) < 1e-12 && std::abs(m_base[i].y - y) < 1e-12) return static_cast<int>(i);
    m_base.push_back({x, y, 0});
    return static_cast<int>(m_base.size() - 1);
  }
  /// Quad a-b-c-d counter-clockwise seen from +z.
  void block(int a, int b, int c, int d, int n1, int n2, double g1 = 1, double g2 = 1) {
    m_blocks.push_back({{a, b, c, d, a, b, c, d}, {n1, n2, 1}, {g1, g2, 1}});
  }
  void arc(int a, int b, double x, double y) { m_arcs.push_back({a, b, {x, y, 0}}); }
  /// Boundary edge a-b of the 2D layout, as a face of patch `name`.
  void face(const std::string& name, int a, int b) { m_faces.push_back({name, a, b}); }

  BlockMeshDict finish(const std::vector<Patch>& patch_types) {
    const int n = static_cast<int>(m_base.size());
    BlockMeshDict d;
    d.vertices = m_base;
    for (auto p : m_base) {
      p.z = m_depth;
      d.vertices.push_back(p);
    }
    for (auto b : m_blocks) {
      for (int k = 4; k < 8; ++k) b.v[k] += n;
      d.blocks.push_back(b);
    }
    for (const auto& a : m_arcs) {
      d.arcs.push_back(a);
      d.arcs.push_back({a.from + n, a.to + n, {a.through.x, a.through.y, m_depth}});
    }
    for (auto p : patch_types) {
      for (const auto& f : m_faces)
        if (f.patch == p.name) p.faces.push_back({f.a, f.b, f.b + n, f.a + n});
      if (p.type == "empty")
        for (const auto& b : m_blocks) {
          p.faces.push_back({b.v[0], b.v[3], b.v[2], b.v[1]});
          p.faces.push_back({b.v[0] + n, b.v[1] + n, b.v[2] + n, b.v[3] + n});
        }
      if (p.faces.empty()) throw std::logic_error("blockMesh patch '" + p.name + "' has no faces");
      d.patches.push_back(p);
    }
    return d;
  }

 private:
  struct Face {
    std::string patch;
    int a, b;
  };
  double m_depth;
  std::vector<Point> m_base;
  std::vector<Block> m_blocks;
  std::vector<ArcEdge> m_arcs;
  std::vector<Face> m_faces;
};

}  // namespace

BlockMeshDict channelMesh(double length, double height, double depth, int nx, int ny, const std::string& side_type) {
  if (nx < 1 || ny < 1 || length <= 0 || height <= 0) throw std::invalid_argument("channelMesh: bad size or resolution");
  Builder b(depth);
  const int v0 = b.vertex(0, 0), v1 = b.vertex(length, 0), v2 = b.vertex(length, height), v3 = b.vertex(0, height);
  b.block(v0, v1, v2, v3, nx, ny);
  b.face("inlet", v3, v0);
  b.face("outlet", v1, v2);
  b.face("walls", v0, v1);
  b.face("walls", v2, v3);
  return b.finish({{"inlet", "patch", {}, {}}, {"outlet", "patch", {}, {}}, {"walls", side_type, {}, {}}, {"frontAndBack", "empty", {}, {}}});
}

namespace {
/// A cylinder channel's side farther than this many diameters from the O-grid's box is far field.
constexpr double kFarFieldSide = 16.0;
/// A far-field side's cells grow by this side's length / (kFarFieldGrowthLength D), at most 4x.
constexpr double kFarFieldGrowthLength = 10.0;
}  // namespace

BlockMeshDict cylinderChannelMesh(const CylinderChannel& g, int n, double radial_grading) {
  if (n < 4 || n % 4 != 0) throw std::invalid_argument("cylinderChannelMesh: cells_around must be a multiple of 4");
  const double r = 0.5 * g.diameter;
  const double a = std::min({2 * r, g.cx - 1e-3 * r, g.cy - 1e-3 * r, g.height - g.cy - 1e-3 * r});  // half side of the box
  if (a <= r * 1.2) throw std::invalid_argument("cylinderChannelMesh: cylinder too close to the channel walls or inlet");
  const int nt = n / 4;                         // cells along each side of the box
  const double h = 2 * a / nt;                  // cell size at the box
  const int nr = std::max(4, nt);               // radial cells
  const double x0 = g.cx - a, x1 = g.cx + a, y0 = g.cy - a, y1 = g.cy + a;
  const double L = g.length, H = g.height;
  const double s = r / std::sqrt(2.0);

  Builder b(g.depth);
  // Box corners, cylinder points at 45 degrees, outer frame.
  const int S0 = b.vertex(x0, y0), S1 = b.vertex(x1, y0), S2 = b.vertex(x1, y1), S3 = b.vertex(x0, y1);
  const int C0 = b.vertex(g.cx - s, g.cy - s), C1 = b.vertex(g.cx + s, g.cy - s), C2 = b.vertex(g.cx + s, g.cy + s),
            C3 = b.vertex(g.cx - s, g.cy + s);
  const int A0 = b.vertex(0, 0), A1 = b.vertex(x0, 0), A2 = b.vertex(x1, 0), A3 = b.vertex(L, 0);
  const int B0 = b.vertex(0, y0), B3 = b.vertex(L, y0);
  const int D0 = b.vertex(0, y1), D3 = b.vertex(L, y1);
  const int E0 = b.vertex(0, H), E1 = b.vertex(x0, H), E2 = b.vertex(x1, H), E3 = b.vertex(L, H);

  const double gr = 1.0 / radial_grading;  // radial direction runs from the box to the cylinder
  b.block(S0, S1, C1, C0, nt, nr, 1, gr);  // below
  b.block(S1, S2, C2, C1, nt, nr, 1, gr);  // right
  b.block(S2, S3, C3, C2, nt, nr, 1, gr);  // above
  b.block(S3, S0, C0, C3, nt, nr, 1, gr);  // left
  b.arc(C0, C1, g.cx, g.cy - r);
  b.arc(C1, C2, g.cx + r, g.cy);
  b.arc(C2, C3, g.cx, g.cy + r);
  b.arc(C3, C0, g.cx - r, g.cy);

  // Downstream: cells grow geometrically from h to at most 4h.
  const double right = L - x1;
  const double expand = std::min(4.0, std::max(1.0, right / (40 * h)));
  // Upstream and across: uniform cells of h in a channel; a far-field side (more than
  // kFarFieldSide diameters from the box, unconfined flow) grows its cells geometrically from the
  // box to the boundary by len / (kFarFieldGrowthLength D), at most 4x, the same at every level
  // (the confined benchmarks' sides, at most ~15 D, keep their uniform cells). The cell counts
  // take the mean cell as (1 + e) h / 2, as downstream.
  const auto side = [&](double len) { return len > kFarFieldSide * g.diameter ? std::min(4.0, len / (kFarFieldGrowthLength * g.diameter)) : 1.0; };
  const double e_left = side(x0), e_bottom = side(y0), e_top = side(H - y1);
  const auto graded = [&](double len, double e) { return std::max(1, static_cast<int>(std::lround(len / (h * 0.5 * (1 + e))))); };
  const int nl = graded(x0, e_left), nb = graded(y0, e_bottom), ntop = graded(H - y1, e_top), nright = graded(right, expand);
  b.block(A0, A1, S0, B0, nl, nb, 1 / e_left, 1 / e_bottom);  // lower left
  b.block(B0, S0, S3, D0, nl, nt, 1 / e_left, 1);             // left
  b.block(D0, S3, E1, E0, nl, ntop, 1 / e_left, e_top);       // upper left
  b.block(A1, A2, S1, S0, nt, nb, 1, 1 / e_bottom);           // below the box
  b.block(S3, S2, E2, E1, nt, ntop, 1, e_top);                // above the box
  b.block(A2, A3, B3, S1, nright, nb, expand, 1 / e_bottom);  // lower right
  b.block(S1, B3, D3, S2, nright, nt, expand, 1);             // right
  b.block(S2, D3, E3, E2, nright, ntop, expand, e_top);       // upper right

  for (auto [p, q] : {std::pair{A0, B0}, {B0, D0}, {D0, E0}}) b.face("inlet", q, p);
  for (auto [p, q] : {std::pair{A3, B3}, {B3, D3}, {D3, E3}}) b.face("outlet", p, q);
  for (auto [p, q] : {std::pair{A0, A1}, {A1, A2}, {A2, A3}, {E1, E0}, {E2, E1}, {E3, E2}}) b.face("walls", p, q);
  for (auto [p, q] : {std::pair{C0, C1}, {C1, C2}, {C2, C3}, {C3, C0}}) b.face("cylinder", q, p);
  return b.finish({{"inlet", "patch", {}, {}},
                   {"outlet", "patch", {}, {}},
                   {"walls", "wall", {}, {}},
                   {"cylinder", "wall", {}, {}},
                   {"frontAndBack", "empty", {}, {}}});
}

int cellsAroundForSpacing(double diameter, double spacing) {
  if (!(diameter > 0) || !(spacing > 0) || !std::isfinite(diameter) || !std::isfinite(spacing))
    throw std::invalid_argument("cellsAroundForSpacing: diameter and spacing must be positive and finite");
  const double quarters = std::round(M_PI * diameter / spacing / 4);
  return 4 * static_cast<int>(std::clamp(quarters, 2.0, 1e6));
}

BlockMeshDict periodicCellMesh(double L, double radius, double depth, int n, double radial_grading) {
  if (n < 4 || n % 4 != 0) throw std::invalid_argument("periodicCellMesh: cells_around must be a multiple of 4");
  if (radius <= 0 || radius >= 0.5 * L * 0.98) throw std::invalid_argument("periodicCellMesh: radius must be in (0, 0.49 L)");
  const int nt = n / 4;
  const double c = 0.5 * L, s = radius / std::sqrt(2.0);
  // Radial cells: spacing comparable to the tangential one at the cell edge.
  const double gap = c * std::sqrt(2.0) - radius;
  const int nr = std::max(4, static_cast<int>(std::lround(gap / (L / nt) * 1.5)));
  Builder b(depth);
  const int S0 = b.vertex(0, 0), S1 = b.vertex(L, 0), S2 = b.vertex(L, L), S3 = b.vertex(0, L);
  const int C0 = b.vertex(c - s, c - s), C1 = b.vertex(c + s, c - s), C2 = b.vertex(c + s, c + s), C3 = b.vertex(c - s, c + s);
  const double gr = 1.0 / radial_grading;
  b.block(S0, S1, C1, C0, nt, nr, 1, gr);
  b.block(S1, S2, C2, C1, nt, nr, 1, gr);
  b.block(S2, S3, C3, C2, nt, nr, 1, gr);
  b.block(S3, S0, C0, C3, nt, nr, 1, gr);
  b.arc(C0, C1, c, c - radius);
  b.arc(C1, C2, c + radius, c);
  b.arc(C2, C3, c, c + radius);
  b.arc(C3, C0, c - radius, c);
  b.face("left", S3, S0);
  b.face("right", S1, S2);
  b.face("bottom", S0, S1);
  b.face("top", S2, S3);
  for (auto [p, q] : {std::pair{C0, C1}, {C1, C2}, {C2, C3}, {C3, C0}}) b.face("cylinder", q, p);
  return b.finish({{"left", "cyclic", {}, "right"},
                   {"right", "cyclic", {}, "left"},
                   {"bottom", "cyclic", {}, "top"},
                   {"top", "cyclic", {}, "bottom"},
                   {"cylinder", "wall", {}, {}},
                   {"frontAndBack", "empty", {}, {}}});
}

}  // namespace mmval::openfoam
