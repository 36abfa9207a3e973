#include "mmval/particles/Micromodel.hpp"

#include "CaseScene.hpp"
#include "MicromodelDetail.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <functional>
#include <cmath>
#include <map>
#include <optional>
#include <limits>
#include <sstream>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/core/VtkWriter.hpp"
#include "mmval/particles/DepositGrid.hpp"
#include "mmval/particles/EngineComparison.hpp"
#include "mmval/particles/MicromodelBookkeeping.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
#include "mmval/particles/SceneSelection.hpp"

namespace mmval::particles {

namespace {

namespace fs = std::filesystem;
using detail::declareMicromodel;
using detail::loadGeometry;
constexpr double kDarcy = 9.869233e-13;  // m2

/// One trajectory row, POD so that checkpoints hold it as raw bytes.
struct TrajRow {
  std::int64_t frame, particle;
  double t, x_px, y_px, z;
  std::uint8_t deposited;
};
struct LastPos {
  std::int64_t id;
  double x, y;
};

/// One size class: its own engine (one radius per engine), injection and ids.
struct SizeClass {
  double diameter = 0, fraction = 1;
  std::unique_ptr<OverdampedEngine> engine;
  std::int64_t injected = 0;   ///< placed in the chip
  std::int64_t deferred = 0;   ///< due but not yet placed (inlet strip full)
  std::vector<std::int64_t> global_id;   ///< by engine index: id in the outputs (injection order over all classes)
  std::vector<std::uint8_t> accounted;   ///< by engine index: bit 0 deposit volume added, bit 1 deposited row written
};

/// Everything of the runner that a checkpoint must carry besides the engines and the deposits.
struct RunnerState {
  std::int64_t next_frame = 0, next_id = 1, resolves = 0, steps_at_checkpoint = 0;
  std::int64_t wall_deposits = 0, plate_deposits = 0;  ///< deposits booked as columns (at a grain) / as plate layers
  double lost_at_solve = 0;  ///< DepositGrid::lostColumns() at the last solve
  double blocked_at = -1;    ///< s: first re-solve that found no flow path (-1: never)
  double k = 0, k0 = 0, speed_sum = 0, solve_seconds = 0, wall_before = 0;
  std::int64_t speed_n = 0;
  std::vector<TrajRow> rows;
  std::vector<LastPos> last;  ///< sorted by id
  std::string retention, permeability;
};

void writeCheckpoint(const fs::path& file, const std::string& fp, const RunnerState& s, const std::vector<SizeClass>& classes,
                     const DepositGrid& deposits, const MicromodelFlow& flow) {
  CheckpointWriter w;
  w.putString("mmval-micromodel-checkpoint-5");
  w.putString(fp);
  w.put(s.next_frame); w.put(s.next_id); w.put(s.resolves); w.put(s.steps_at_checkpoint);
  w.put(s.wall_deposits); w.put(s.plate_deposits); w.put(s.lost_at_solve); w.put(s.blocked_at);
  w.put(s.k); w.put(s.k0); w.put(s.speed_sum); w.put(s.solve_seconds); w.put(s.wall_before); w.put(s.speed_n);
  w.putVector(s.rows);
  w.putVector(s.last);
  w.putString(s.retention);
  w.putString(s.permeability);
  w.put<std::uint64_t>(classes.size());
  for (const auto& cl : classes) {
    w.put(cl.injected);
    w.put(cl.deferred);
    w.putVector(cl.global_id);
    w.putVector(cl.accounted);
    cl.engine->saveState(w);
  }
  deposits.save(w);
  w.putVector(flow.nodeUx());
  w.putVector(flow.nodeUy());
  w.putVector(flow.nodeSolid());
  w.putVector(flow.nodeDepth());
  writeFileAtomic(file, w.bytes());
}

bool readCheckpoint(const fs::path& file, const std::string& fp, RunnerState& s, std::vector<SizeClass>& classes, DepositGrid& deposits,
                    MicromodelFlow& flow) {
  CheckpointReader r(readBinaryFile(file), file.string());
  if (r.getString() != "mmval-micromodel-checkpoint-5") throw std::runtime_error("checkpoint " + file.string() + ": unknown format");
  if (r.getString() != fp) return false;  // another scene: start afresh
  s.next_frame = r.get<std::int64_t>(); s.next_id = r.get<std::int64_t>(); s.resolves = r.get<std::int64_t>();
  s.steps_at_checkpoint = r.get<std::int64_t>();
  s.wall_deposits = r.get<std::int64_t>(); s.plate_deposits = r.get<std::int64_t>(); s.lost_at_solve = r.get<double>();
  s.blocked_at = r.get<double>();
  s.k = r.get<double>(); s.k0 = r.get<double>(); s.speed_sum = r.get<double>(); s.solve_seconds = r.get<double>();
  s.wall_before = r.get<double>(); s.speed_n = r.get<std::int64_t>();
  s.rows = r.getVector<TrajRow>();
  s.last = r.getVector<LastPos>();
  s.retention = r.getString();
  s.permeability = r.getString();
  if (r.get<std::uint64_t>() != classes.size()) throw std::runtime_error("checkpoint " + file.string() + ": other number of size classes");
  for (auto& cl : classes) {
    cl.injected = r.get<std::int64_t>();
    cl.deferred = r.get<std::int64_t>();
    cl.global_id = r.getVector<std::int64_t>();
    cl.accounted = r.getVector<std::uint8_t>();
    cl.engine->loadState(r);
  }
  deposits.load(r);
  auto ux = r.getVector<double>(), uy = r.getVector<double>();
  auto solid = r.getVector<std::uint8_t>();
  auto depth = r.getVector<double>();
  if (depth.size() != ux.size()) throw std::runtime_error("checkpoint " + file.string() + ": flow depth of another size");
  flow.restore(ux, uy, solid, depth);
  return true;
}

/// The "cheaper model against LIGGGHTS on a shared window of the same scene":
/// particles of the first size class spread over this scene's pore space at t = 0,
/// both engines on its flow field (grains an STL mesh wall for LIGGGHTS), one row per
/// overdamped step setting into details.engine_comparison (the report's table), the
/// first row's errors also as metrics.
void compareEnginesOnTheScene(const Case& c, std::shared_ptr<const FlowField> field, const SceneConfig& scene, double diameter, RunOutput& out) {
  SceneConfig ref = scene;
  ref.particle.diameter = diameter;
  ref.particle.youngs_modulus = c.quantity("engines.compare_youngs_modulus");
  ref.work_dir = std::filesystem::temp_directory_path() / fmt::format("mmval-engines-{:016x}", std::hash<std::string>{}(checkpointFingerprint(c)));
  SceneWindow w;
  w.window = c.quantity("engines.compare_window");
  w.interval = std::min(w.window, std::max(w.window / 20, c.quantity("run.output_interval") / 4));
  w.particles = static_cast<int>(c.integer("engines.compare_particles"));
  w.gravity_factor = c.real("engines.compare_gravity_factor");
  w.seed = static_cast<std::uint64_t>(c.integer("run.seed"));
  std::vector<double> fractions{scene.max_step_fraction};
  if (c.has("engines.compare_step_fractions")) fractions = c.reals("engines.compare_step_fractions");
  std::vector<SceneConfig> candidates;
  for (double f : fractions) {
    candidates.push_back(ref);
    candidates.back().max_step_fraction = f;
  }
  const auto results = compareOnScene(field, ref, w, candidates);
  nlohmann::json rows = nlohmann::json::array();
  for (std::size_t i = 0; i < results.size(); ++i) {
    const EngineComparison& r = results[i];
    nlohmann::json row = r.toJson();
    row["candidate"] = fmt::format("overdamped, step {:g} radii", fractions[i]);
    row["gravity_factor"] = w.gravity_factor;
    row["youngs_modulus_Pa"] = ref.particle.youngs_modulus;
    rows.push_back(row);
  }
  const EngineComparison& r = results.front();
  out.metrics["engines_rms_position_difference"] = r.rms_position_difference;  // SI; shown in um
  out.units["engines_rms_position_difference"] = "um";
  out.metrics["engines_captured_liggghts"] = r.captured_reference;
  out.metrics["engines_captured_overdamped"] = r.captured_candidate;
  out.metrics["engines_capture_difference"] = std::abs(r.captured_reference - r.captured_candidate);
  out.metrics["engines_speedup"] = r.wall_seconds_reference / std::max(r.wall_seconds_candidate, 1e-9);
  out.details["engine_comparison"] = rows;
}

/// The pump's outputs: the pressure drop the set rate needed on the clean
/// chip and at the last solve with a flow path (Darcy: mu u L / k, `mu_u_L` = mu u L),
/// and the stall if there was one, also as one line on stderr.
void reportPump(const RunnerState& s, const std::optional<PumpStall>& stall, double max_pressure, double mu_u_L, std::int64_t scheduled,
                std::int64_t injected, RunOutput& out) {
  const auto pressureFor = [&](double k) { return k > 0 ? mu_u_L / k : 0.0; };
  double k_open = s.k0;
  std::istringstream rows(s.permeability);
  std::string line;
  std::getline(rows, line);
  while (std::getline(rows, line)) {
    double t = 0, km2 = 0;
    char sep = 0;
    std::istringstream l(line);
    l >> t >> sep >> km2;
    if (km2 > 0) k_open = km2;
  }
  const nlohmann::json limit = max_pressure > 0 ? nlohmann::json(max_pressure) : nlohmann::json(nullptr);
  out.metrics["pressure_drop_initial"] = pressureFor(s.k0);
  out.units["pressure_drop_initial"] = "Pa";
  out.metrics["pressure_drop_final"] = pressureFor(k_open);
  out.units["pressure_drop_final"] = "Pa";
  out.details["pump"] = {{"max_pressure_Pa", limit},
                         {"pressure_drop_initial_Pa", pressureFor(s.k0)},
                         {"pressure_drop_final_Pa", pressureFor(k_open)},
                         {"scope", "inlet to outlet of the simulated geometry at its Darcy velocity (Darcy's law, mu u L / k); tubing and "
                                   "unsimulated chip length not included"},
                         {"stalled", stall.has_value()}};
  if (!stall) return;
  out.metrics["pump_stall_time"] = stall->time_s;
  out.units["pump_stall_time"] = "s";
  if (std::isfinite(stall->pressure_Pa)) {
    out.metrics["pump_stall_pressure"] = stall->pressure_Pa;
    out.units["pump_stall_pressure"] = "Pa";
  }
  out.details["pump_stall"] = {{"time_s", stall->time_s},
                               {"reason", stall->reasonName()},
                               {"pressure_Pa", std::isfinite(stall->pressure_Pa) ? nlohmann::json(stall->pressure_Pa) : nlohmann::json(nullptr)},
                               {"max_pressure_Pa", limit},
                               {"message", stall->describe()},
                               {"then", "injection stopped and the run ended at this frame; particles still moving are counted as inside"},
                               {"never_injected", scheduled - injected}};
  std::fprintf(stderr, "mmval: %s; injection stopped and the run ended there (%lld of %lld scheduled particles never injected)\n",
               stall->describe().c_str(), static_cast<long long>(scheduled - injected), static_cast<long long>(scheduled));
}

/// Retention of the particles injected in the window (from, to], `to` cut at the last
/// frame `t_end`, from the trajectories' rows: a particle enters in the frame of its
/// first row and is retained in that of its deposited row.
void reportWindow(const RunnerState& s, const std::vector<double>& window, double t_end, RunOutput& out) {
  std::map<std::int64_t, ParticleLife> lives;
  for (const auto& r : s.rows) {
    const auto it = lives.try_emplace(r.particle, ParticleLife{r.t, -1.0}).first;
    if (r.deposited) it->second.retained_s = r.t;
  }
  std::vector<ParticleLife> all;
  all.reserve(lives.size());
  for (const auto& [id, life] : lives) all.push_back(life);
  const double to = std::min(window[1], t_end);
  nlohmann::json wj = {{"from_s", window[0]}, {"to_s", window[1]}, {"counted_to_s", to}};
  if (to > window[0]) {
    const WindowRetention w = retentionInWindow(all, window[0], to);
    out.metrics["window_injected"] = static_cast<double>(w.injected);
    out.metrics["window_retained"] = static_cast<double>(w.retained);
    if (w.injected > 0) out.metrics["window_retained_fraction"] = w.fraction();
    wj["injected"] = w.injected;
    wj["retained"] = w.retained;
  } else {
    wj["note"] = "the run ended before the window began: nothing to count";
  }
  out.details["retention_window"] = wj;
}

RunOutput runMicromodel(const Case& c, const RunContext& ctx) {
  const auto t_start = std::chrono::steady_clock::now();
  outputFrames(c);  // a run whose frames cannot fit in memory is refused before the mask is read
  RunOutput out;
  double porosity = 0;
  const PixelMask grains = loadGeometry(c, out.details, porosity);
  const double pixel = c.quantity("geometry.pixel_size"), h = c.quantity("geometry.depth");

  // Size classes.
  std::vector<SizeClass> classes;
  if (c.has("particles.diameters")) {
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
  } else {
    classes.emplace_back();
    classes.back().diameter = c.quantity("particles.diameter");
  }
  const std::string dkey = c.has("particles.diameters") ? "particles.diameters" : "particles.diameter";
  double d_max = 0;
  for (const auto& cl : classes) d_max = std::max(d_max, cl.diameter);
  if (!(h > d_max))
    throw InputError(c.where(dkey), "particles do not fit in the chip depth", fmt::format("{:.3g} um", d_max * 1e6),
                     fmt::format("< geometry.depth ({:.3g} um)", h * 1e6));
  const double H = grains.rows() * pixel, W = grains.cols() * pixel;

  // Throats: can a particle enter, can it pass?
  const double opening = inletOpening(grains, pixel), passable = passableDiameter(grains, pixel);
  out.details["inlet_opening_um"] = opening * 1e6;
  out.details["passable_diameter_um"] = passable * 1e6;
  if (opening < d_max)
    throw InputError(c.where(dkey), "no pore at the inlet (first image column) is wide enough to take a particle",
                     fmt::format("{:.3g} um", d_max * 1e6),
                     fmt::format("a diameter below the widest inlet opening, {:.3g} um, or a mask/crop with a wider inlet", opening * 1e6));
  out.details["straining"] = passable < d_max ? fmt::format("every inlet-to-outlet pore path has a throat narrower than the (largest) "
                                                            "particles ({:.3g} um < {:.3g} um): they are strained, none can leave",
                                                            passable * 1e6, d_max * 1e6)
                                              : std::string("none: some path admits the particles");

  // Flow at the experiment's Darcy velocity.
  const double Q = c.quantity("flow.rate"), rate_width = c.quantity("flow.rate_width");
  const double u_darcy = c.has("flow.darcy_velocity") ? c.quantity("flow.darcy_velocity") : Q / ((rate_width > 0 ? rate_width : H) * h);
  MicromodelFlowOptions fo;
  fo.pixel = pixel;
  fo.depth = h;
  fo.viscosity = c.quantity("fluid.viscosity");
  fo.darcy_velocity = u_darcy;
  fo.cells_per_pixel = c.real("numerics.cells_per_pixel");
  MicromodelFlow flow(grains, fo);
  // The syringe pump's pressure limit (0: none); each solve says what pressure the set rate needs.
  const double max_pressure = c.has("flow.max_pressure") ? c.quantity("flow.max_pressure") : 0.0;

  // Engine choice from the scene's numbers (for the largest class: the most inertial).
  SceneScales scales;
  scales.fluid = {c.quantity("fluid.viscosity"), c.quantity("fluid.density"), c.quantity("fluid.temperature")};
  scales.particle.diameter = d_max;
  scales.particle.density = c.quantity("particles.density");
  scales.velocity = porosity > 0 ? u_darcy / porosity : u_darcy;
  scales.length = h;
  scales.depth = h;
  scales.cell_size = pixel / fo.cells_per_pixel;
  scales.gravity = c.quantity("physics.gravity");
  const double conc = c.quantity("particles.concentration");
  const double t_inj0 = c.quantity("particles.injection_time") > 0 ? c.quantity("particles.injection_time") : c.quantity("run.duration");
  const std::int64_t count0 = c.integer("particles.count");
  // Volume fraction of the injected suspension (a count given: spread over the flow of the injection time).
  double mean_volume = 0;
  for (const auto& cl : classes) mean_volume += cl.fraction * kPi * std::pow(cl.diameter, 3) / 6.0;
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

  SceneConfig scene;
  scene.fluid = scales.fluid;
  scene.particle.density = scales.particle.density;
  scene.gravity = scales.gravity;
  physicsAndDepositionFromCase(c, choice, scene);
  scene.outlet_x = W;
  scene.max_step_fraction = c.real("numerics.max_step_fraction");
  const auto seed = static_cast<std::uint64_t>(c.integer("run.seed"));
  for (std::size_t i = 0; i < classes.size(); ++i) {
    SceneConfig sc = scene;
    sc.particle.diameter = classes[i].diameter;
    sc.seed = seed + 7919ULL * i;  // independent streams per class; class 0 keeps the case's seed
    classes[i].engine = std::make_unique<OverdampedEngine>(flow.field(), sc);
  }

  const double sample = c.real("particles.sample_fraction");
  const bool four_way = c.text("coupling.mode") == "four-way";
  const double weight = c.flag("coupling.parcel_weighting") ? 1.0 / sample : 1.0;
  // Plate deposits (layer mode): a layer of the stated packing thins the aperture;
  // a pixel closes below coupling.min_aperture (default: the largest diameter, the
  // aperture no particle of the scene can pass).
  const bool layers = c.text("coupling.plate_deposits") == "layer";
  DepositLayerModel layer_model;
  layer_model.packing = c.real("coupling.layer_packing");
  layer_model.min_aperture = c.quantity("coupling.min_aperture") > 0 ? c.quantity("coupling.min_aperture") : d_max;
  if (!(layer_model.min_aperture < h))
    throw InputError(c.where("coupling.min_aperture"), "the closing aperture must be below the chip depth",
                     fmt::format("{:.3g} um", layer_model.min_aperture * 1e6), fmt::format("< geometry.depth ({:.3g} um)", h * 1e6));
  DepositGrid deposits(grains, pixel, h, c.real("coupling.fill_fraction"), layer_model);
  const auto pore_pixels = static_cast<std::int64_t>((grains == false).count());
  const auto resolve_pixels = std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(c.real("coupling.resolve_threshold") * pore_pixels)));

