#include "mmval/particles/LiggghtsInput.hpp"

#include <algorithm>
#include <cmath>

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
  const double h = flow.depth(0.5 * (b.x0 + b.x1), 0.5 * (b.y0 + b.y1));
  for (double fx : {0.0, 0.5, 1.0})
    for (double fy : {0.1, 0.5, 0.9}) {
      const double hh = flow.depth(b.x0 + fx * (b.x1 - b.x0), b.y0 + fy * (b.y1 - b.y0));
      if (std::abs(hh - h) > 1e-9 * h)
        throw InputError(keyLocation("flow"), "the LIGGGHTS engine models the chip's plates as two planes; this field's depth varies", fmt::format("{:.4g} vs {:.4g} um", hh * 1e6, h * 1e6),
                         "a constant-depth field, or the overdamped engine");
    }
  if (dynamic_cast<const HeleShawChannel*>(&flow) != nullptr) {
    s.side_walls = true;
    s.wall_y0 = b.y0;
    s.wall_y1 = b.y1;
  } else if (dynamic_cast<const UniformFlow*>(&flow) == nullptr) {
    throw InputError(keyLocation("engine"), "the LIGGGHTS engine has plane walls only; grain walls from STL meshes are not implemented yet", "liggghts",
                     "engine = \"overdamped\" for fields with grains");
  }
  s.depth = h;
  const double margin = 2 * d;
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

}  // namespace mmval::particles
