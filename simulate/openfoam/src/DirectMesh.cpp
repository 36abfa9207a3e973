#include "mmval/openfoam/DirectMesh.hpp"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/openfoam/FoamFile.hpp"
#include "mmval/openfoam/ImageGeometry.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::openfoam {

namespace {

/// How far a wall vertex may look for the level, in cells: a wall vertex touches a fluid cell
/// (centre fluid) and a grain cell (centre grain), so the level lies within h / sqrt 2 of it.
constexpr double kReachCells = 0.75;
/// Samples along a search segment before bisection: a crossing pair closer than reach / kSamples
/// could be missed, which only means the vertex takes the next crossing or stays.
constexpr int kSamples = 24;
/// A snapped cell's shape bounds. Its area stays above kMinCellArea dx dy (an unsnapped cell's is
/// dx dy), and its centroid at least kMinCentroidDistance cells from every side's line: the cell
/// is star-shaped about its centre, so OpenFOAM's face pyramids are positive. Corners may reach
/// or pass 180 degrees: where the level crosses the grid obliquely, a staircase cell with three
/// wall vertices becomes a triangle, with a slight reflex corner where the grain bulges into it.
constexpr double kMinCellArea = 0.1;
constexpr double kMinCentroidDistance = 0.1;
/// Halvings of a vertex's move before it is left where it was.
constexpr int kMaxHalvings = 8;

double cross(const Vertex2& o, const Vertex2& a, const Vertex2& b) { return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x); }

/// Cells of the grid with fluid at the centre, joined through faces to both the inlet and the
/// outlet column: -1 for the others, else 1.
std::vector<int> connectedFluid(const LevelFunction& level, int nx, int ny, double dx, double dy, int& disconnected) {
  // Rows are y, columns x, inlet column 0: the pore-space analysis of the image kinds, on the cells.
  simulate::BoolArray solid(ny, nx);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) solid(j, i) = !(level((i + 0.5) * dx, (j + 0.5) * dy) <= 0);
  std::vector<int> out(static_cast<std::size_t>(nx) * ny, -1);
  simulate::BoolArray kept = simulate::BoolArray::Constant(ny, nx, true);
  try {
    kept = simulate::analysePoreSpace(solid).solid_connected;
  } catch (const simulate::NoFlowPath&) {
    // No cell joins inlet and outlet: every fluid cell is disconnected.
  }
  disconnected = 0;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      if (!kept(j, i)) out[static_cast<std::size_t>(j) * nx + i] = 1;
      else if (!solid(j, i)) ++disconnected;
    }
  return out;
}

/// Finds the level's crossings for the wall vertices.
class Snapper {
 public:
  Snapper(const LevelFunction& level, double width, double height, double dx, double dy)
      : m_level(level), m_w(width), m_h(height), m_scale(std::sqrt(dx * dy)) {}

  /// The first crossing of the level from p along the unit direction (ux, uy) within `reach`
  /// (sampled, then bisected to ~1e-12 of a cell); the distance, or -1 if none in reach.
  double along(const Vertex2& p, double f0, double ux, double uy, double reach) const {
    double lo = 0;
    for (int k = 1; k <= kSamples; ++k) {
      const double t = reach * k / kSamples;
      const double x = p.x + t * ux, y = p.y + t * uy;
      if (x < 0 || x > m_w || y < 0 || y > m_h) return -1;  // the level beyond the image is not the image's
      if ((m_level(x, y) > 0) != (f0 > 0)) {
        double a = lo, b = t;
        for (int it = 0; it < 60 && b - a > 1e-12 * m_scale; ++it) {
          const double mid = 0.5 * (a + b);
          ((m_level(p.x + mid * ux, p.y + mid * uy) > 0) == (f0 > 0) ? a : b) = mid;
        }
        return 0.5 * (a + b);
      }
      lo = t;
    }
    return -1;
  }

  /// Gradient of the level by central differences (1e-4 of a cell).
  std::array<double, 2> gradient(const Vertex2& p) const {
    const double d = 1e-4 * m_scale;
    return {(m_level(p.x + d, p.y) - m_level(p.x - d, p.y)) / (2 * d), (m_level(p.x, p.y + d) - m_level(p.x, p.y - d)) / (2 * d)};
  }

  double level(const Vertex2& p) const { return m_level(p.x, p.y); }
  double scale() const { return m_scale; }