  const double duration = c.quantity("run.duration"), dt_out = c.quantity("run.output_interval");
  if (dt_out > duration)
    throw InputError(c.where("run.output_interval"), "longer than the run", fmt::format("{:g} s", dt_out), fmt::format("<= run.duration ({:g} s)", duration));
  const double t_inj = c.quantity("particles.injection_time") > 0 ? c.quantity("particles.injection_time") : duration;
  std::vector<double> window;
  if (c.has("analysis.retention_window")) {
    window = c.reals("analysis.retention_window");
    if (window.size() != 2 || !(window[1] > window[0]))
      throw InputError(c.where("analysis.retention_window"), "a window needs two times, the first before the second",
                       window.size() == 2 ? fmt::format("[{:g} s, {:g} s]", window[0], window[1]) : fmt::format("{} entries", window.size()),
                       "[from, to] with from < to, e.g. [\"0 s\", \"600 s\"]");
  }
  const std::int64_t count = c.integer("particles.count");
  const double inject_rate = count > 0 ? count / t_inj : conc * u_darcy * H * h * sample;  // simulated particles per second
  const std::int64_t frames = outputFrames(c);
  const std::int64_t checkpoint_every = c.integer("run.checkpoint_every"), stop_after = c.integer("run.stop_after_frames");
  const fs::path ckpt = ctx.out_dir / "checkpoint.bin";
  const std::string fp = checkpointFingerprint(c);

