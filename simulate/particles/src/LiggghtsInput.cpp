#include "mmval/particles/LiggghtsInput.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace mmval::particles {

namespace {

void require(bool ok, const std::string& key, const std::string& problem, double got, const std::string& expected) {
  if (!ok) throw InputError(keyLocation(key), problem, fmt::format("{:.6g}", got), expected);
}

std::string num(double v) { return fmt::format("{:.17g}", v); }

bool safePath(const std::filesystem::path& p) {
  const std::string s = p.string();
  return !s.empty() && s.find_first_of(" \t\n\"'#$&;") == std::string::npos;
}

}  // namespace

std::string grainWallStl(const GriddedFlow& flow, double z0, double z1, int max_run, long& triangles) {
  const int nx = flow.nx(), ny = flow.ny();
  const Bounds2 b = flow.bounds();
  const double dx = nx > 1 ? (b.x1 - b.x0) / (nx - 1) : 1.0, dy = ny > 1 ? (b.y1 - b.y0) / (ny - 1) : 1.0;
  // Node solidity sampled at the nodes themselves (nearest node = the node).
  std::vector<std::uint8_t> solid(static_cast<std::size_t>(nx) * ny);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) solid[static_cast<std::size_t>(j) * nx + i] = flow.isSolid(b.x0 + i * dx, b.y0 + j * dy) ? 1 : 0;
  const auto at = [&](int i, int j) { return solid[static_cast<std::size_t>(j) * nx + i] != 0; };
  std::string out = "solid grains\n";
  triangles = 0;
  // One rectangle (two triangles) in the vertical plane through (xa, ya)-(xb, yb), normal n.
  const auto quad = [&](double xa, double ya, double xb, double yb, double nxv, double nyv) {
    const double p[4][3] = {{xa, ya, z0}, {xb, yb, z0}, {xb, yb, z1}, {xa, ya, z1}};
    for (const auto& tri : {std::array<int, 3>{0, 1, 2}, std::array<int, 3>{0, 2, 3}}) {
      out += fmt::format("facet normal {:.9g} {:.9g} 0\n outer loop\n", nxv, nyv);
      for (int v : tri) out += fmt::format("  vertex {:.12g} {:.12g} {:.12g}\n", p[v][0], p[v][1], p[v][2]);
      out += " endloop\nendfacet\n";
      ++triangles;
    }
  };
  const int run_max = std::max(1, max_run);
  // Faces normal to x: between nodes (i, j) and (i + 1, j), at x = x_i + dx / 2; runs along y.
  for (int i = 0; i + 1 < nx; ++i)
    for (int side = 0; side < 2; ++side) {  // side 0: solid on the left (normal +x), 1: solid on the right
      int j = 0;
      while (j < ny) {
        const auto face = [&](int jj) { return side == 0 ? (at(i, jj) && !at(i + 1, jj)) : (!at(i, jj) && at(i + 1, jj)); };
        if (!face(j)) {
          ++j;
          continue;
        }
        int k = j;
        while (k + 1 < ny && k + 1 - j < run_max && face(k + 1)) ++k;
        const double x = b.x0 + (i + 0.5) * dx;
        quad(x, b.y0 + (j - 0.5) * dy, x, b.y0 + (k + 0.5) * dy, side == 0 ? 1.0 : -1.0, 0.0);
        j = k + 1;
      }
    }
  // Faces normal to y: between nodes (i, j) and (i, j + 1); runs along x.
  for (int j = 0; j + 1 < ny; ++j)
    for (int side = 0; side < 2; ++side) {
      int i = 0;
      while (i < nx) {
        const auto face = [&](int ii) { return side == 0 ? (at(ii, j) && !at(ii, j + 1)) : (!at(ii, j) && at(ii, j + 1)); };
        if (!face(i)) {
          ++i;
          continue;
        }
        int k = i;
        while (k + 1 < nx && k + 1 - i < run_max && face(k + 1)) ++k;
        const double y = b.y0 + (j + 0.5) * dy;
        quad(b.x0 + (i - 0.5) * dx, y, b.x0 + (k + 0.5) * dx, y, 0.0, side == 0 ? 1.0 : -1.0);
        i = k + 1;
      }
    }
  out += "endsolid grains\n";
  return out;
}