 private:
  const LevelFunction& m_level;
  double m_w, m_h, m_scale;
};

/// Where the wall vertex (i, j) goes: its move, or nothing (pinned). `kept(i, j)` says whether grid
/// cell (i, j) is kept; cells outside the grid count as neither.
template <class Kept>
std::optional<Vertex2> wallTarget(const DirectMesh2D& m, const Snapper& s, int i, int j, const Kept& kept) {
  const Vertex2 p = m.vertices[static_cast<std::size_t>(j) * (m.nx + 1) + i];
  const double f0 = s.level(p);
  if (std::abs(f0) < 1e-14) return Vertex2{0, 0};
  const bool edge_x = i == 0 || i == m.nx, edge_y = j == 0 || j == m.ny;
  if (edge_x && edge_y) return std::nullopt;  // an image corner stays
  const double reach = kReachCells * s.scale();
  auto move = [&](double ux, double uy, double t) { return Vertex2{t * ux, t * uy}; };
  if (edge_x || edge_y) {
    // On the image edge: slide along it to the nearer crossing.
    const double ux = edge_y ? 1 : 0, uy = edge_x ? 1 : 0;
    const double a = s.along(p, f0, ux, uy, reach), b = s.along(p, f0, -ux, -uy, reach);
    if (a < 0 && b < 0) return std::nullopt;
    return (b < 0 || (a >= 0 && a <= b)) ? move(ux, uy, a) : move(-ux, -uy, b);
  }
  const bool k00 = kept(i - 1, j - 1), k10 = kept(i, j - 1), k11 = kept(i, j), k01 = kept(i - 1, j);
  if ((k00 && k11 && !k10 && !k01) || (k10 && k01 && !k00 && !k11)) return std::nullopt;  // diagonal contact
  const auto g = s.gradient(p);
  const double gn = std::hypot(g[0], g[1]);
  if (gn > 0 && std::isfinite(gn)) {
    const double sign = f0 > 0 ? -1 : 1;  // grain side: down the gradient; fluid side: up it
    const double ux = sign * g[0] / gn, uy = sign * g[1] / gn;
    if (const double t = s.along(p, f0, ux, uy, reach); t >= 0) {
        return move(ux, uy, t);
    }
  }
  // A flat or misleading gradient: towards the adjacent cell centres on the other side.
  double best = -1, bx = 0, by = 0;
  for (int a = -1; a <= 0; ++a)
    for (int b = -1; b <= 0; ++b) {
      const double cx = p.x + (a + 0.5) * m.dx(), cy = p.y + (b + 0.5) * m.dy();
      if ((s.level({cx, cy}) > 0) == (f0 > 0)) continue;
      const double len = std::hypot(cx - p.x, cy - p.y);
      const double t = s.along(p, f0, (cx - p.x) / len, (cy - p.y) / len, len);
      if (t >= 0 && (best < 0 || t < best)) {
        best = t;
        bx = (cx - p.x) / len;
        by = (cy - p.y) / len;
      }
    }
  if (best < 0) return std::nullopt;
  return move(bx, by, best);
}

/// Whether a counter-clockwise quad keeps its shape bounds.
bool shapely(const std::vector<Vertex2>& v, const std::array<int, 4>& c, double dxdy) {
  const double area = 0.5 * (cross(v[c[0]], v[c[1]], v[c[2]]) + cross(v[c[0]], v[c[2]], v[c[3]]));
  if (area < kMinCellArea * dxdy) return false;
  const Vertex2 centre{0.25 * (v[c[0]].x + v[c[1]].x + v[c[2]].x + v[c[3]].x), 0.25 * (v[c[0]].y + v[c[1]].y + v[c[2]].y + v[c[3]].y)};
  const double min_distance = kMinCentroidDistance * std::sqrt(dxdy);
  for (int k = 0; k < 4; ++k) {
    const Vertex2& a = v[c[k]];
    const Vertex2& b = v[c[(k + 1) % 4]];
    const double len = std::hypot(b.x - a.x, b.y - a.y);
    if (!(len > 0) || cross(centre, a, b) < min_distance * len) return false;
  }
  return true;
}

