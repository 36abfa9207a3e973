#include "mmval/openfoam/Kinds.hpp"

#include <cmath>
#include <cstdio>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/openfoam/Peer.hpp"

namespace mmval::openfoam {

namespace {

Scene cylinderScene(const Case& c) {
  Scene s;
  s.kind = Scene::Kind::cylinder_channel;
  s.length = c.quantity("geometry.length");
  s.height = c.quantity("geometry.height");
  s.cx = c.quantity("geometry.cylinder_x");
  s.cy = c.quantity("geometry.cylinder_y");
  s.diameter = c.quantity("geometry.diameter");
  s.depth = c.quantity("geometry.depth");
  s.rho = c.quantity("fluid.density");
  s.nu = c.quantity("fluid.viscosity") / s.rho;
  s.inflow_max = c.quantity("inflow.max_velocity");
  s.uniform_inflow = c.text("inflow.profile") == "uniform";
  s.slip_walls = c.text("geometry.walls") == "slip";
  s.u_ref = c.has("forces.reference_velocity") ? c.quantity("forces.reference_velocity")
                                                : (s.uniform_inflow ? 1.0 : 2.0 / 3.0) * s.inflow_max;
  s.l_ref = c.has("forces.reference_length") ? c.quantity("forces.reference_length") : s.diameter;
  if (c.has("probes.pressure_a") && c.has("probes.pressure_b")) {
    const auto& a = c.reals("probes.pressure_a");
    const auto& b = c.reals("probes.pressure_b");
    if (a.size() != 2 || b.size() != 2) throw InputError(c.where("probes.pressure_a"), "a probe needs two coordinates", {}, "[\"x\", \"y\"]");
    s.pressure_probes = {{a[0], a[1]}, {b[0], b[1]}};
  }
  if (s.cx - 0.5 * s.diameter <= 0 || s.cy - 0.5 * s.diameter <= 0 || s.cy + 0.5 * s.diameter >= s.height || s.cx + 0.5 * s.diameter >= s.length)
    throw InputError(c.where("geometry.cylinder_x"), "the cylinder does not fit inside the channel", {}, "0 < x - d/2, x + d/2 < length, 0 < y - d/2, y + d/2 < height");
  s.unsteady = c.text("numerics.mode") == "unsteady";
  if (s.unsteady) {
    s.end_time = c.quantity("numerics.end_time");
    s.dt = c.quantity("numerics.time_step");
  }
  s.max_iterations = static_cast<int>(c.integer("numerics.max_iterations"));
  s.residual = c.real("numerics.residual");
  return s;
}

Scene arrayScene(const Case& c) {
  Scene s;
  s.kind = Scene::Kind::periodic_array;
  s.cell = c.quantity("geometry.cell");
  const double phi = c.quantity("geometry.solid_fraction");
  s.radius = s.cell * std::sqrt(phi / M_PI);
  s.depth = s.cell / 10;
  s.rho = c.quantity("fluid.density");
  s.nu = c.quantity("fluid.viscosity") / s.rho;
  s.mean_velocity = c.quantity("flow.mean_velocity");
  s.max_iterations = static_cast<int>(c.integer("numerics.max_iterations"));
  s.residual = c.real("numerics.residual");
  return s;
}

Scene imageScene(const Case& c) {
  Scene s;
  s.kind = Scene::Kind::image;
  s.mask = c.path("geometry.mask");
  s.pixel = c.quantity("geometry.pixel_size");
  s.grain_dark = c.text("geometry.grains") == "dark";
  s.cells_per_pixel = c.real("numerics.cells_per_pixel");
  s.rho = c.quantity("fluid.density");
  s.nu = c.quantity("fluid.viscosity") / s.rho;
  s.pressure_drop = c.quantity("flow.pressure_drop") / s.rho;
  s.max_iterations = static_cast<int>(c.integer("numerics.max_iterations"));
  s.residual = c.real("numerics.residual");
  return s;
}

/// The primary metric of a kind: the one whose error the ladder records.
const char* primaryMetric(const std::string& kind) {
  if (kind == "cylinder-channel") return "c_D";  // steady; unsteady cases report c_D_mean too
  if (kind == "periodic-array") return "F_star";
  return "permeability";
}

void addMetrics(const Scene& s, const Result& r, RunOutput& out) {
  auto put = [&](const char* name, const std::optional<double>& v, const char* unit = "1") {
    if (v) {
      out.metrics[name] = *v;
      out.units[name] = unit;
    }
  };
  put("c_D", r.c_d);
  put("c_L", r.c_l);
  put("dp", r.dp, "Pa");
  put("c_D_max", r.c_d_max);
  put("c_D_mean", r.c_d_mean);
  put("c_L_max", r.c_l_max);
  put("St", r.strouhal);
  put("F_star", r.f_star);
  if (s.kind == Scene::Kind::periodic_array && r.permeability) {
    put("k_over_L2", *r.permeability / (s.cell * s.cell));
    put("permeability", r.permeability, "m2");
  }
  if (s.kind == Scene::Kind::image) {
    put("permeability", r.permeability, "D");
    put("porosity_total", r.porosity_total);
    put("porosity_connected", r.porosity_connected);
    put("porosity_mesh", r.porosity_mesh);
  }
}

}  // namespace

std::string notConvergedText(const Scene& s, const Result& r, const std::string& case_dir) {
  return fmt::format("simpleFoam did not converge in {} ({} iterations, the cap numerics.max_iterations = {}): initial residuals {}, "
                     "target numerics.residual = {:g}; its last iterate is not reported as a value (raise numerics.max_iterations)",
                     case_dir, r.iterations, s.max_iterations, residualText(r.residuals), s.residual);
}

Scene peerScene(const Case& c) {
  if (c.kind() == "cylinder-channel") return cylinderScene(c);
  if (c.kind() == "periodic-array") return arrayScene(c);
  if (c.kind() == "image-permeability") return imageScene(c);
  throw InputError(c.where("case.kind"), "the OpenFOAM peer does not run this kind", c.kind(), "cylinder-channel, periodic-array or image-permeability");
}

RunOutput runPeer(const Case& c, const RunContext& ctx, const PeerRunOptions& options) {
  const Installation inst = options.runner ? Installation{true, "(test runner)", {}, {}} : detect();
  if (!inst.available) throw InputError({c.file().string(), 0, 0, "case.kind"}, "cannot run this case: " + inst.reason, {}, "OpenFOAM v1912 installed");
  Scene scene = peerScene(c);
  std::vector<int> levels;
  if (options.levels) {
    levels = *options.levels;
  } else if (c.kind() != "image-permeability" && c.has("numerics.levels")) {
    for (auto v : c.integers("numerics.levels")) levels.push_back(static_cast<int>(v));
  }
  if (levels.empty()) levels.push_back(c.kind() == "image-permeability" ? 0 : static_cast<int>(c.integer("numerics.cells_around")));
  for (int l : levels)
    if (c.kind() != "image-permeability" && (l < 8 || l > 4096 || l % 4 != 0))
      throw InputError(c.where("numerics.levels"), "a resolution level must be a multiple of 4 from 8 to 4096", std::to_string(l), "8, 12, 16, ... 4096");
  const Acceptance* primary = c.acceptanceFor(primaryMetric(c.kind()));
  RunOutput out;
  out.details["solver"] = "openfoam " + inst.version;
  if (scene.kind == Scene::Kind::cylinder_channel) out.details["Re"] = scene.u_ref * scene.l_ref / scene.nu;
  out.details["ranks"] = options.ranks;
  nlohmann::json ladder = nlohmann::json::array();
  nlohmann::json warnings = nlohmann::json::array();
  Progress progress("openfoam " + c.name(), levels.size(), ctx.quiet);
  Result last;
  for (std::size_t i = 0; i < levels.size(); ++i) {
    if (c.kind() != "image-permeability") scene.cells_around = levels[i];
    const std::string sub = levels.size() > 1 ? fmt::format("openfoam-level{}", i) : "openfoam";
    last = options.runner ? options.runner(scene, ctx.out_dir / sub, options.ranks) : runCase(scene, ctx.out_dir / sub, options.ranks);
    if (!last.ok) throw std::runtime_error(fmt::format("OpenFOAM run of '{}' failed (case kept in {}): {}", c.name(), (ctx.out_dir / sub).string(), last.failure));
    nlohmann::json row = {{"level", i}, {"cells_around", levels[i]}, {"cells", last.cells}, {"ranks", last.ranks},
                          {"mesh_seconds", last.mesh_seconds}, {"solve_seconds", last.solve_seconds},
                          {"wall_seconds", last.mesh_seconds + last.solve_seconds}, {"iterations", last.iterations}, {"case_dir", sub}};
    if (!last.converged) {
      // The last iterate of a SIMPLE loop that ran out of iterations is no solution: no value, no
      // error, so the row stays out of the observed order and of the speed-against-error plot.
      row["status"] = "not converged";
      row["residuals"] = last.residuals;
      warnings.push_back(notConvergedText(scene, last, sub));
      if (!ctx.quiet) std::fprintf(stderr, "mmval: warning: %s: %s\n", c.name().c_str(), warnings.back().get<std::string>().c_str());
    } else {
      RunOutput level_out;
      addMetrics(scene, last, level_out);
      auto it = level_out.metrics.find(primaryMetric(c.kind()));
      if (it != level_out.metrics.end()) {
        row["value"] = it->second;
        if (primary != nullptr && !primary->reference.isInterval() && primary->reference.value != 0)
          row["error"] = (it->second - primary->reference.value) / primary->reference.value;
      }
    }
    ladder.push_back(row);
    progress.update(i + 1);
  }
  progress.finish();
  addObservedOrder(ladder, levels);
  out.details["ladder"] = ladder;
  out.details["cells"] = last.cells;
  if (!warnings.empty()) out.details["warnings"] = warnings;
  addMetrics(scene, last, out);
  if (!last.converged) {
    // Reported as "not converged", never as a value: every metric of the finest level is null
    // but the porosities (acceptance entries on them fail: nothing was measured); the status and
    // residuals are in details.
    out.details["status"] = "not converged";
    out.details["residuals"] = last.residuals;
    out.details["iterations"] = last.iterations;
    for (auto& [name, value] : out.metrics)
      if (name.rfind("porosity", 0) != 0) value = std::nan("");  // porosities are the geometry's and the mesh's, not the flow's
  }
  out.files.push_back(levels.size() > 1 ? fmt::format("openfoam-level{}", levels.size() - 1) : "openfoam");
  return out;
}

}  // namespace mmval::openfoam
