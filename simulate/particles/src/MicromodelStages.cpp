// The stages of a particles-micromodel run (MicromodelStages.hpp).
#include "MicromodelStages.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "CaseScene.hpp"
#include "MicromodelDetail.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/OutputTables.hpp"

namespace mmval::particles::stages {

namespace {

/// The inlet strip new particles are placed in: what the flow fills in one
/// output interval at this many times the mean interstitial velocity (the pore
/// velocity's spread: faster paths fill further), capped at this fraction of the
/// geometry's length so that an entering particle is never placed near the outlet.
constexpr double kStripVelocityFactor = 1.5, kStripMaxOfLength = 0.5;

/// geometry.sides = "slip": the top and bottom edges are mirror planes (fluid, particles, throats).
bool mirrorSides(const Case& c) { return c.text("geometry.sides") == "slip"; }

/// particles.diameter, or particles.diameters with their number fractions.
std::vector<SizeClass> readSizeClasses(const Case& c) {
  std::vector<SizeClass> classes;
  if (!c.has("particles.diameters")) {
    classes.emplace_back();
    classes.back().diameter = c.quantity("particles.diameter");
    return classes;
  }
  const auto& ds = c.reals("particles.diameters");
  if (!c.has("particles.size_fractions") || c.reals("particles.size_fractions").size() != ds.size())
    throw InputError(c.where("particles.size_fractions"), "one number fraction per entry of particles.diameters is needed", {},
                     fmt::format("a list of {} fractions summing to 1", ds.size()));
  const auto& fs_ = c.reals("particles.size_fractions");
  double sum = 0;
  for (double f : fs_) {
    if (!(f >= 0)) throw InputError(c.where("particles.size_fractions"), "fractions must be >= 0", fmt::format("{}", f), ">= 0");
    sum += f;
  }
  if (std::abs(sum - 1.0) > 1e-6)
    throw InputError(c.where("particles.size_fractions"), "fractions do not sum to 1", fmt::format("{:.6g}", sum), "a sum of 1");
  for (std::size_t i = 0; i < ds.size(); ++i)
    if (fs_[i] > 0) {
      classes.emplace_back();
      classes.back().diameter = ds[i];
      classes.back().fraction = fs_[i];
    }
  return classes;
}

/// The largest particles must fit in the chip depth and through some inlet pore;
/// whether they can pass every path is recorded (straining). Returns the largest diameter.
double checkParticlesFit(const Case& c, const std::vector<SizeClass>& classes, const SceneGeometry& geo, RunOutput& out) {
  const std::string dkey = c.has("particles.diameters") ? "particles.diameters" : "particles.diameter";
  double d_max = 0;
  for (const auto& cl : classes) d_max = std::max(d_max, cl.diameter);
  if (!(geo.depth > d_max))
    throw InputError(c.where(dkey), "particles do not fit in the chip depth", fmt::format("{:.3g} um", d_max * 1e6),
                     fmt::format("< geometry.depth ({:.3g} um)", geo.depth * 1e6));
  const bool mirror = mirrorSides(c);
  const double opening = inletOpening(geo.grains, geo.pixel, mirror), passable = passableDiameter(geo.grains, geo.pixel, mirror);
  out.details["inlet_opening_um"] = opening * 1e6;
  setDetail(out.details, DetailField::passable_diameter_um, passable * 1e6);
  if (opening < d_max)
    throw InputError(c.where(dkey), "no pore at the inlet (first image column) is wide enough to take a particle",
                     fmt::format("{:.3g} um", d_max * 1e6),
                     fmt::format("a diameter below the widest inlet opening, {:.3g} um, or a mask/crop with a wider inlet", opening * 1e6));
  setDetail(out.details, DetailField::straining,
            passable < d_max ? fmt::format("every inlet-to-outlet pore path has a throat narrower than the (largest) particles ({:.3g} um < "
                                           "{:.3g} um): they are strained, none can leave",
                                           passable * 1e6, d_max * 1e6)
                             : std::string("none: some path admits the particles"));
  return d_max;
}

/// The fluid solver's options at the experiment's Darcy velocity (flow.darcy_velocity,
/// else flow.rate through flow.rate_width x depth).
MicromodelFlowOptions readFlow(const Case& c, const SceneGeometry& geo) {
  const double Q = c.quantity("flow.rate"), rate_width = c.quantity("flow.rate_width");
  MicromodelFlowOptions fo;
  fo.pixel = geo.pixel;
  fo.depth = geo.depth;
  fo.viscosity = c.quantity("fluid.viscosity");
  fo.darcy_velocity =
      c.has("flow.darcy_velocity") ? c.quantity("flow.darcy_velocity") : Q / ((rate_width > 0 ? rate_width : geo.height) * geo.depth);
  fo.cells_per_pixel = c.real("numerics.cells_per_pixel");
  fo.warm_start = c.text("numerics.resolve") == "warm";
  fo.fixed_pattern = c.text("numerics.resolve_pattern") == "fixed";
  fo.mirror_sides = mirrorSides(c);
  fo.smooth_walls = c.text("geometry.boundary") == "smooth";
  fo.smoothing_px = c.real("geometry.smoothing");
  return fo;
}

/// The engine from the scene's numbers (for the largest class: the most inertial);
/// only the overdamped engine can run the scene, so another choice is an
/// InputError unless the case forces the overdamped one.
EngineChoice chooseSceneEngine(const Case& c, const MicromodelSetup& set) {
  const double u_darcy = set.flow.darcy_velocity, H = set.geo.height, h = set.geo.depth;
  SceneScales scales;
  scales.fluid = {c.quantity("fluid.viscosity"), c.quantity("fluid.density"), c.quantity("fluid.temperature")};
  scales.particle.diameter = set.d_max;
  scales.particle.density = c.quantity("particles.density");
  scales.velocity = set.geo.porosity > 0 ? u_darcy / set.geo.porosity : u_darcy;
  scales.length = h;
  scales.depth = h;
  scales.cell_size = set.geo.pixel / set.flow.cells_per_pixel;
  scales.gravity = c.quantity("physics.gravity");
  const double conc = c.quantity("particles.concentration");
  const double t_inj0 = c.quantity("particles.injection_time") > 0 ? c.quantity("particles.injection_time") : c.quantity("run.duration");
  const std::int64_t count0 = c.integer("particles.count");
  // Volume fraction of the injected suspension (a count given: spread over the flow of the injection time).
  double mean_volume = 0;
  for (const auto& cl : set.classes) mean_volume += cl.fraction * kPi * std::pow(cl.diameter, 3) / 6.0;
  const double q_vol = u_darcy * H * h;
  scales.volume_fraction = count0 > 0 ? (q_vol > 0 ? count0 / t_inj0 * mean_volume / q_vol : 0.0) : conc * mean_volume;
  if (!(scales.velocity > 0)) scales.velocity = 1e-12;  // zero flow: numbers of a still fluid (the choice needs U > 0)
  EngineChoice choice = chooseEngine(scales);
  if (choice.engine != EngineKind::overdamped) {
    if (c.text("particles.engine") != "overdamped")
      throw InputError(c.where("particles.engine"), "this scene's numbers ask for an inertial engine, which cannot run the micromodel's length",
                       choice.reason, "a scene with St <= 1e-3 and a dilute suspension, or particles.engine = \"overdamped\" to force the cheaper model");
    choice.reason = "forced by the case (particles.engine = \"overdamped\"); the automatic choice would be: " + choice.reason;
    choice.engine = EngineKind::overdamped;
  }
  return choice;
}

/// The engines' shared settings: fluid, particle density, gravity, [physics], [deposition].
SceneConfig readScene(const Case& c, const EngineChoice& choice, const SceneGeometry& geo) {
  SceneConfig scene;
  scene.fluid = {c.quantity("fluid.viscosity"), c.quantity("fluid.density"), c.quantity("fluid.temperature")};
  scene.particle.density = c.quantity("particles.density");
  scene.gravity = c.quantity("physics.gravity");
  physicsAndDepositionFromCase(c, choice, scene);
  scene.straining.enabled = c.flag("deposition.straining");
  scene.straining.time = c.quantity("deposition.straining_time");
  scene.outlet_x = geo.width;
  scene.mirror_sides = mirrorSides(c);
  scene.max_step_fraction = c.real("numerics.max_step_fraction");
  engineNumericsFromCase(c, scene);
  return scene;
}

/// [coupling]: one- or four-way, plate deposits as layers or columns, parcel
/// weight, and the re-solve threshold in pixel columns.
Coupling readCoupling(const Case& c, const SceneGeometry& geo, double d_max, double sample) {
  Coupling cp;
  cp.four_way = c.text("coupling.mode") == "four-way";
  cp.weight = c.flag("coupling.parcel_weighting") ? 1.0 / sample : 1.0;
  // Plate deposits (layer mode): a layer of the stated packing thins the aperture;
  // a pixel closes below coupling.min_aperture (default: the largest diameter, the
  // aperture no particle of the scene can pass).
  cp.layers = c.text("coupling.plate_deposits") == "layer";
  cp.layer_model.packing = c.real("coupling.layer_packing");
  cp.layer_model.min_aperture = c.quantity("coupling.min_aperture") > 0 ? c.quantity("coupling.min_aperture") : d_max;
  if (!(cp.layer_model.min_aperture < geo.depth))
    throw InputError(c.where("coupling.min_aperture"), "the closing aperture must be below the chip depth",
                     fmt::format("{:.3g} um", cp.layer_model.min_aperture * 1e6), fmt::format("< geometry.depth ({:.3g} um)", geo.depth * 1e6));
  cp.fill_fraction = c.real("coupling.fill_fraction");
  cp.resolve_pixels =
      std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(c.real("coupling.resolve_threshold") * geo.pore_pixels)));
  return cp;
}