/// Evens out the spacing of the wall vertices along the level: projection alone leaves pairs of
/// vertices a fraction of a cell apart where the level crosses the grid obliquely, and the short
/// grain face between them is highly skewed (checkMesh flags skewness > 4). Each wall vertex with
/// two wall neighbours (along grain faces) moves to the level point nearest the midpoint of
/// theirs, kSmoothingPasses times (Jacobi).
template <class Kept>
void evenOut(const DirectMesh2D& m, const Snapper& snap, const Kept& kept, const std::vector<char>& wall, std::vector<Vertex2>& move,
             const std::vector<double>& scale) {
  constexpr int kSmoothingPasses = 3;
  const int nx = m.nx, ny = m.ny;
  std::vector<std::array<int, 4>> nb(m.vertices.size(), {-1, -1, -1, -1});
  std::vector<int> count(m.vertices.size(), 0);
  auto link = [&](int a, int b) {
    if (count[a] < 4) nb[a][count[a]] = b;
    ++count[a];
  };
  for (std::size_t c = 0; c < m.cells.size(); ++c) {
    const int i = m.grid_cell[c][0], j = m.grid_cell[c][1];
    const int across[4][2] = {{i, j - 1}, {i + 1, j}, {i, j + 1}, {i - 1, j}};
    for (int k = 0; k < 4; ++k) {
      const int ai = across[k][0], aj = across[k][1];
      if (ai < 0 || ai >= nx || aj < 0 || aj >= ny || kept(ai, aj)) continue;
      link(m.cells[c][k], m.cells[c][(k + 1) % 4]);
      link(m.cells[c][(k + 1) % 4], m.cells[c][k]);
    }
  }
  const double reach = kReachCells * snap.scale();
  for (int pass = 0; pass < kSmoothingPasses; ++pass) {
    std::vector<Vertex2> next = move;
    for (std::size_t v = 0; v < m.vertices.size(); ++v) {
      const int i = static_cast<int>(v) % (nx + 1), j = static_cast<int>(v) / (nx + 1);
      if (!wall[v] || scale[v] == 0 || count[v] != 2 || i == 0 || i == nx || j == 0 || j == ny) continue;
      const Vertex2& o = m.vertices[v];
      const int a = nb[v][0], b = nb[v][1];
      const Vertex2 mid{0.5 * (m.vertices[a].x + move[a].x + m.vertices[b].x + move[b].x), 0.5 * (m.vertices[a].y + move[a].y + m.vertices[b].y + move[b].y)};
      const double f0 = snap.level(mid);
      const auto g = snap.gradient(mid);
      const double gn = std::hypot(g[0], g[1]);
      if (!(gn > 0) || !std::isfinite(gn)) continue;
      const double sign = f0 > 0 ? -1 : 1;
      const double ux = sign * g[0] / gn, uy = sign * g[1] / gn;
      const double t = std::abs(f0) < 1e-14 ? 0.0 : snap.along(mid, f0, ux, uy, reach);
      if (t < 0) continue;
      const Vertex2 d{mid.x + t * ux - o.x, mid.y + t * uy - o.y};
      if (std::hypot(d.x, d.y) <= reach) next[v] = d;  // stays within reach of its grid position
    }
    move = next;
  }
}

}  // namespace

double DirectMesh2D::area() const {
  double a = 0;
  for (const auto& c : cells)
    for (int k = 0; k < 4; ++k) {
      const Vertex2& p = vertices[c[k]];
      const Vertex2& q = vertices[c[(k + 1) % 4]];
      a += 0.5 * (p.x * q.y - q.x * p.y);
    }
  return a;
}

double DirectMesh2D::minCellAreaRatio() const {
  double m = 1e300;
  for (const auto& c : cells) m = std::min(m, 0.5 * (cross(vertices[c[0]], vertices[c[1]], vertices[c[2]]) + cross(vertices[c[0]], vertices[c[2]], vertices[c[3]])));
  return cells.empty() ? 0 : m / (dx() * dy());
}