double liggghtsTimeStep(const ParticleMaterial& p, double rayleigh_fraction, double impact_speed) {
  const double dt_r = rayleigh_fraction * rayleighTime(p);
  const double dt_h = hertzContactTimeEqual(p, std::max(impact_speed, 1e-9)) / 20.0;
  return std::min(dt_r, dt_h);
}

LiggghtsSetup liggghtsSetupFor(const FlowField& flow, const SceneConfig& cfg, double outlet_x) {
  LiggghtsSetup s;
  const Bounds2 b = flow.bounds();
  const double d = cfg.particle.diameter;
  s.particle = cfg.particle;
  s.cohesion_energy_density = cfg.cohesion_energy_density;
  // The plates are two planes: the depth must be one number over the fluid.
  double h = 0;
  for (int fx = 0; fx <= 8; ++fx)
    for (int fy = 1; fy <= 7; ++fy) {
      const double x = b.x0 + fx / 8.0 * (b.x1 - b.x0), y = b.y0 + fy / 8.0 * (b.y1 - b.y0);
      if (flow.isSolid(x, y)) continue;
      const double hh = flow.depth(x, y);
      if (h == 0) h = hh;
      if (std::abs(hh - h) > 1e-9 * h)
        throw InputError(keyLocation("flow"), "the LIGGGHTS engine models the chip's plates as two planes; this field's depth varies",
                         fmt::format("{:.4g} vs {:.4g} um", hh * 1e6, h * 1e6), "a constant-depth field, or the overdamped engine");
    }
  if (!(h > 0)) throw InputError(keyLocation("flow"), "no fluid found in the field for the LIGGGHTS engine", "all solid", "a field with pore space");
  const auto* gridded = dynamic_cast<const GriddedFlow*>(&flow);
  double margin = 2 * d;
  if (dynamic_cast<const HeleShawChannel*>(&flow) != nullptr) {
    s.side_walls = true;
    s.wall_y0 = b.y0;
    s.wall_y1 = b.y1;
  } else if (gridded != nullptr) {
    // The node squares reach half a spacing beyond the outer nodes: keep them inside the box.
    const double dx = gridded->nx() > 1 ? (b.x1 - b.x0) / (gridded->nx() - 1) : 0.0, dy = gridded->ny() > 1 ? (b.y1 - b.y0) / (gridded->ny() - 1) : 0.0;
    margin = std::max(margin, std::max(dx, dy));
  } else if (dynamic_cast<const UniformFlow*>(&flow) == nullptr) {
    throw InputError(keyLocation("engine"), "the LIGGGHTS engine knows plane plates, channel side walls and gridded grains; this flow field is none of them",
                     "liggghts", "engine = \"overdamped\"");
  }
  s.depth = h;
  s.x0 = b.x0 - margin;
  s.x1 = std::max(b.x1, outlet_x) + margin;
  s.y0 = b.y0 - margin;
  s.y1 = b.y1 + margin;
  s.z0 = -0.25 * d;
  s.z1 = h + 0.25 * d;
  const double umax = 1.5 * std::max(flow.meanVelocity(0.5 * (b.x0 + b.x1), 0.5 * (b.y0 + b.y1)).norm(), 1e-12);
  s.dt = liggghtsTimeStep(cfg.particle, cfg.rayleigh_fraction, std::max(umax, settlingSpeed(cfg.fluid, cfg.particle, cfg.gravity)));
  s.skin = 0.5 * d;
  std::filesystem::create_directories(cfg.work_dir);
  if (gridded != nullptr) {
    // Grain walls span the box's depth beyond both plates, so no particle meets an edge.
    const std::string stl = grainWallStl(*gridded, 0.5 * s.z0, s.depth + 0.5 * (s.z1 - s.depth), 4, s.grain_triangles);
    if (s.grain_triangles > 0) {
      s.grain_stl = cfg.work_dir / "grains.stl";
      std::ofstream(s.grain_stl) << stl;
      if (!std::ifstream(s.grain_stl)) throw InputError(keyLocation("work_dir"), "cannot write the grain mesh for LIGGGHTS", s.grain_stl.string(), "a writable folder");
    }
  }
  s.log_file = cfg.work_dir / "liggghts.log";
  s.screen_file = cfg.work_dir / "liggghts.screen";
  return s;
}