/// [run] and analysis.retention_window.
RunControl readRunControl(const Case& c) {
  RunControl run;
  const double duration = c.quantity("run.duration");
  run.dt_out = c.quantity("run.output_interval");
  if (run.dt_out > duration)
    throw InputError(c.where("run.output_interval"), "longer than the run", fmt::format("{:g} s", run.dt_out),
                     fmt::format("<= run.duration ({:g} s)", duration));
  if (c.has("analysis.retention_window")) {
    run.window = c.reals("analysis.retention_window");
    const auto& w = run.window;
    if (w.size() != 2 || !(w[1] > w[0]))
      throw InputError(c.where("analysis.retention_window"), "a window needs two times, the first before the second",
                       w.size() == 2 ? fmt::format("[{:g} s, {:g} s]", w[0], w[1]) : fmt::format("{} entries", w.size()),
                       "[from, to] with from < to, e.g. [\"0 s\", \"600 s\"]");
  }
  run.frames = outputFrames(c);
  run.checkpoint_every = c.integer("run.checkpoint_every");
  run.stop_after = c.integer("run.stop_after_frames");
  return run;
}

/// The injection schedule: particles.count over the injection time, else the
/// suspension's concentration times the flow, sampled.
Schedule readSchedule(const Case& c, const MicromodelSetup& set) {
  Schedule sch;
  const double duration = c.quantity("run.duration");
  const double u_darcy = set.flow.darcy_velocity;
  sch.injection_time = c.quantity("particles.injection_time") > 0 ? c.quantity("particles.injection_time") : duration;
  const std::int64_t count = c.integer("particles.count");
  sch.rate_per_s = count > 0 ? count / sch.injection_time
                             : c.quantity("particles.concentration") * u_darcy * set.geo.height * set.geo.depth * set.sample;
  sch.strip = kStripVelocityFactor * (set.geo.porosity > 0 ? u_darcy / set.geo.porosity : 0.0) * set.run.dt_out;
  sch.max_strip = kStripMaxOfLength * set.geo.width;
  sch.seed = set.seed;
  return sch;
}

}  // namespace

