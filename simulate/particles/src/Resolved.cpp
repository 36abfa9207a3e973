// "particles-resolved": particles that span many fluid cells, moved through
// creeping flow by the resolved immersed boundary (issue 6, the coupling mode
// for d/dx >= ~8). Each particle is a rigid disk in the 2D flow (a cylinder
// through the plane, or with channel.depth > 0 a pillar spanning a Hele-Shaw
// chip); its motion is the Stokes mobility problem of ResolvedStokes: no
// drag law, no wall correction, no lubrication model: the flow between the
// particle, the walls, the obstacles and the other particles is solved on the
// grid. Particle inertia is left out (the overdamped limit: St << 1 is what
// makes a scene Stokes flow in the first place).
//
// Time stepping: explicit midpoint (two mobility solves per step) with the
// step set by the fastest particle moving at most numerics.max_step_fraction
// of a cell. Contacts: surfaces closer than numerics.contact_gap (in cells;
// the immersed boundary needs a fluid node between two surfaces) are held
// apart by moving the particle back along the normal, and a particle within
// deposition.capture_distance of a wall, an obstacle or a deposited particle
// sticks there and becomes a fixed body: the flow and the pressure drop then
// feel it (four-way coupling; permeability.csv).
// Outputs retention.csv and permeability.csv follow the one schema of
// mmval/core/OutputTables.hpp: every particle is injected at t = 0, and k is
// the channel's Darcy permeability mu U L / dp (U the mean inflow speed, L the
// distance between the first and last cell centres along x, where pressureDrop
// measures dp), so k/k0 = dp0/dp.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Tracks.hpp"
#include "CaseScene.hpp"
#include "MicromodelDetail.hpp"
#include "ResolvedScene.hpp"
#include "mmval/core/Checkpoint.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/particles/Kinds.hpp"
#include "mmval/particles/Micromodel.hpp"
#include "mmval/simulate/FieldOutput.hpp"
#include "mmval/simulate/ResolvedStokes.hpp"