namespace {
/// Steps 1 of directMesh2D: the grid, its fluid cells joined to inlet and outlet, vertices unmoved.
DirectMesh2D gridMesh(const LevelFunction& level, double width, double height, int nx, int ny) {
  if (!(width > 0) || !(height > 0) || nx < 2 || ny < 2)
    throw std::invalid_argument(fmt::format("directMesh2D: a {} x {} m domain with {} x {} cells; expected positive sizes and at least 2 x 2 cells",
                                            width, height, nx, ny));
  DirectMesh2D m;
  m.nx = nx;
  m.ny = ny;
  m.width = width;
  m.height = height;
  const double dx = m.dx(), dy = m.dy();
  const std::vector<int> fluid = connectedFluid(level, nx, ny, dx, dy, m.dropped_disconnected);
  m.cell_of.assign(fluid.size(), -1);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i)
      if (fluid[static_cast<std::size_t>(j) * nx + i] > 0) {
        m.cell_of[static_cast<std::size_t>(j) * nx + i] = static_cast<int>(m.cells.size());
        const int v = j * (nx + 1) + i;
        m.cells.push_back({v, v + 1, v + nx + 2, v + nx + 1});
        m.grid_cell.push_back({i, j});
      }
  if (m.cells.empty()) throw std::runtime_error("directMesh2D: no fluid cell connects the inlet (x = 0) and the outlet (x = width)");
  m.vertices.resize(static_cast<std::size_t>(nx + 1) * (ny + 1));
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) m.vertices[static_cast<std::size_t>(j) * (nx + 1) + i] = {i * dx, j * dy};
  // Grid edges and corners are exact multiples, not accumulated: the last column sits on width.
  for (int j = 0; j <= ny; ++j) m.vertices[static_cast<std::size_t>(j) * (nx + 1) + nx].x = width;
  for (int i = 0; i <= nx; ++i) m.vertices[static_cast<std::size_t>(ny) * (nx + 1) + i].y = height;
  return m;
}

/// Vertices on a face between a kept and a dropped cell (or none).
bool touchesGrain(const DirectMesh2D& m, int i, int j, bool& used) {
  const int nx = m.nx, ny = m.ny;
  auto kept = [&](int a, int b) { return a >= 0 && a < nx && b >= 0 && b < ny && m.cell_of[static_cast<std::size_t>(b) * nx + a] >= 0; };
  auto dropped = [&](int a, int b) { return a >= 0 && a < nx && b >= 0 && b < ny && m.cell_of[static_cast<std::size_t>(b) * nx + a] < 0; };
  used = kept(i - 1, j - 1) || kept(i, j - 1) || kept(i - 1, j) || kept(i, j);
  return dropped(i - 1, j - 1) || dropped(i, j - 1) || dropped(i - 1, j) || dropped(i, j);
}
}  // namespace

DirectMesh2D directMesh2D(const LevelFunction& level, double width, double height, int nx, int ny) {
  DirectMesh2D m = gridMesh(level, width, height, nx, ny);
  const double dx = m.dx(), dy = m.dy();
  auto kept = [&](int i, int j) { return i >= 0 && i < nx && j >= 0 && j < ny && m.cell_of[static_cast<std::size_t>(j) * nx + i] >= 0; };
  const Snapper snap(level, width, height, dx, dy);
  std::vector<Vertex2> move(m.vertices.size(), Vertex2{0, 0});
  std::vector<double> scale(m.vertices.size(), 0.0);
  std::vector<char> wall(m.vertices.size(), 0);
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) {
      bool used = false;
      const bool touches_grain = touchesGrain(m, i, j, used);
      if (!used || !touches_grain) continue;
      const std::size_t v = static_cast<std::size_t>(j) * (nx + 1) + i;
      wall[v] = 1;
      ++m.wall_vertices;
      const std::optional<Vertex2> d = wallTarget(m, snap, i, j, kept);
      if (!d) {
        ++m.pinned;
        continue;
      }
      move[v] = *d;
      scale[v] = 1;
    }
  evenOut(m, snap, kept, wall, move, scale);
  // Halve the moves of every vertex of a cell that came out too thin or not convex, until all pass.
  std::vector<Vertex2> pos = m.vertices;
  auto place = [&](std::size_t v) { pos[v] = {m.vertices[v].x + scale[v] * move[v].x, m.vertices[v].y + scale[v] * move[v].y}; };
  for (std::size_t v = 0; v < pos.size(); ++v) place(v);
  std::vector<char> halved(m.vertices.size(), 0);
  for (int pass = 0; pass < 100000; ++pass) {  // each pass from kMaxHalvings on stops at least one vertex
    bool changed = false;
    for (const auto& c : m.cells) {
      if (shapely(pos, c, dx * dy)) continue;
      for (int v : c) {
        if (scale[v] == 0) continue;
        scale[v] = pass >= kMaxHalvings ? 0 : 0.5 * scale[v];
        halved[v] = 1;
        place(v);
        changed = true;
      }
    }
    if (!changed) break;
  }
  for (std::size_t v = 0; v < pos.size(); ++v) {
    if (!wall[v] || scale[v] == 0) continue;
    if (halved[v]) ++m.pulled_back;
    else ++m.snapped;
    m.max_move_cells = std::max(m.max_move_cells, scale[v] * std::hypot(move[v].x / dx, move[v].y / dy));
  }
  for (std::size_t v = 0; v < pos.size(); ++v)
    if (wall[v] && scale[v] == 0 && halved[v]) ++m.pulled_back;
  m.vertices = pos;
  return m;
}