MicromodelSetup readSetup(const Case& c, RunOutput& out) {
  outputFrames(c);  // a run whose frames cannot fit in memory is refused before the mask is read
  MicromodelSetup set;
  SceneGeometry& geo = set.geo;
  geo.grains = detail::loadGeometry(c, out.details, geo.porosity);
  geo.pixel = c.quantity("geometry.pixel_size");
  geo.depth = c.quantity("geometry.depth");
  geo.width = geo.grains.cols() * geo.pixel;
  geo.height = geo.grains.rows() * geo.pixel;
  geo.pore_pixels = static_cast<std::int64_t>((geo.grains == false).count());
  set.classes = readSizeClasses(c);
  set.d_max = checkParticlesFit(c, set.classes, geo, out);
  set.flow = readFlow(c, geo);
  set.max_pressure = c.has("flow.max_pressure") ? c.quantity("flow.max_pressure") : 0.0;
  set.choice = chooseSceneEngine(c, set);
  set.scene = readScene(c, set.choice, geo);
  set.seed = static_cast<std::uint64_t>(c.integer("run.seed"));
  if (c.has("analysis.table3_case")) setDetail(out.details, DetailField::table3_case, c.text("analysis.table3_case"));
  return set;
}

void readCouplingAndSchedule(const Case& c, MicromodelSetup& set) {
  set.sample = c.real("particles.sample_fraction");
  set.coupling = readCoupling(c, set.geo, set.d_max, set.sample);
  set.run = readRunControl(c);
  set.schedule = readSchedule(c, set);
}