  RunnerState s;
  bool resumed = false;
  if (ctx.resume && fs::exists(ckpt)) {
    try {
      resumed = readCheckpoint(ckpt, fp, s, classes, deposits, flow);
    } catch (const std::exception& e) {
      throw InputError(keyLocation("run"), fmt::format("cannot resume from {}: {}", ckpt.string(), e.what()), {},
                       "delete the checkpoint (or the .partial folder) to start afresh");
    }
  }
  if (!resumed) {
    const FlowSolveResult r0 = flow.solve({});
    if (r0.blocked) throw InputError(c.where("geometry.mask"), "the flow solver found no flow through the geometry", {}, "a mask with an open pore path");
    if (max_pressure > 0 && r0.pressure_drop > max_pressure)
      throw InputError(c.where("flow.max_pressure"), "the clean chip already needs more pressure than the pump's limit at the set flow rate",
                       fmt::format("{:.4g} Pa", max_pressure),
                       fmt::format("a limit above the {:.4g} Pa the clean geometry needs, or a lower flow rate", r0.pressure_drop));
    s.k = s.k0 = r0.permeability;
    s.solve_seconds = r0.seconds;
  }
  out.details["resumed_from_frame"] = resumed ? s.next_frame : 0;
  if (!resumed && c.quantity("engines.compare_window") > 0) compareEnginesOnTheScene(c, flow.field(), scene, classes[0].diameter, out);
  if (s.retention.empty()) s.retention = "t_s,injected,retained,left,inside\n";
  if (s.permeability.empty()) s.permeability = "t_s,k_m2,k_D,k_over_k0,resolves\n";