namespace mmval::particles {

namespace {

namespace sim = mmval::simulate;
using namespace resolved;
constexpr double kPi = 3.14159265358979323846;

void declareResolved(Schema& s) {
  declareMask(s, {.mask_doc = "Grains from a binary image of the pore geometry, also looked for from the folder above the case file's; it then sets "
                             "the channel's length and width (absent: a plain channel with channel.length x channel.width)",
                 .pixel_default = "1 um",
                 .optional = true});
  s.integer("geometry.dilate", "Grow the grains by this many pixels; 0: as drawn").def(0).min(0).max(1000);
  s.integerList("geometry.crop", "Window of the image [first column, first row, columns, rows]; absent: the whole image").optional();
  s.quantity("channel.length", "um", "Channel length along x (inlet x = 0, outlet x = length)").def("160 um").positive();
  s.quantity("channel.width", "um", "Channel width (walls at y = 0 and y = width)").def("40 um").positive();
  s.quantity("channel.mean_velocity", "mm/s",
             "Mean speed of the parabolic inflow at x = 0 (open outlet at x = length); 0: a closed box of fluid at rest")
      .def(0.0)
      .nonNegative();
  s.quantity("channel.depth", "um", "Hele-Shaw depth (friction -12 mu u / h^2; the disks then span the depth); 0: plane 2D").def(0.0).nonNegative();
  declareFluid(s, {});
  s.quantity("particles.diameter", "um", "Particle (disk) diameter").def("10 um").positive();
  s.quantity("particles.density", "g/cm3", "Particle density").def("1.05 g/cm3").positive();
  s.quantityList("particles.x", "um", "Start x of each particle's centre").def(std::vector<double>{80e-6});
  s.quantityList("particles.y", "um", "Start y of each particle's centre").def(std::vector<double>{20e-6});
  s.quantityList("obstacles.x", "um", "Centres x of fixed circular obstacles (grains)").def(std::vector<double>{});
  s.quantityList("obstacles.y", "um", "Centres y of the obstacles").def(std::vector<double>{});
  s.quantityList("obstacles.diameter", "um", "Diameters of the obstacles").def(std::vector<double>{});
  s.quantity("physics.gravity_x", "m/s2", "Gravity along +x (a vertical channel: -9.81)").def(0.0);
  s.quantity("physics.gravity_y", "m/s2", "Gravity along +y (towards the wall y = 0: -9.81)").def(0.0);
  s.quantity("deposition.capture_distance", "um", "Surface gap at which a particle sticks to a wall, obstacle or deposit (0: never)").def(0.0).nonNegative();
  s.integer("numerics.cells_per_diameter", "Grid cells across a particle diameter (the paper's rule: ~8 at least)").def(16).min(4).max(200);
  s.real("numerics.max_step_fraction", "Largest particle displacement per step near a surface, in cells (up to 4 x this in open pores)").def(0.5).min(0.01).max(2);
  s.real("numerics.contact_gap", "Smallest surface gap kept between a moving particle and any surface, in cells").def(1.0).min(0.5).max(4);
  s.quantity("run.duration", "s", "Physical time simulated").def("5 s").positive();
  s.quantity("run.output_interval", "s", "Output (frame) interval").def("0.5 s").positive();
  s.quantity("output.pixel_size", "um", "Pixel size for the pixel columns of trajectories.csv (0: none)").def(0.0).nonNegative();
  s.integer("run.checkpoint_every", "Write checkpoint.json every this many output frames (0: never); `mmval run --resume` continues from it").def(10).min(0);
  s.integer("run.stop_after_frames", "Stop (as if killed) after this many output frames, leaving a checkpoint (0: run to the end; tests)").def(0).min(0);
}

RunOutput runResolved(const Case& c, const RunContext& ctx) {
  outputFrames(c);  // a run whose frames cannot fit in memory is refused before the mask is read
  Scene sc;
  sc.L = c.quantity("channel.length");
  sc.W = c.quantity("channel.width");
  nlohmann::json geometry = nlohmann::json::object();
  if (c.has("geometry.mask")) {
    double porosity = 0;
    const PixelMask solid = detail::loadGeometry(c, geometry, porosity);
    const double px = c.quantity("geometry.pixel_size");
    sc.grains = std::make_shared<sim::MaskShape>(solid, px);
    sc.L = static_cast<double>(solid.cols()) * px;
    sc.W = static_cast<double>(solid.rows()) * px;
    geometry["porosity_connected"] = porosity;
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
  const double area = kPi * a * a;  // per unit depth
  sc.weight = (rho_p - rho_f) * area * Eigen::Vector2d(c.quantity("physics.gravity_x"), c.quantity("physics.gravity_y"));
  const double duration = c.quantity("run.duration"), dt_out = c.quantity("run.output_interval");
  if (dt_out > duration) throw InputError(c.where("run.output_interval"), "longer than the run", fmt::format("{:g} s", dt_out), fmt::format("<= run.duration ({:g} s)", duration));

  // Every move refactorises the coupled Stokes matrix (3 unknowns per cell): beyond ~1e6 cells the
  // direct solver's memory and time leave this machine's range, so say so before starting.
  const double cells = std::ceil(sc.L / dx) * std::ceil(sc.W / dx);
  constexpr double kMaxCells = 1e6;
  if (cells > kMaxCells)
    throw InputError(c.where("numerics.cells_per_diameter"), "the resolved grid is too large for the direct Stokes solver",
                     fmt::format("{:.3g} cells ({:.4g} x {:.4g} um at {:.3g} um per cell)", cells, sc.L * 1e6, sc.W * 1e6, dx * 1e6),
                     fmt::format("at most {:.0e} cells: crop the image (geometry.crop), shorten the channel, or fewer cells per diameter", kMaxCells));
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
  sim::ResolvedStokes fluid(prob);

  // The flow with no particle: the reference pressure drop of the clean channel.
  double dp0 = 0;
  {
    Scene clean = sc;
    clean.disks.clear();
    std::vector<int> body;
    fluid.setShape(shapeOf(clean, body));
    fluid.loads(std::vector<sim::RigidMotion>(static_cast<std::size_t>(fixedBodies(clean))), 1.0);
    dp0 = pressureDrop(fluid);
  }

  std::int64_t out_resumed_from = 0;
  Tracks traj;
  std::string perm = tables::permeabilityHeader(), retention = tables::retentionHeader();
  // Darcy: k = mu U L / dp over the span pressureDrop measures (first to last cell centre).
  const double mu_U_L = mu * sc.U * (prob.x.centre(prob.x.cells() - 1) - prob.x.centre(0));
  const double pixel = c.quantity("output.pixel_size");
  int solves = 0, steps = 0, contacts = 0, attached = 0;
  double t = 0;
  std::int64_t frame = 0;
  const std::int64_t frames = outputFrames(c);
  Progress progress("particles-resolved", static_cast<std::size_t>(frames), ctx.quiet);
  const double max_move = c.real("numerics.max_step_fraction") * dx;
  const auto t0 = std::chrono::steady_clock::now();
  auto record = [&]() {
    for (std::size_t k = 0; k < sc.disks.size(); ++k) {
      const Disk& D = sc.disks[k];
      if (D.state == State::left) continue;
      TrackPoint tp;
      tp.frame = frame;
      tp.particle = static_cast<std::int64_t>(k);
      tp.t = t;
      tp.x = D.x.x();
      tp.y = D.x.y();
      tp.z = 0.5 * sc.h;
      tp.state = D.state == State::mobile ? "mobile" : "deposited";
      traj.points.push_back(tp);
    }
    const double dp = pressureDrop(fluid);
    const auto dep = std::count_if(sc.disks.begin(), sc.disks.end(), [](const Disk& D) { return D.state == State::deposited; });
    const auto gone = std::count_if(sc.disks.begin(), sc.disks.end(), [](const Disk& D) { return D.state == State::left; });
    const auto all = static_cast<std::int64_t>(sc.disks.size());
    retention += tables::formatRow(tables::RetentionRow{frame, t, all, all - dep - gone, dep, gone});
    perm += tables::formatRow(tables::PermeabilityRow{frame, t, dp > 0 ? mu_U_L / dp : 0.0, (sc.U > 0 && dp > 0 && dp0 > 0) ? dp0 / dp : 1.0, dp, dep, solves});
    ++frame;
  };
  // Checkpoint: positions, states, counters and the outputs so far, as JSON (doubles round-trip exactly).
  const std::filesystem::path ckpt = ctx.out_dir / "checkpoint.json";
  const std::int64_t checkpoint_every = c.integer("run.checkpoint_every"), stop_after = c.integer("run.stop_after_frames");
  auto saveCheckpoint = [&](std::int64_t f) {
    nlohmann::json j;
    j["format"] = "mmval-resolved-checkpoint-2";
    j["scenario"] = checkpointFingerprint(c);
    j["frame"] = f;
    j["t"] = t;
    j["counters"] = {solves, steps, contacts, attached};
    for (const auto& D : sc.disks) j["disks"].push_back({D.x.x(), D.x.y(), static_cast<int>(D.state), D.attached_at});
    for (const auto& tp : traj.points)
      j["trajectory"].push_back({tp.frame, tp.particle, tp.t, tp.x, tp.y, tp.state == "mobile" ? 0 : 1});
    j["permeability_csv"] = perm;
    j["retention_csv"] = retention;
    writeFileAtomic(ckpt, j.dump());
  };
  std::int64_t first = 1;
  std::vector<Eigen::Vector2d> v;
  if (ctx.resume && std::filesystem::exists(ckpt)) {
    try {
      const nlohmann::json j = nlohmann::json::parse(readBinaryFile(ckpt));
      if (j.at("format") != "mmval-resolved-checkpoint-2") throw std::runtime_error("unknown format");
      if (j.at("scenario").get<std::string>() != checkpointFingerprint(c)) throw std::runtime_error("it belongs to another version of this case");
      if (j.at("disks").size() != sc.disks.size()) throw std::runtime_error("other number of particles");
      first = j.at("frame").get<std::int64_t>() + 1;
      frame = first;
      t = j.at("t").get<double>();
      const auto& n = j.at("counters");
      solves = n[0];
      steps = n[1];
      contacts = n[2];
      attached = n[3];
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
        traj.points.push_back(tp);
      }
      perm = j.at("permeability_csv").get<std::string>();
      retention = j.at("retention_csv").get<std::string>();
    } catch (const std::exception& e) {
      throw InputError(c.where("run.checkpoint_every"), fmt::format("cannot resume from {}: {}", ckpt.string(), e.what()), {},
                       "delete the checkpoint (or the .partial folder) to start afresh");
    }
    const int counted = solves;
    v = velocities(fluid, sc, solves);  // the same solve the interrupted run ended its frame with
    solves = counted;
  } else {
    v = velocities(fluid, sc, solves);
    record();
  }
  out_resumed_from = first - 1;
  for (std::int64_t f = first; f <= frames; ++f) {
    const double t_next = f * dt_out;
    while (t < t_next - 1e-12 * dt_out) {
      // Each particle may move max_move, or a quarter of its distance to the nearest surface when
      // that is larger (at most 4 max_move): long steps in open pores, short ones near contacts.
      double dt = t_next - t;
      for (std::size_t k = 0; k < sc.disks.size(); ++k) {
        const double speed = v[k].norm();
        if (speed <= 0 || sc.disks[k].state != State::mobile) continue;
        const double allowed = std::clamp(0.25 * (nearestSurface(sc, k).gap - sc.contact_gap), max_move, 4 * max_move);
        dt = std::min(dt, allowed / speed);
      }
      // Explicit midpoint: the velocity at the half step moves the particles.
      const std::vector<Eigen::Vector2d> x0 = [&] {
        std::vector<Eigen::Vector2d> x;
        for (const auto& D : sc.disks) x.push_back(D.x);
        return x;
      }();
      for (std::size_t k = 0; k < sc.disks.size(); ++k) sc.disks[k].x = x0[k] + 0.5 * dt * v[k];
      const std::vector<Eigen::Vector2d> vh = velocities(fluid, sc, solves);
      for (std::size_t k = 0; k < sc.disks.size(); ++k) sc.disks[k].x = x0[k] + dt * vh[k];
      t += dt;
      ++steps;
      contacts += settleContacts(sc, t, attached);
      for (std::size_t k = 0; k < sc.disks.size(); ++k)
        if (!sc.disks[k].x.allFinite()) throw std::runtime_error(fmt::format("particles-resolved: particle {} left the finite numbers at t = {:.4g} s", k + 1, t));
      v = velocities(fluid, sc, solves);
    }
    t = t_next;
    record();
    progress.update(static_cast<std::size_t>(f));
    if (f < frames && ((checkpoint_every > 0 && f % checkpoint_every == 0) || f == stop_after)) saveCheckpoint(f);
    if (f == stop_after && f < frames)
      throw RunStopped(fmt::format("stopped after {} output frames as asked (run.stop_after_frames); {} holds the checkpoint, "
                                   "continue with `mmval run --resume`",
                                   f, ckpt.string()));
  }
  progress.finish();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::sort(traj.points.begin(), traj.points.end(), [](const TrackPoint& p, const TrackPoint& q) {
    return p.particle != q.particle ? p.particle < q.particle : p.frame < q.frame;
  });
  writeTracksCsv(ctx.out_dir / "trajectories.csv", traj, pixel);
  writeFileAtomic(ctx.out_dir / "retention.csv", retention);
  if (sc.U > 0) writeFileAtomic(ctx.out_dir / "permeability.csv", perm);  // a closed box has no flow through it
  std::vector<std::vector<Eigen::Vector2d>> paths(sc.disks.size());
  for (const auto& tp : traj.points) paths[static_cast<std::size_t>(tp.particle)].emplace_back(tp.x, tp.y);
  sim::writeSpeedPng(fluid, ctx.out_dir / "speed.png", 1200, paths);
  sim::writeVtr(fluid, ctx.out_dir / "fields.vtr");
  std::filesystem::remove(ckpt);  // complete: nothing to resume

  RunOutput out;
  out.files = {"trajectories.csv", "retention.csv", "speed.png", "fields.vtr"};
  if (sc.U > 0) out.files.push_back("permeability.csv");
  out.details["resumed_from_frame"] = out_resumed_from;
  // First particle's velocity at the end: the terminal velocity of a settling scene.
  const Eigen::Vector2d v0 = sc.disks[0].state == State::mobile ? v[0] : Eigen::Vector2d::Zero();
  if (sc.disks[0].state == State::mobile) {  // a deposited or departed particle has no velocity to report
    out.metrics["final_velocity_x"] = v0.x();
    out.metrics["final_velocity_y"] = v0.y();
    out.units["final_velocity_x"] = out.units["final_velocity_y"] = "um/s";
  }
  // Faxen's cylinder midway between two plates (simulate::faxenCylinderResistance), for a particle
  // settling along x in a channel of half-width l = W/2 at rest: U = F / R (plane 2D only).
  if (sc.h == 0 && sc.U == 0 && sc.weight.x() != 0) {
    const double l = 0.5 * sc.W, k = a / l;
    const double faxen = sc.weight.x() / sim::faxenCylinderResistance(a, l, mu);
    out.metrics["faxen_velocity_ratio"] = faxen != 0 ? v0.x() / faxen : 0.0;
    out.details["faxen"] = {{"velocity_um_s", faxen * 1e6},
                            {"a_over_l", k},
                            {"offset_from_midline_um", (sc.disks[0].x.y() - l) * 1e6},
                            {"meaning", "terminal velocity of particle 1 over Faxen's series for a cylinder midway between plates"}};
  }
  const auto dep = std::count_if(sc.disks.begin(), sc.disks.end(), [](const Disk& D) { return D.state == State::deposited; });
  const auto left = std::count_if(sc.disks.begin(), sc.disks.end(), [](const Disk& D) { return D.state == State::left; });
  out.metrics["deposited"] = static_cast<double>(dep);
  out.metrics["left"] = static_cast<double>(left);
  out.metrics["inside"] = static_cast<double>(sc.disks.size()) - static_cast<double>(dep + left);
  out.metrics["retained_fraction"] = static_cast<double>(dep) / static_cast<double>(sc.disks.size());
  if (sc.U > 0) {
    const double dp = pressureDrop(fluid);
    out.metrics["k_over_k0"] = dp != 0 ? dp0 / dp : 1.0;
    out.details["pressure_drop_clean_pa"] = dp0;
    out.details["pressure_drop_final_pa"] = dp;
  }
  out.metrics["wall_time"] = wall;
  out.units["wall_time"] = "s";
  out.details["coupling"] = fmt::format("resolved immersed boundary: {} cells per diameter (grid {} x {}, cell {:.3g} um), Stokes mobility of free rigid disks",
                                        per_d, prob.x.cells(), prob.y.cells(), dx * 1e6);
  if (per_d < 8) out.details["warning"] = fmt::format("{} cells per diameter is below the ~8 a resolved particle needs: forces are coarse", per_d);
  if (sc.grains) out.details["geometry"] = geometry;
  out.details["steps"] = steps;
  out.details["stokes_solves"] = solves;
  out.details["factorisations"] = fluid.factorisations();
  out.details["contacts_resolved"] = contacts;
  out.details["attached"] = attached;
  out.details["contact_gap_um"] = sc.contact_gap * 1e6;
  out.details["capture_distance_used_um"] = sc.capture * 1e6;
  return out;
}

}  // namespace

CaseKind resolvedKind() {
  CaseKind k;
  k.name = "particles-resolved";
  k.summary = "Particles spanning many cells moved through creeping flow by the resolved immersed boundary (Stokes mobility of rigid disks): "
              "trajectories, attachment, permeability over time";
  k.declare = declareResolved;
  k.run = runResolved;
  return k;
}

}  // namespace mmval::particles