void makeEngines(std::vector<SizeClass>& classes, const std::shared_ptr<const FlowField>& field, const SceneConfig& scene,
                 std::uint64_t seed) {
  for (std::size_t i = 0; i < classes.size(); ++i) {
    SceneConfig sc = scene;
    sc.particle.diameter = classes[i].diameter;
    sc.seed = seed + kClassSeedStride * i;  // independent streams per class; class 0 keeps the case's seed
    classes[i].engine = std::make_unique<OverdampedEngine>(field, sc);
  }
}

ClassParticles transport(std::vector<SizeClass>& classes, std::int64_t k, double t) {
  ClassParticles ps(classes.size());
  for (std::size_t ci = 0; ci < classes.size(); ++ci) {
    if (k > 0) classes[ci].engine->advance(t);
    ps[ci] = classes[ci].engine->particles();
  }
  return ps;
}

void deposit(std::vector<SizeClass>& classes, const ClassParticles& ps, const FlowField& field, const Coupling& coupling,
             DepositGrid& deposits, std::int64_t& at_walls, std::int64_t& on_plates) {
  for (std::size_t ci = 0; ci < classes.size(); ++ci) {
    auto& cl = classes[ci];
    const double vol = coupling.weight * kPi * cl.diameter * cl.diameter * cl.diameter / 6.0;
    for (std::size_t i = 0; i < ps[ci].size(); ++i) {
      if (ps[ci][i].status != ParticleStatus::deposited || (cl.accounted[i] & kVolumeBooked)) continue;
      const Vec3& x = ps[ci][i].x;
      const bool at_wall = field.wallDistance(x.x(), x.y()) < cl.diameter;
      ++(at_wall ? at_walls : on_plates);
      if (!coupling.layers || at_wall) deposits.add(x.x(), x.y(), vol);
      else deposits.addLayer(x.x(), x.y(), vol, cl.diameter);
      cl.accounted[i] |= kVolumeBooked;
    }
  }
}

std::optional<PumpStall> resolve(MicromodelFlow& flow, const DepositGrid& deposits, const Coupling& coupling, double max_pressure,
                                 double t, std::vector<SizeClass>& classes, ClassParticles& ps, FlowRecord record) {
  if (deposits.lostColumns() - record.lost_at_solve < static_cast<double>(coupling.resolve_pixels)) return std::nullopt;
  const FlowSolveResult r = flow.solve(deposits.closed(), coupling.layers ? deposits.aperture() : std::vector<double>{});
  ++record.resolves;
  if (r.pattern_kept) ++record.resolves_pattern_kept;
  record.solve_seconds += r.seconds;
  record.lost_at_solve = deposits.lostColumns();
  record.k = r.permeability;
  record.pressure_drop = r.pressure_drop;
  if (r.blocked && record.blocked_at < 0) record.blocked_at = t;
  std::optional<PumpStall> stall = pumpStall(r, max_pressure, t);
  for (std::size_t ci = 0; ci < classes.size(); ++ci) {
    classes[ci].engine->captureInSolid();
    ps[ci] = classes[ci].engine->particles();
  }
  return stall;
}

namespace {
/// Up to `n` particles of radius `radius` placed one by one in the strip, each
/// with its own seed, until one does not fit (the strip is full).
std::vector<Vec3> placeWhatFits(const FlowField& field, double radius, double strip, std::int64_t n, std::uint64_t seed,
                                std::vector<ParticleState> taken) {
  std::vector<Vec3> pos;
  for (std::int64_t m = 0; m < n; ++m) {
    try {
      const auto one = sampleInlet(field, radius, 0.0, strip, 1, seed + kRetrySeedStride * (m + 1), taken);
      pos.push_back(one[0]);
      ParticleState q;
      q.x = one[0];
      taken.push_back(q);
    } catch (const InputError&) {
      break;
    }
  }
  return pos;
}
}  // namespace