PolyMesh extrude(const DirectMesh2D& m, double thickness, const std::string& side_type) {
  PolyMesh p;
  p.cells = static_cast<int>(m.cells.size());
  // Points: the used grid vertices at z = 0, then the same at z = thickness.
  std::vector<int> id(m.vertices.size(), -1);
  int n = 0;
  for (const auto& c : m.cells)
    for (int v : c)
      if (id[v] < 0) id[v] = n++;
  p.points.resize(static_cast<std::size_t>(2) * n);
  for (std::size_t v = 0; v < m.vertices.size(); ++v)
    if (id[v] >= 0) {
      p.points[id[v]] = {m.vertices[v].x, m.vertices[v].y, 0.0};
      p.points[id[v] + n] = {m.vertices[v].x, m.vertices[v].y, thickness};
    }
  // The face on the cell's edge from corner k to corner k + 1 (counter-clockwise), extruded: its
  // right-hand normal points out of the cell.
  auto side = [&](const std::array<int, 4>& c, int k) {
    const int a = id[c[k]], b = id[c[(k + 1) % 4]];
    return std::array<int, 4>{a, b, b + n, a + n};
  };
  // Corner order of a cell: (i, j), (i + 1, j), (i + 1, j + 1), (i, j + 1); edge k: 0 bottom, 1 right, 2 top, 3 left.
  auto cellAt = [&](int i, int j) { return i >= 0 && i < m.nx && j >= 0 && j < m.ny ? m.cell_of[static_cast<std::size_t>(j) * m.nx + i] : -2; };
  // Internal faces by owner, then by neighbour: the right neighbour's index is below the top one's.
  for (int c = 0; c < p.cells; ++c) {
    const auto [i, j] = m.grid_cell[c];
    for (int k : {1, 2}) {
      const int nb = k == 1 ? cellAt(i + 1, j) : cellAt(i, j + 1);
      if (nb < 0) continue;
      p.faces.push_back(side(m.cells[c], k));
      p.owner.push_back(c);
      p.neighbour.push_back(nb);
    }
  }
  struct Group {
    const char* name;
    std::string type;
  };
  const Group groups[] = {{"inlet", "patch"}, {"outlet", "patch"}, {"walls", side_type}, {"grains", "wall"}, {"back", "empty"}, {"front", "empty"}};
  for (int g = 0; g < 6; ++g) {
    PolyPatch patch{groups[g].name, groups[g].type, static_cast<int>(p.faces.size()), 0};
    for (int c = 0; c < p.cells; ++c) {
      const auto& q = m.cells[c];
      if (g == 4) {
        p.faces.push_back({id[q[0]], id[q[3]], id[q[2]], id[q[1]]});  // normal -z
        p.owner.push_back(c);
        continue;
      }
      if (g == 5) {
        p.faces.push_back({id[q[0]] + n, id[q[1]] + n, id[q[2]] + n, id[q[3]] + n});  // normal +z
        p.owner.push_back(c);
        continue;
      }
      const int i = m.grid_cell[c][0], j = m.grid_cell[c][1];
      const int across[4] = {cellAt(i, j - 1), cellAt(i + 1, j), cellAt(i, j + 1), cellAt(i - 1, j)};
      for (int k = 0; k < 4; ++k) {
        int group = -1;
        if (across[k] == -1) group = 3;                  // a dropped cell: grain
        else if (across[k] == -2) group = k == 3 ? 0 : k == 1 ? 1 : 2;  // beyond the image
        if (group != g) continue;
        p.faces.push_back(side(q, k));
        p.owner.push_back(c);
      }
    }
    patch.size = static_cast<int>(p.faces.size()) - patch.start;
    p.patches.push_back(patch);
  }
  return p;
}