std::vector<std::string> liggghtsSetupCommands(const LiggghtsSetup& s) {
  const auto& p = s.particle;
  require(std::isfinite(p.diameter) && p.diameter > 0 && p.diameter < 1e-2, "particles.diameter", "must be in (0, 1 cm)", p.diameter, "a particle diameter in m");
  require(std::isfinite(p.density) && p.density > 0, "particles.density", "must be > 0", p.density, "kg/m3");
  require(std::isfinite(p.youngs_modulus) && p.youngs_modulus >= 1e3 && p.youngs_modulus <= 1e12, "particles.youngs_modulus",
          "outside what LIGGGHTS accepts here", p.youngs_modulus, "1e3 .. 1e12 Pa");
  require(p.poisson_ratio > 0 && p.poisson_ratio < 0.5, "particles.poisson_ratio", "must be in (0, 0.5)", p.poisson_ratio, "(0, 0.5)");
  require(p.restitution > 0.01 && p.restitution <= 1, "particles.restitution", "must be in (0.01, 1]", p.restitution, "(0.01, 1]");
  require(p.friction >= 0 && p.friction <= 10, "particles.friction", "must be in [0, 10]", p.friction, "[0, 10]");
  require(s.cohesion_energy_density >= 0 && std::isfinite(s.cohesion_energy_density), "particles.cohesion_energy_density", "must be >= 0",
          s.cohesion_energy_density, "J/m3");
  require(std::isfinite(s.dt) && s.dt > 0 && s.dt < 1, "numerics.dt", "DEM step must be in (0, 1 s)", s.dt, "s");
  for (double v : {s.x0, s.x1, s.y0, s.y1, s.z0, s.z1, s.depth, s.skin})
    require(std::isfinite(v), "flow.bounds", "box coordinate not finite", v, "finite numbers");
  require(s.x1 > s.x0 && s.y1 > s.y0 && s.z1 > s.z0, "flow.bounds", "empty box", s.x1 - s.x0, "positive extents");
  require(s.depth > 2 * p.radius(), "flow.depth", "the depth must exceed a particle diameter", s.depth, "> diameter");
  require(s.z0 < 0 && s.z1 > s.depth, "flow.bounds", "the plates must lie inside the box", s.z1, "z0 < 0 and z1 > depth");
  require(s.skin > 0, "numerics.skin", "neighbour skin must be > 0", s.skin, "m");
  // LIGGGHTS bins the box at half the neighbour cutoff; a box of many bins
  // per particle size exhausts memory (a 1 m box of 5 um particles would).
  const double bin = 0.5 * (p.diameter + s.skin);
  const double bins = std::ceil((s.x1 - s.x0) / bin) * std::ceil((s.y1 - s.y0) / bin) * std::ceil((s.z1 - s.z0) / bin);
  require(bins <= 5e7, "flow.bounds", "box too large for the particle size (neighbour bins)", bins, "<= 5e7 bins of d/2 + skin/2");
  require(safePath(s.log_file) && safePath(s.screen_file), "work_dir", "LIGGGHTS log path empty or with spaces/special characters", 0,
          "a plain path");
  if (s.side_walls) require(s.wall_y1 > s.wall_y0 && s.wall_y0 > s.y0 && s.wall_y1 < s.y1, "flow.bounds", "side walls outside the box", s.wall_y0, "inside the box");
  if (!s.grain_stl.empty()) {
    require(safePath(s.grain_stl), "work_dir", "grain mesh path empty or with spaces/special characters", 0, "a plain path");
    require(s.grain_triangles > 0 && s.grain_triangles <= 2000000, "geometry.mask", "grain mesh triangle count out of range", static_cast<double>(s.grain_triangles),
            "1 .. 2e6 triangles");
    // LIGGGHTS 3.8 rejects meshes whose overall extent is under ~1e-4 m (a 60 um duct is refused).
    require(std::max(s.x1 - s.x0, s.y1 - s.y0) > 1.5e-4, "geometry.mask", "a grain mesh smaller than LIGGGHTS accepts", std::max(s.x1 - s.x0, s.y1 - s.y0),
            "a field wider than 150 um");
  }

  const bool cohesion = s.cohesion_energy_density > 0;
  const std::string model = std::string("model hertz tangential history") + (cohesion ? " cohesion sjkr" : "");
  std::vector<std::string> c;
  c.push_back("units si");
  c.push_back("atom_style granular");
  c.push_back("atom_modify map array");
  c.push_back("boundary f f f");
  c.push_back("newton off");
  c.push_back("communicate single vel yes");
  if (p.youngs_modulus < 5e6) c.push_back("soft_particles yes");
  if (p.youngs_modulus > 1e9) c.push_back("hard_particles yes");
  c.push_back(fmt::format("region mmval_box block {} {} {} {} {} {} units box", num(s.x0), num(s.x1), num(s.y0), num(s.y1), num(s.z0), num(s.z1)));
  c.push_back("create_box 1 mmval_box");
  c.push_back(fmt::format("neighbor {} bin", num(s.skin)));
  c.push_back("neigh_modify delay 0");
  c.push_back(fmt::format("fix m1 all property/global youngsModulus peratomtype {}", num(p.youngs_modulus)));
  c.push_back(fmt::format("fix m2 all property/global poissonsRatio peratomtype {}", num(p.poisson_ratio)));
  c.push_back(fmt::format("fix m3 all property/global coefficientRestitution peratomtypepair 1 {}", num(p.restitution)));
  c.push_back(fmt::format("fix m4 all property/global coefficientFriction peratomtypepair 1 {}", num(p.friction)));
  if (cohesion) c.push_back(fmt::format("fix m5 all property/global cohesionEnergyDensity peratomtypepair 1 {}", num(s.cohesion_energy_density)));
  c.push_back("pair_style gran " + model);
  c.push_back("pair_coeff * *");
  c.push_back(fmt::format("timestep {}", num(s.dt)));
  c.push_back(fmt::format("fix wall_bottom all wall/gran {} primitive type 1 zplane 0.0", model));
  c.push_back(fmt::format("fix wall_top all wall/gran {} primitive type 1 zplane {}", model, num(s.depth)));
  if (s.side_walls) {
    c.push_back(fmt::format("fix wall_y0 all wall/gran {} primitive type 1 yplane {}", model, num(s.wall_y0)));
    c.push_back(fmt::format("fix wall_y1 all wall/gran {} primitive type 1 yplane {}", model, num(s.wall_y1)));
  }
  if (!s.grain_stl.empty()) {
    c.push_back(fmt::format("fix grains all mesh/surface file {} type 1", s.grain_stl.string()));
    c.push_back(fmt::format("fix wall_grains all wall/gran {} mesh n_meshes 1 meshes grains", model));
  }
  c.push_back("thermo 1000000000");
  c.push_back("thermo_modify lost ignore norm no");
  return c;
}

