#include "ResolvedStages.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <fmt/format.h>

#include "CaseScene.hpp"
#include "MicromodelDetail.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Checkpoint.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/VtkWriter.hpp"
#include "mmval/simulate/FieldOutput.hpp"

namespace mmval::particles::resolved {

namespace sim = mmval::simulate;

namespace {

constexpr double kPi = 3.14159265358979323846;
/// Every move refactorises the coupled Stokes matrix (3 unknowns per cell): beyond ~1e6 cells the
/// direct solver's memory and time leave this machine's range, so say so before starting.
constexpr double kMaxCells = 1e6;
constexpr const char* kCheckpointFormat = "mmval-resolved-checkpoint-2";

/// The particles at their start positions, each checked to lie inside the channel, clear of
/// every surface by the contact gap.
void placeParticles(const Case& c, double a, Scene& sc) {
  const auto& px = c.reals("particles.x");
  const auto& py = c.reals("particles.y");
  for (std::size_t k = 0; k < px.size(); ++k) {
    Disk D;
    D.x = {px[k], py[k]};
    D.a = a;
    sc.disks.push_back(D);
    const Nearest n = nearestSurface(sc, k);
    const bool inside = D.x.x() >= a && D.x.x() <= sc.L - a && D.x.y() >= a && D.x.y() <= sc.W - a;
    if (!inside || n.gap < sc.contact_gap)
      throw InputError(c.where("particles.x"), fmt::format("particle {} at ({:.4g}, {:.4g}) um overlaps a grain, a wall, an obstacle or another particle", k + 1,
                                                         px[k] * 1e6, py[k] * 1e6),
                       fmt::format("surface gap {:.3g} um", n.gap * 1e6), fmt::format(">= the contact gap {:.3g} um (numerics.contact_gap cells)", sc.contact_gap * 1e6));
  }
}

/// The uniform grid of cells `dx` over the channel, parabolic inflow of mean U at x = 0 and an
/// open outlet (U = 0: a closed box).
sim::FlowProblem flowProblem(const Scene& sc, double dx, double mu, double rho_f) {
  sim::FlowProblem prob;
  prob.x = sim::uniformAxis(0, sc.L, std::max(4, static_cast<int>(std::lround(sc.L / dx))));
  prob.y = sim::uniformAxis(0, sc.W, std::max(4, static_cast<int>(std::lround(sc.W / dx))));
  prob.viscosity = mu;
  prob.density = rho_f;
  prob.depth = sc.h;
  if (sc.U > 0) {
    const double W = sc.W, Umax = 1.5 * sc.U;
    prob.boundary[static_cast<std::size_t>(sim::Side::west)].type = sim::BoundaryType::velocity;
    prob.boundary[static_cast<std::size_t>(sim::Side::west)].velocity = [W, Umax](double y) { return 4 * Umax * y * (W - y) / (W * W); };
    prob.boundary[static_cast<std::size_t>(sim::Side::east)].type = sim::BoundaryType::pressure;
  }
  return prob;
}

/// Checkpoint: positions, states, counters and the outputs so far, as JSON (doubles round-trip exactly).
void saveCheckpoint(const std::filesystem::path& file, const std::string& fingerprint, std::int64_t f, const Transport& tr, const Scene& sc) {
  nlohmann::json j;
  j["format"] = kCheckpointFormat;
  j["scenario"] = fingerprint;
  j["frame"] = f;
  j["t"] = tr.t;
  j["counters"] = {tr.solves, tr.steps, tr.contacts, tr.attached};
  for (const auto& D : sc.disks) j["disks"].push_back({D.x.x(), D.x.y(), static_cast<int>(D.state), D.attached_at});
  for (const auto& tp : tr.trajectories.points)
    j["trajectory"].push_back({tp.frame, tp.particle, tp.t, tp.x, tp.y, tp.state == "mobile" ? 0 : 1});
  j["permeability_csv"] = tr.permeability_csv;
  j["retention_csv"] = tr.retention_csv;
  writeFileAtomic(file, j.dump());
}

/// Restores tr and the disks from a checkpoint; returns the first frame still to run. Throws
/// InputError naming run.checkpoint_every when the file is not this case's.
std::int64_t loadCheckpoint(const Case& c, const std::filesystem::path& file, const std::string& fingerprint, Transport& tr, Scene& sc) {
  try {
    const nlohmann::json j = nlohmann::json::parse(readBinaryFile(file));
    if (j.at("format") != kCheckpointFormat) throw std::runtime_error("unknown format");
    if (j.at("scenario").get<std::string>() != fingerprint) throw std::runtime_error("it belongs to another version of this case");
    if (j.at("disks").size() != sc.disks.size()) throw std::runtime_error("other number of particles");
    const std::int64_t first = j.at("frame").get<std::int64_t>() + 1;
    tr.frame = first;
    tr.t = j.at("t").get<double>();
    const auto& n = j.at("counters");
    tr.solves = n[0];
    tr.steps = n[1];
    tr.contacts = n[2];
    tr.attached = n[3];
    for (std::size_t k = 0; k < sc.disks.size(); ++k) {
      const auto& d = j["disks"][k];
      sc.disks[k].x = {d[0].get<double>(), d[1].get<double>()};
      sc.disks[k].state = static_cast<State>(d[2].get<int>());
      sc.disks[k].attached_at = d[3].get<double>();
    }
    for (const auto& p : j.at("trajectory")) {
      TrackPoint tp;
      tp.frame = p[0];
      tp.particle = p[1];
      tp.t = p[2];
      tp.x = p[3];
      tp.y = p[4];
      tp.z = 0.5 * sc.h;
      tp.state = p[5].get<int>() == 0 ? "mobile" : "deposited";
      tr.trajectories.points.push_back(tp);
    }
    tr.permeability_csv = j.at("permeability_csv").get<std::string>();
    tr.retention_csv = j.at("retention_csv").get<std::string>();
    return first;
  } catch (const std::exception& e) {
    throw InputError(c.where("run.checkpoint_every"), fmt::format("cannot resume from {}: {}", file.string(), e.what()), {},
                     "delete the checkpoint (or the .partial folder) to start afresh");
  }
}

std::int64_t countState(const Scene& sc, State s) {
  return std::count_if(sc.disks.begin(), sc.disks.end(), [s](const Disk& D) { return D.state == s; });
}

}  // namespace

Setup setUpResolved(const Case& c) {
  Setup setup;
  Scene& sc = setup.scene;
  sc.L = c.quantity("channel.length");
  sc.W = c.quantity("channel.width");
  if (c.has("geometry.mask")) {
    double porosity = 0;
    const PixelMask solid = detail::loadGeometry(c, setup.geometry, porosity);
    const double px = c.quantity("geometry.pixel_size");
    sc.grains = std::make_shared<sim::MaskShape>(solid, px);
    sc.L = static_cast<double>(solid.cols()) * px;
    sc.W = static_cast<double>(solid.rows()) * px;
    setup.geometry["porosity_connected"] = porosity;
  }
  sc.U = c.quantity("channel.mean_velocity");
  sc.h = c.quantity("channel.depth");
  const double mu = c.quantity("fluid.viscosity"), rho_f = c.quantity("fluid.density");
  const double d = c.quantity("particles.diameter"), rho_p = c.quantity("particles.density");
  const double a = 0.5 * d;
  const auto& px = c.reals("particles.x");
  const auto& py = c.reals("particles.y");
  if (px.size() != py.size())
    throw InputError(c.where("particles.y"), "one y per particle x", fmt::format("{} values", py.size()), fmt::format("{} (as particles.x)", px.size()));
  if (px.empty()) throw InputError(c.where("particles.x"), "no particles", "[]", "at least one start position");
  const auto& ox = c.reals("obstacles.x");
  const auto& oy = c.reals("obstacles.y");
  const auto& od = c.reals("obstacles.diameter");
  if (oy.size() != ox.size() || od.size() != ox.size())
    throw InputError(c.where("obstacles.diameter"), "obstacles need one x, y and diameter each",
                     fmt::format("{} x, {} y, {} diameters", ox.size(), oy.size(), od.size()), "equal counts");
  const int per_d = static_cast<int>(c.integer("numerics.cells_per_diameter"));
  const double dx = d / per_d;
  sc.contact_gap = c.real("numerics.contact_gap") * dx;
  sc.capture = c.quantity("deposition.capture_distance");
  if (sc.capture > 0 && sc.capture < sc.contact_gap)
    sc.capture = sc.contact_gap;  // attachment is decided no closer than the grid lets surfaces come (stated in result.json)
  if (!(sc.W > d + 2 * sc.contact_gap))
    throw InputError(c.where("channel.width"), "the particles do not fit across the channel with the contact gap",
                     fmt::format("{:.4g} um", sc.W * 1e6), fmt::format("> diameter + 2 gaps = {:.4g} um", (d + 2 * sc.contact_gap) * 1e6));
  for (std::size_t k = 0; k < ox.size(); ++k) {
    if (!(od[k] > 0)) throw InputError(c.where("obstacles.diameter"), fmt::format("obstacle {} has no size", k + 1), fmt::format("{:g} um", od[k] * 1e6), "> 0");
    sc.obstacles.push_back({ox[k], oy[k], 0.5 * od[k]});
  }
  placeParticles(c, a, sc);
  const double area = kPi * a * a;  // per unit depth
  sc.weight = (rho_p - rho_f) * area * Eigen::Vector2d(c.quantity("physics.gravity_x"), c.quantity("physics.gravity_y"));
  const double duration = c.quantity("run.duration"), dt_out = c.quantity("run.output_interval");
  if (dt_out > duration) throw InputError(c.where("run.output_interval"), "longer than the run", fmt::format("{:g} s", dt_out), fmt::format("<= run.duration ({:g} s)", duration));
  const double cells = std::ceil(sc.L / dx) * std::ceil(sc.W / dx);
  if (cells > kMaxCells)
    throw InputError(c.where("numerics.cells_per_diameter"), "the resolved grid is too large for the direct Stokes solver",
                     fmt::format("{:.3g} cells ({:.4g} x {:.4g} um at {:.3g} um per cell)", cells, sc.L * 1e6, sc.W * 1e6, dx * 1e6),
                     fmt::format("at most {:.0e} cells: crop the image (geometry.crop), shorten the channel, or fewer cells per diameter", kMaxCells));
  setup.problem = flowProblem(sc, dx, mu, rho_f);
  setup.viscosity_pa_s = mu;
  setup.radius_m = a;
  setup.cells_per_diameter = per_d;
  setup.cell_m = dx;
  setup.stepping = {dt_out, c.real("numerics.max_step_fraction") * dx};
  return setup;
}

double cleanPressureDrop(sim::ResolvedStokes& fluid, const Scene& sc) {
  Scene clean = sc;
  clean.disks.clear();
  std::vector<int> body;
  fluid.setShape(shapeOf(clean, body));
  fluid.loads(std::vector<sim::RigidMotion>(static_cast<std::size_t>(fixedBodies(clean))), 1.0);
  return pressureDrop(fluid);
}

void recordFrame(Transport& tr, const Scene& sc, const sim::ResolvedStokes& fluid, const FrameScales& scales) {
  for (std::size_t k = 0; k < sc.disks.size(); ++k) {
    const Disk& D = sc.disks[k];
    if (D.state == State::left) continue;
    TrackPoint tp;
    tp.frame = tr.frame;
    tp.particle = static_cast<std::int64_t>(k);
    tp.t = tr.t;
    tp.x = D.x.x();
    tp.y = D.x.y();
    tp.z = 0.5 * sc.h;
    tp.state = D.state == State::mobile ? "mobile" : "deposited";
    tr.trajectories.points.push_back(tp);
  }
  const double dp = pressureDrop(fluid);
  const std::int64_t dep = countState(sc, State::deposited), gone = countState(sc, State::left);
  const auto all = static_cast<std::int64_t>(sc.disks.size());
  tr.retention_csv += tables::formatRow(tables::RetentionRow{tr.frame, tr.t, all, all - dep - gone, dep, gone});
  tr.permeability_csv += tables::formatRow(tables::PermeabilityRow{tr.frame, tr.t, dp > 0 ? scales.mu_u_l / dp : 0.0,
                                                                   (sc.U > 0 && dp > 0 && scales.dp0_pa > 0) ? scales.dp0_pa / dp : 1.0, dp, dep,
                                                                   tr.solves});
  ++tr.frame;
}

void advanceTo(double t_next, const Stepping& stepping, Transport& tr, Scene& sc, sim::ResolvedStokes& fluid) {
  const double max_move = stepping.max_move_m;
  while (tr.t < t_next - 1e-12 * stepping.output_interval_s) {
    // Each particle may move max_move, or a quarter of its distance to the nearest surface when
    // that is larger (at most 4 max_move): long steps in open pores, short ones near contacts.
    double dt = t_next - tr.t;
    for (std::size_t k = 0; k < sc.disks.size(); ++k) {
      const double speed = tr.velocities[k].norm();
      if (speed <= 0 || sc.disks[k].state != State::mobile) continue;
      const double allowed = std::clamp(0.25 * (nearestSurface(sc, k).gap - sc.contact_gap), max_move, 4 * max_move);
      dt = std::min(dt, allowed / speed);
    }
    // Explicit midpoint: the velocity at the half step moves the particles.
    std::vector<Eigen::Vector2d> x0;
    for (const auto& D : sc.disks) x0.push_back(D.x);
    for (std::size_t k = 0; k < sc.disks.size(); ++k) sc.disks[k].x = x0[k] + 0.5 * dt * tr.velocities[k];
    const std::vector<Eigen::Vector2d> vh = velocities(fluid, sc, tr.solves);
    for (std::size_t k = 0; k < sc.disks.size(); ++k) sc.disks[k].x = x0[k] + dt * vh[k];
    tr.t += dt;
    ++tr.steps;
    tr.contacts += settleContacts(sc, tr.t, tr.attached);
    for (std::size_t k = 0; k < sc.disks.size(); ++k)
      if (!sc.disks[k].x.allFinite()) throw std::runtime_error(fmt::format("particles-resolved: particle {} left the finite numbers at t = {:.4g} s", k + 1, tr.t));
    tr.velocities = velocities(fluid, sc, tr.solves);
  }
  tr.t = t_next;
}

Transport transport(const Case& c, const RunContext& ctx, const Stepping& stepping, Scene& sc, sim::ResolvedStokes& fluid, const FrameScales& scales) {
  Transport tr;
  tr.permeability_csv = tables::permeabilityHeader();
  tr.retention_csv = tables::retentionHeader();
  const std::int64_t frames = outputFrames(c);
  Progress progress("particles-resolved", static_cast<std::size_t>(frames), ctx.quiet);
  const std::filesystem::path ckpt = ctx.out_dir / "checkpoint.json";
  const std::string fingerprint = checkpointFingerprint(c);
  const std::int64_t checkpoint_every = c.integer("run.checkpoint_every"), stop_after = c.integer("run.stop_after_frames");
  std::int64_t first = 1;
  if (ctx.resume && std::filesystem::exists(ckpt)) {
    first = loadCheckpoint(c, ckpt, fingerprint, tr, sc);
    const int counted = tr.solves;
    tr.velocities = velocities(fluid, sc, tr.solves);  // the same solve the interrupted run ended its frame with
    tr.solves = counted;
  } else {
    tr.velocities = velocities(fluid, sc, tr.solves);
    recordFrame(tr, sc, fluid, scales);
  }
  tr.resumed_from = first - 1;
  for (std::int64_t f = first; f <= frames; ++f) {
    advanceTo(static_cast<double>(f) * stepping.output_interval_s, stepping, tr, sc, fluid);
    recordFrame(tr, sc, fluid, scales);
    progress.update(static_cast<std::size_t>(f));
    if (f < frames && ((checkpoint_every > 0 && f % checkpoint_every == 0) || f == stop_after)) saveCheckpoint(ckpt, fingerprint, f, tr, sc);
    if (f == stop_after && f < frames)
      throw RunStopped(fmt::format("stopped after {} output frames as asked (run.stop_after_frames); {} holds the checkpoint, "
                                   "continue with `mmval run --resume`",
                                   f, ckpt.string()));
  }
  progress.finish();
  return tr;
}

std::vector<std::string> writeResolvedFiles(const std::filesystem::path& dir, Transport& tr, const Scene& sc, const sim::ResolvedStokes& fluid,
                                            double pixel_size_m) {
  auto& points = tr.trajectories.points;
  std::sort(points.begin(), points.end(), [](const TrackPoint& p, const TrackPoint& q) {
    return p.particle != q.particle ? p.particle < q.particle : p.frame < q.frame;
  });
  std::vector<std::string> files = {"trajectories.csv", "retention.csv", "speed.png", "fields.vtr"};
  writeTracksCsv(dir / "trajectories.csv", tr.trajectories, pixel_size_m);
  writeFileAtomic(dir / "retention.csv", tr.retention_csv);
  if (sc.U > 0) {  // a closed box has no flow through it
    writeFileAtomic(dir / "permeability.csv", tr.permeability_csv);
    files.push_back("permeability.csv");
  }
  std::vector<std::vector<Eigen::Vector2d>> paths(sc.disks.size());
  for (const auto& tp : points) paths[static_cast<std::size_t>(tp.particle)].emplace_back(tp.x, tp.y);
  sim::writeSpeedPng(fluid, dir / "speed.png", 1200, paths);
  sim::writeVtr(fluid, dir / "fields.vtr");
  // The particles as a .vtp series (docs/outputs.md): the disks' centres in the fluid grid's frame,
  // the plane z = 0 of fields.vtr; their height (mid-depth of a Hele-Shaw chip) is the z array.
  const std::vector<std::string> series = vtk::writeParticleSeries(dir, "particles", tr.trajectories,
                                                                   [](const TrackPoint& q) { return std::array<double, 3>{q.x, q.y, 0.0}; });
  if (!series.empty()) files.push_back(series.back());
  std::filesystem::remove(dir / "checkpoint.json");  // complete: nothing to resume
  return files;
}

RunOutput resolvedResult(const Setup& setup, const Transport& tr, const Scene& sc, const sim::ResolvedStokes& fluid, double dp0_pa, double wall_s) {
  RunOutput out;
  setDetail(out.details, DetailField::resumed_from_frame, tr.resumed_from);
  // First particle's velocity at the end: the terminal velocity of a settling scene.
  const bool first_mobile = sc.disks[0].state == State::mobile;
  const Eigen::Vector2d v0 = first_mobile ? tr.velocities[0] : Eigen::Vector2d::Zero();
  if (first_mobile) {  // a deposited or departed particle has no velocity to report
    out.metrics["final_velocity_x"] = v0.x();
    out.metrics["final_velocity_y"] = v0.y();
    out.units["final_velocity_x"] = out.units["final_velocity_y"] = "um/s";
  }
  // Faxen's cylinder midway between two plates (simulate::faxenCylinderResistance), for a particle
  // settling along x in a channel of half-width l = W/2 at rest: U = F / R (plane 2D only).
  if (sc.h == 0 && sc.U == 0 && sc.weight.x() != 0) {
    const double a = setup.radius_m, l = 0.5 * sc.W;
    const double faxen = sc.weight.x() / sim::faxenCylinderResistance(a, l, setup.viscosity_pa_s);
    out.metrics["faxen_velocity_ratio"] = faxen != 0 ? v0.x() / faxen : 0.0;
    out.details["faxen"] = {{"velocity_um_s", faxen * 1e6},
                            {"a_over_l", a / l},
                            {"offset_from_midline_um", (sc.disks[0].x.y() - l) * 1e6},
                            {"meaning", "terminal velocity of particle 1 over Faxen's series for a cylinder midway between plates"}};
  }
  const std::int64_t dep = countState(sc, State::deposited), left = countState(sc, State::left);
  out.metrics["deposited"] = static_cast<double>(dep);
  out.metrics["left"] = static_cast<double>(left);
  out.metrics["inside"] = static_cast<double>(sc.disks.size()) - static_cast<double>(dep + left);
  out.metrics["retained_fraction"] = static_cast<double>(dep) / static_cast<double>(sc.disks.size());
  if (sc.U > 0) {
    const double dp = pressureDrop(fluid);
    out.metrics["k_over_k0"] = dp != 0 ? dp0_pa / dp : 1.0;
    out.details["pressure_drop_clean_pa"] = dp0_pa;
    out.details["pressure_drop_final_pa"] = dp;
  }
  out.metrics["wall_time"] = wall_s;
  out.units["wall_time"] = "s";
  const int per_d = setup.cells_per_diameter;
  setDetail(out.details, DetailField::coupling,
            {{"mode", "resolved"},
             {"cells_per_diameter", per_d},
             {"fluid_grid_cells", {setup.problem.x.cells(), setup.problem.y.cells()}},
             {"cell_um", setup.cell_m * 1e6},
             {"description", "resolved immersed boundary, Stokes mobility of free rigid disks"}});
  if (per_d < 8)
    setDetail(out.details, DetailField::warnings,
              nlohmann::json::array({fmt::format("{} cells per diameter is below the ~8 a resolved particle needs: forces are coarse", per_d)}));
  if (sc.grains) out.details["geometry"] = setup.geometry;
  out.details["steps"] = tr.steps;
  out.details["stokes_solves"] = tr.solves;
  out.details["factorisations"] = fluid.factorisations();
  out.details["contacts_resolved"] = tr.contacts;
  out.details["attached"] = tr.attached;
  out.details["contact_gap_um"] = sc.contact_gap * 1e6;
  out.details["capture_distance_used_um"] = sc.capture * 1e6;
  return out;
}

}  // namespace mmval::particles::resolved