void writePolyMesh(const PolyMesh& mesh, const std::filesystem::path& case_dir) {
  const std::filesystem::path dir = case_dir / "constant" / "polyMesh";
  std::filesystem::create_directories(dir);
  const std::string note = fmt::format("nPoints:{} nCells:{} nFaces:{} nInternalFaces:{}", mesh.points.size(), mesh.cells, mesh.faces.size(),
                                       mesh.neighbour.size());
  auto header = [&](const char* cls, const char* object) {
    std::string h = foamHeader(cls, object, "constant/polyMesh");
    // OpenFOAM's readers take the counts from the note when present; it is informative only.
    const auto at = h.find("    object");
    return h.insert(at, fmt::format("    note        \"{}\";\n", note));
  };
  std::string out = header("vectorField", "points") + fmt::format("{}\n(\n", mesh.points.size());
  for (const auto& q : mesh.points) out += fmt::format("({:.12g} {:.12g} {:.12g})\n", q[0], q[1], q[2]);
  writeFileAtomic(dir / "points", out + ")\n");
  out = header("faceList", "faces") + fmt::format("{}\n(\n", mesh.faces.size());
  for (const auto& f : mesh.faces) out += fmt::format("4({} {} {} {})\n", f[0], f[1], f[2], f[3]);
  writeFileAtomic(dir / "faces", out + ")\n");
  auto labels = [&](const char* object, const std::vector<int>& v) {
    std::string text = header("labelList", object) + fmt::format("{}\n(\n", v.size());
    for (int x : v) text += fmt::format("{}\n", x);
    writeFileAtomic(dir / object, text + ")\n");
  };
  labels("owner", mesh.owner);
  labels("neighbour", mesh.neighbour);
  out = foamHeader("polyBoundaryMesh", "boundary", "constant/polyMesh") + fmt::format("{}\n(\n", mesh.patches.size());
  for (const auto& p : mesh.patches) {
    out += fmt::format("    {}\n    {{\n        type            {};\n", p.name, p.type);
    if (p.type != "patch") out += fmt::format("        inGroups        List<word> 1({});\n", p.type);
    out += fmt::format("        nFaces          {};\n        startFace       {};\n    }}\n", p.size, p.start);
  }
  writeFileAtomic(dir / "boundary", out + ")\n");
}

DirectMesh2D pixelImageMesh(const MaskGeometry& g, int cells_per_pixel) {
  if (cells_per_pixel < 1) throw std::invalid_argument(fmt::format("pixelImageMesh: {} cells per pixel; expected a whole number >= 1", cells_per_pixel));
  const int cols = g.fluid.cols, rows = g.fluid.rows;
  const double p = g.pixel;
  // +1 in a grain pixel, -1 in a pore pixel (row 0 of the image is its top); cell centres never
  // sit on a pixel edge at a whole number of cells per pixel.
  const LevelFunction pixels = [&g, cols, rows, p](double x, double y) {
    const int c = std::clamp(static_cast<int>(std::floor(x / p)), 0, cols - 1), r = rows - 1 - std::clamp(static_cast<int>(std::floor(y / p)), 0, rows - 1);
    return g.fluid.at<std::uint8_t>(r, c) != 0 ? -1.0 : 1.0;
  };
  DirectMesh2D m = gridMesh(pixels, g.width(), g.height(), cols * cells_per_pixel, rows * cells_per_pixel);
  for (int j = 0; j <= m.ny; ++j)
    for (int i = 0; i <= m.nx; ++i) {
      bool used = false;
      if (touchesGrain(m, i, j, used) && used) ++m.wall_vertices;
    }
  return m;
}

DirectMesh2D directImageMesh(const MaskGeometry& g, double sigma_px, double cells_per_pixel) {
  const int nx = std::max(4, static_cast<int>(std::lround(g.fluid.cols * cells_per_pixel)));
  const int ny = std::max(4, static_cast<int>(std::lround(g.fluid.rows * cells_per_pixel)));
  return directMesh2D(smoothLevel(g, sigma_px), g.width(), g.height(), nx, ny);
}

}  // namespace mmval::openfoam