std::vector<std::string> liggghtsInsertCommands(const LiggghtsSetup& s, const std::vector<Vec3>& positions, long first_id) {
  std::vector<std::string> c;
  const double a = s.particle.radius();
  for (const auto& x : positions) {
    require(x.allFinite(), "particles.insert", "position not finite", 0, "finite");
    require(x.x() > s.x0 && x.x() < s.x1 && x.y() > s.y0 && x.y() < s.y1, "particles.insert", "position outside the box", x.x(), "inside the box");
    require(x.z() >= a && x.z() <= s.depth - a, "particles.insert", "particle crosses a plate", x.z(), "z in [a, h - a]");
    c.push_back(fmt::format("create_atoms 1 single {} {} {} units box", num(x.x()), num(x.y()), num(x.z())));
  }
  if (!positions.empty()) {
    const long last = first_id + static_cast<long>(positions.size()) - 1;
    c.push_back(fmt::format("set atom {}*{} diameter {} density {}", first_id, last, num(s.particle.diameter), num(s.particle.density)));
  }
  return c;
}

std::optional<std::string> liggghtsVersionFromHeader(std::string_view text) {
  std::string_view line = text.substr(0, text.find('\n'));
  const auto trim = [](std::string_view v) {
    const auto b = v.find_first_not_of(" \t\r");
    if (b == std::string_view::npos) return std::string_view{};
    return v.substr(b, v.find_last_not_of(" \t\r") - b + 1);
  };
  line = trim(line);
  // The log's first line wraps the version: "LIGGGHTS (" + version + ")".
  constexpr std::string_view wrapper = "LIGGGHTS (";
  if (line.substr(0, wrapper.size()) == wrapper && line.back() == ')') line = trim(line.substr(wrapper.size(), line.size() - wrapper.size() - 1));
  constexpr std::string_view prefix = "Version ";
  if (line.substr(0, prefix.size()) == prefix) line = trim(line.substr(prefix.size()));
  const bool names_liggghts = line.substr(0, 8) == "LIGGGHTS";
  const bool has_number = line.find_first_of("0123456789") != std::string_view::npos;
  if (!names_liggghts || !has_number) return std::nullopt;
  return std::string(line);
}

}  // namespace mmval::particles