void insertDue(std::vector<SizeClass>& classes, const FlowField& field, const Schedule& schedule, std::int64_t k, double t,
               ClassParticles& ps, std::int64_t& next_id) {
  for (std::size_t ci = 0; ci < classes.size(); ++ci) {
    auto& cl = classes[ci];
    const std::int64_t due = dueBy(schedule.rate_per_s, cl.fraction, t, schedule.injection_time);
    if (due <= cl.injected) continue;
    const double strip = std::min(std::max(schedule.strip, cl.diameter), schedule.max_strip);
    const std::uint64_t sseed = schedule.seed * kFrameSeedStride + static_cast<std::uint64_t>(k) + kClassSeedStride * ci;
    std::vector<Vec3> pos;
    try {
      pos = sampleInlet(field, 0.5 * cl.diameter, 0.0, strip, static_cast<int>(due - cl.injected), sseed, ps[ci]);
    } catch (const InputError&) {
      // The inlet strip is full (deposits clog the inlet, or a burst of large
      // fines): place what fits and carry the rest to the next frame.
      pos = placeWhatFits(field, 0.5 * cl.diameter, strip, due - cl.injected, sseed, ps[ci]);
    }
    cl.engine->insert(pos);
    cl.injected += static_cast<std::int64_t>(pos.size());
    cl.deferred = due - cl.injected;
    ps[ci] = cl.engine->particles();
    while (cl.global_id.size() < ps[ci].size()) cl.global_id.push_back(next_id++);
    cl.accounted.resize(ps[ci].size(), 0);
  }
}

Counts recordFrame(std::vector<SizeClass>& classes, const ClassParticles& ps, std::int64_t k, double t, const ImageFrame& image,
                   double dt_out, RunnerState& s) {
  std::vector<LastPos> now;
  Counts n;
  for (std::size_t ci = 0; ci < classes.size(); ++ci) {
    auto& cl = classes[ci];
    const Counts nc = countParticles(ps[ci]);
    n.injected += nc.injected;
    n.inside += nc.inside;
    n.deposited += nc.deposited;
    n.left += nc.left;
    for (std::size_t i = 0; i < ps[ci].size(); ++i) {
      const auto& p = ps[ci][i];
      if (p.status == ParticleStatus::left) continue;
      const bool dep = p.status == ParticleStatus::deposited;
      if (dep && (cl.accounted[i] & kRowWritten)) continue;
      if (dep) cl.accounted[i] |= kRowWritten;
      const std::int64_t id = cl.global_id[i];
      // Pixel centres of the image, row 0 at the top: x_px = X/p - 1/2, y_px = (H - Y)/p - 1/2.
      s.rows.push_back({k, id, t, p.x.x() / image.pixel - 0.5, (image.height - p.x.y()) / image.pixel - 0.5, p.x.z(),
                        static_cast<std::uint8_t>(dep)});
      if (dep) continue;
      now.push_back({id, p.x.x(), p.x.y()});
      const auto it = std::lower_bound(s.last.begin(), s.last.end(), id, [](const LastPos& l, std::int64_t v) { return l.id < v; });
      if (it != s.last.end() && it->id == id) {
        s.speed_sum += std::hypot(p.x.x() - it->x, p.x.y() - it->y) / dt_out;
        ++s.speed_n;
      }
    }
  }
  std::sort(now.begin(), now.end(), [](const LastPos& x, const LastPos& y) { return x.id < y.id; });
  s.last = std::move(now);
  if (!n.balanced()) throw std::logic_error(fmt::format("particle counts do not balance at t = {} s", t));
  s.retention += tables::formatRow(tables::RetentionRow{k, t, n.injected, n.inside, n.deposited, n.left});
  s.permeability += tables::formatRow(tables::PermeabilityRow{k, t, s.k, s.k / s.k0, s.pressure_drop, n.deposited, s.resolves});
  s.next_frame = k + 1;
  return n;
}

}  // namespace mmval::particles::stages