  const double strip_u = 1.5 * (porosity > 0 ? u_darcy / porosity : 0.0) * dt_out;
  const auto wall_now = [&] { return s.wall_before + std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count(); };
  const double wall_at_start = s.wall_before;
  const auto totalSteps = [&] {
    std::int64_t n = 0;
    for (const auto& cl : classes) n += cl.engine->stats().steps;
    return n;
  };
  std::vector<std::vector<ParticleState>> ps(classes.size());
  // Set when a fluid solve finds that the pump cannot deliver the set rate: injection
  // stops, the frame is written and the run ends (Micromodel.hpp, "The pump").
  std::optional<PumpStall> stall;
  for (std::int64_t k = s.next_frame; k <= frames; ++k) {
    const double t = k * dt_out;
    for (std::size_t ci = 0; ci < classes.size(); ++ci) {
      if (k > 0) classes[ci].engine->advance(t);
      ps[ci] = classes[ci].engine->particles();
    }
    // Four-way: every new deposit adds its (parcel) volume to the deposit grid:
    // at a grain (in-plane gap to the wall below one radius: touching it, within
    // the pixel staircase's resolution) it fills columns, elsewhere it lies on a
    // plate and thins the aperture by up to a monolayer per pixel (layer mode).
    if (four_way) {
      for (std::size_t ci = 0; ci < classes.size(); ++ci) {
        auto& cl = classes[ci];
        const double vol = weight * kPi * cl.diameter * cl.diameter * cl.diameter / 6.0;
        for (std::size_t i = 0; i < ps[ci].size(); ++i)
          if (ps[ci][i].status == ParticleStatus::deposited && !(cl.accounted[i] & 1)) {
            const Vec3& x = ps[ci][i].x;
            const bool at_wall = flow.field()->wallDistance(x.x(), x.y()) < cl.diameter;
            ++(at_wall ? s.wall_deposits : s.plate_deposits);
            if (!layers || at_wall) deposits.add(x.x(), x.y(), vol);
            else deposits.addLayer(x.x(), x.y(), vol, cl.diameter);
            cl.accounted[i] |= 1;
          }
      }
      if (deposits.lostColumns() - s.lost_at_solve >= static_cast<double>(resolve_pixels)) {
        const FlowSolveResult r = flow.solve(deposits.closed(), layers ? deposits.aperture() : std::vector<double>{});
        ++s.resolves;
        s.solve_seconds += r.seconds;
        s.lost_at_solve = deposits.lostColumns();
        s.k = r.permeability;
        if (r.blocked && s.blocked_at < 0) s.blocked_at = t;
        stall = pumpStall(r, max_pressure, t);
        for (std::size_t ci = 0; ci < classes.size(); ++ci) {
          classes[ci].engine->captureInSolid();
          ps[ci] = classes[ci].engine->particles();
        }
      }
    }
    // Injection: each class's particles due by t, placed in the inlet strip the flow filled during the last interval.
    for (std::size_t ci = 0; ci < classes.size() && !stall; ++ci) {
      auto& cl = classes[ci];
      const std::int64_t due = dueBy(inject_rate, cl.fraction, t, t_inj);
      if (due <= cl.injected) continue;
      const double strip = std::min(std::max(strip_u, cl.diameter), 0.5 * W);
      const std::uint64_t sseed = seed * 1000003ULL + static_cast<std::uint64_t>(k) + 7919ULL * ci;
      std::vector<Vec3> pos;
      try {
        pos = sampleInlet(*flow.field(), 0.5 * cl.diameter, 0.0, strip, static_cast<int>(due - cl.injected), sseed, ps[ci]);
      } catch (const InputError&) {
        // The inlet strip is full (deposits clog the inlet, or a burst of large
        // fines): place what fits one by one and carry the rest to the next frame.
        std::vector<ParticleState> taken = ps[ci];
        for (std::int64_t m = 0; m < due - cl.injected; ++m) {
          try {
            const auto one = sampleInlet(*flow.field(), 0.5 * cl.diameter, 0.0, strip, 1, sseed + 104729ULL * (m + 1), taken);
            pos.push_back(one[0]);
            ParticleState q;
            q.x = one[0];
            taken.push_back(q);
          } catch (const InputError&) {
            break;
          }
        }
      }
      cl.engine->insert(pos);
      cl.injected += static_cast<std::int64_t>(pos.size());
      cl.deferred = due - cl.injected;
      ps[ci] = cl.engine->particles();
      while (cl.global_id.size() < ps[ci].size()) cl.global_id.push_back(s.next_id++);
      cl.accounted.resize(ps[ci].size(), 0);
    }
    // Frame output.
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
        if (dep && (cl.accounted[i] & 2)) continue;
        if (dep) cl.accounted[i] |= 2;
        const std::int64_t id = cl.global_id[i];
        s.rows.push_back({k, id, t, p.x.x() / pixel - 0.5, (H - p.x.y()) / pixel - 0.5, p.x.z(), static_cast<std::uint8_t>(dep)});
        if (!dep) {
          now.push_back({id, p.x.x(), p.x.y()});
          const auto it = std::lower_bound(s.last.begin(), s.last.end(), id, [](const LastPos& l, std::int64_t v) { return l.id < v; });
          if (it != s.last.end() && it->id == id) {
            s.speed_sum += std::hypot(p.x.x() - it->x, p.x.y() - it->y) / dt_out;
            ++s.speed_n;
          }
        }
      }
    }
    std::sort(now.begin(), now.end(), [](const LastPos& x, const LastPos& y) { return x.id < y.id; });
    s.last = std::move(now);
    if (!n.balanced()) throw std::logic_error(fmt::format("particle counts do not balance at t = {} s", t));
    s.retention += fmt::format("{:.9g},{},{},{},{}\n", t, n.injected, n.deposited, n.left, n.inside);
    s.permeability += fmt::format("{:.9g},{:.9g},{:.9g},{:.9g},{}\n", t, s.k, s.k / kDarcy, s.k / s.k0, s.resolves);
    s.next_frame = k + 1;
    if (stall) break;
    const std::int64_t steps = totalSteps();
    const bool stop = stop_after > 0 && s.next_frame >= stop_after && k < frames;
    if (stop || (checkpoint_every > 0 && steps - s.steps_at_checkpoint >= checkpoint_every && k < frames)) {
      s.steps_at_checkpoint = steps;
      RunnerState snapshot = s;
      snapshot.wall_before = wall_now();
      writeCheckpoint(ckpt, fp, snapshot, classes, deposits, flow);
      if (stop) throw RunStopped(fmt::format("stopped after {} output frames as asked (run.stop_after_frames); {} holds the checkpoint, "
                                             "continue with `mmval run --resume`", s.next_frame, ckpt.string()));
    }
  }
  const double wall = wall_now();

  // Outputs.
  Tracks traj;
  traj.points.reserve(s.rows.size());
  for (const auto& r : s.rows) {
    TrackPoint tp;
    tp.frame = r.frame;
    tp.particle = r.particle;
    tp.t = r.t;
    tp.x_px = r.x_px;
    tp.y_px = r.y_px;
    tp.x = r.x_px * pixel;
    tp.y = r.y_px * pixel;
    tp.z = r.z;
    tp.state = r.deposited ? "deposited" : "mobile";
    traj.points.push_back(tp);
  }
  std::stable_sort(traj.points.begin(), traj.points.end(), [](const TrackPoint& x, const TrackPoint& y) {
    return x.particle != y.particle ? x.particle < y.particle : x.frame < y.frame;
  });
  writeTracksCsv(ctx.out_dir / "trajectories.csv", traj, pixel);
  // The particles as a .vtp series in the fields' frame (docs/outputs.md: metres, y up from
  // the image's bottom edge): the inverse of the pixel columns' x_px = X/p - 1/2, y_px = (H - Y)/p - 1/2.
  const std::vector<std::string> particle_series = vtk::writeParticleSeries(ctx.out_dir, "particles", traj, [&](const TrackPoint& q) {
    return std::array<double, 3>{(q.x_px + 0.5) * pixel, H - (q.y_px + 0.5) * pixel, std::isfinite(q.z) ? q.z : 0.0};
  });
  writeFileAtomic(ctx.out_dir / "retention.csv", s.retention);
  writeFileAtomic(ctx.out_dir / "permeability.csv", s.permeability);
  std::error_code ec;
  fs::remove(ckpt, ec);

  Counts n;
  EngineStats st;
  st.wall_seconds = 0;
  st.min_dt = std::numeric_limits<double>::infinity();
  nlohmann::json settings = nlohmann::json::array(), per_class = nlohmann::json::array();
  std::int64_t deferred = 0, scheduled = 0;
  // What the schedule called for by the run's planned end (a stall does not shorten the schedule).
  const double t_planned = static_cast<double>(frames) * dt_out;
  for (const auto& cl : classes) {
    const Counts nc = cl.engine->counts();
    const EngineStats e = cl.engine->stats();
    n.injected += nc.injected;
    n.inside += nc.inside;
    n.deposited += nc.deposited;
    n.left += nc.left;
    st.steps += e.steps;
    st.particle_steps += e.particle_steps;
    st.wall_seconds += e.wall_seconds;
    st.min_dt = std::min(st.min_dt, e.min_dt);
    st.max_dt = std::max(st.max_dt, e.max_dt);
    settings.push_back(cl.engine->describe());
    deferred += cl.deferred;
    const std::int64_t sched = dueBy(inject_rate, cl.fraction, t_planned, t_inj);
    scheduled += sched;
    per_class.push_back({{"diameter_um", cl.diameter * 1e6}, {"fraction", cl.fraction}, {"scheduled", sched}, {"injected", nc.injected},
                         {"never_injected", sched - nc.injected}, {"not_yet_placed", cl.deferred}, {"retained", nc.deposited},
                         {"left", nc.left}, {"inside", nc.inside}});
  }
  out.files = {"trajectories.csv", "retention.csv", "permeability.csv"};
  if (!particle_series.empty()) out.files.push_back(particle_series.back());  // particles.pvd stands for its snapshots
  const double inj = static_cast<double>(n.injected);
  out.metrics["retained_fraction"] = n.injected ? n.deposited / inj : 0.0;
  out.metrics["left_fraction"] = n.injected ? n.left / inj : 0.0;
  out.metrics["count_balance_error"] = static_cast<double>(n.injected - n.inside - n.deposited - n.left);
  out.metrics["injected"] = inj;
  out.metrics["retained"] = static_cast<double>(n.deposited);
  out.metrics["left"] = static_cast<double>(n.left);
  out.metrics["inside"] = static_cast<double>(n.inside);
  out.metrics["represented_particles"] = inj / sample;
  // Due by the end of injection but never placed because the inlet strip stayed full (inlet clogging); not part of "injected".
  out.metrics["not_placed"] = static_cast<double>(deferred);
  // The schedule against what entered: never-injected particles are in neither retained nor injected.
  out.metrics["scheduled"] = static_cast<double>(scheduled);
  out.metrics["never_injected"] = static_cast<double>(scheduled - n.injected);
  const double t_end = static_cast<double>(s.next_frame - 1) * dt_out;  // the last frame written
  out.details["end_time_s"] = t_end;
  reportPump(s, stall, max_pressure, fo.viscosity * u_darcy * W, scheduled, n.injected, out);
  if (!window.empty()) reportWindow(s, window, t_end, out);
  out.metrics["mean_speed"] = s.speed_n ? s.speed_sum / s.speed_n : 0.0;
  out.units["mean_speed"] = "um/s";
  out.metrics["k_over_k0"] = s.k / s.k0;
  out.metrics["permeability_reduction"] = 1.0 - s.k / s.k0;
  out.units["permeability_reduction"] = "%";
  out.metrics["k0"] = s.k0;
  out.units["k0"] = "D";
  out.metrics["resolves"] = static_cast<double>(s.resolves);
  {
    // Time to the first 10 % permeability loss (the paper's "time to bridging"
    // trend: shorter at higher velocity); absent when it never happened.
    std::istringstream rows(s.permeability);
    std::string line;
    std::getline(rows, line);
    while (std::getline(rows, line)) {
      double t = 0, km2 = 0, kd = 0, ratio = 1;
      char sep = 0;
      std::istringstream l(line);
      l >> t >> sep >> km2 >> sep >> kd >> sep >> ratio;
      if (ratio < 0.9) {
        out.metrics["time_to_10pct_reduction"] = t;
        out.units["time_to_10pct_reduction"] = "s";
        break;
      }
    }
  }
  if (s.blocked_at >= 0) {
    // Clogging: the first re-solve that found no open path from inlet to outlet (k = 0).
    out.metrics["time_to_clogging"] = s.blocked_at;
    out.units["time_to_clogging"] = "s";
    out.details["blocked_at_s"] = s.blocked_at;
  }
  out.metrics["closed_pixels"] = static_cast<double>(deposits.closedCount());
  // Mean loss of aperture over the pore pixels (closed pixels count as a whole column).
  out.metrics["aperture_loss"] = pore_pixels > 0 ? deposits.lostColumns() / static_cast<double>(pore_pixels) : 0.0;
  out.metrics["wall_time"] = wall;
  out.units["wall_time"] = "s";
  out.metrics["fluid_solve_time"] = s.solve_seconds;
  out.units["fluid_solve_time"] = "s";
  out.metrics["particle_steps_per_second"] = wall > 0 ? static_cast<double>(st.particle_steps) / wall : 0.0;
  out.units["particle_steps_per_second"] = "Hz";
  out.metrics["engine_particle_steps_per_second"] = st.wall_seconds > 0 ? static_cast<double>(st.particle_steps) / st.wall_seconds : 0.0;
  out.units["engine_particle_steps_per_second"] = "Hz";
  out.metrics["porosity"] = porosity;
  out.details["engine"] = "overdamped";
  out.details["engine_reason"] = choice.reason;
  out.details["selection"] = choice.toJson();
  out.details["engine_settings"] = settings.size() == 1 ? settings[0] : settings;
  out.details["size_classes"] = per_class;
  out.details["darcy_velocity_m_s"] = u_darcy;
  out.details["interstitial_velocity_m_s"] = porosity > 0 ? u_darcy / porosity : u_darcy;
  out.details["injection_rate_per_s"] = inject_rate;
  out.details["parcel_weight"] = weight;
  out.details["coupling"] = {{"mode", four_way ? "four-way" : "one-way"},
                             {"resolve_threshold_pixels", resolve_pixels},
                             {"plate_deposits", layers ? "layer" : "column"},
                             {"layer_packing", layer_model.packing},
                             {"min_aperture_um", layer_model.min_aperture * 1e6},
                             {"deposits_at_walls", s.wall_deposits},
                             {"deposits_on_plates", s.plate_deposits},
                             {"pore_pixels", pore_pixels},
                             {"pixel_capacity_um3", deposits.capacity() * 1e18},
                             {"deposited_volume_um3", deposits.depositedVolume() * 1e18},
                             {"fluid_grid_cells", {std::lround(grains.cols() * fo.cells_per_pixel), std::lround(grains.rows() * fo.cells_per_pixel)}}};
  out.details["counts"] = {{"scheduled", scheduled}, {"injected", n.injected}, {"never_injected", scheduled - n.injected},
                           {"inside", n.inside}, {"deposited", n.deposited}, {"left", n.left}};
  out.details["steps"] = st.steps;
  out.details["particle_steps"] = st.particle_steps;
  out.details["dt_min_s"] = std::isfinite(st.min_dt) ? st.min_dt : 0.0;
  out.details["dt_max_s"] = st.max_dt;
  out.details["wall_time_this_process_s"] = wall - wall_at_start;
  out.details["outputs"] = {
      {"trajectories.csv", "frame,particle,x,y,x_um,y_um,t_s,z_um,state (tracks schema; x, y pixels of the geometry image from the "
                           "top-left pixel centre, y down; x_um = x * pixel size; deposited particles appear once, state deposited)"},
      {"retention.csv", "t_s,injected,retained,left,inside"},
      {"permeability.csv", "t_s,k_m2,k_D,k_over_k0,resolves"}};
  return out;
}

}  // namespace

CaseKind micromodelKind() {
  CaseKind k;
  k.name = "particles-micromodel";
  k.summary = "The micromodel experiment: fines injected into a pore image's depth-averaged Stokes flow (mmval's solver), "
              "overdamped engine with attachment, four-way deposits with re-solves: trajectories (tracks schema), retention "
              "and permeability over time, checkpoint/restart";
  k.declare = declareMicromodel;
  k.run = runMicromodel;
  return k;
}

}  // namespace mmval::particles
