#include "mmval/core/JsonNumbers.hpp"
#include "mmval/particles/Micromodel.hpp"

#include "CaseScene.hpp"
#include "MicromodelDetail.hpp"
#include "MicromodelPicture.hpp"
#include "MicromodelStages.hpp"

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
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/OutputTables.hpp"
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
using namespace stages;

void writeCheckpoint(const fs::path& file, const std::string& fp, const RunnerState& s, const std::vector<SizeClass>& classes,
                     const DepositGrid& deposits, const MicromodelFlow& flow) {
  CheckpointWriter w;
  w.putString("mmval-micromodel-checkpoint-7");
  w.putString(fp);
  w.put(s.next_frame); w.put(s.next_id); w.put(s.resolves); w.put(s.resolves_pattern_kept); w.put(s.steps_at_checkpoint);
  w.put(s.wall_deposits); w.put(s.plate_deposits); w.put(s.lost_at_solve); w.put(s.blocked_at);
  w.put(s.k); w.put(s.k0); w.put(s.pressure_drop); w.put(s.speed_sum); w.put(s.solve_seconds); w.put(s.wall_before); w.put(s.speed_n);
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
  if (r.getString() != "mmval-micromodel-checkpoint-7") throw std::runtime_error("checkpoint " + file.string() + ": unknown format");
  if (r.getString() != fp) return false;  // another scene: start afresh
  s.next_frame = r.get<std::int64_t>(); s.next_id = r.get<std::int64_t>(); s.resolves = r.get<std::int64_t>();
  s.resolves_pattern_kept = r.get<std::int64_t>();
  s.steps_at_checkpoint = r.get<std::int64_t>();
  s.wall_deposits = r.get<std::int64_t>(); s.plate_deposits = r.get<std::int64_t>(); s.lost_at_solve = r.get<double>();
  s.blocked_at = r.get<double>();
  s.k = r.get<double>(); s.k0 = r.get<double>(); s.pressure_drop = r.get<double>(); s.speed_sum = r.get<double>(); s.solve_seconds = r.get<double>();
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
  setDetail(out.details, DetailField::engine_comparison, rows);
  if (!r.reference_version.empty()) setDetail(out.details, DetailField::liggghts_version, r.reference_version);
}

/// The pump's outputs: the pressure drop the set rate needed on the clean
/// chip and at the last solve with a flow path (Darcy: mu u L / k, `mu_u_L` = mu u L),
/// and the stall if there was one, also as one line on stderr.
void reportPump(const RunnerState& s, const std::optional<PumpStall>& stall, double max_pressure, double mu_u_L, std::int64_t scheduled,
                std::int64_t injected, RunOutput& out) {
  const auto pressureFor = [&](double k) { return k > 0 ? mu_u_L / k : 0.0; };
  double k_open = s.k0;
  const auto table = tables::parseTable(s.permeability, "permeability.csv");  // named: a temporary would die before the loop
  for (double km2 : table.at("k_m2"))
    if (km2 > 0) k_open = km2;
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
  setDetail(out.details, DetailField::pump_stall,
            {{"time_s", stall->time_s},
             {"reason", stall->reasonName()},
             {"pressure_Pa", finiteOrNull(stall->pressure_Pa)},
             {"max_pressure_Pa", limit},
             {"message", stall->describe()},
             {"then", "injection stopped and the run ended at this frame; particles still moving are counted as inside"},
             {"never_injected", scheduled - injected}});
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

/// Start: from the checkpoint when resuming with one of this scene (returns true),
/// else from a clean chip: its flow solved, the pump's limit checked (InputError),
/// k0 set. Writes the CSV headers either way.
bool startOrResume(const Case& c, const RunContext& ctx, const fs::path& ckpt, const std::string& fp, const MicromodelSetup& set,
                   RunnerState& s, std::vector<SizeClass>& classes, DepositGrid& deposits, MicromodelFlow& flow) {
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
    if (set.max_pressure > 0 && r0.pressure_drop > set.max_pressure)
      throw InputError(c.where("flow.max_pressure"), "the clean chip already needs more pressure than the pump's limit at the set flow rate",
                       fmt::format("{:.4g} Pa", set.max_pressure),
                       fmt::format("a limit above the {:.4g} Pa the clean geometry needs, or a lower flow rate", r0.pressure_drop));
    s.k = s.k0 = r0.permeability;
    s.pressure_drop = r0.pressure_drop;
    s.solve_seconds = r0.seconds;
  }
  if (s.retention.empty()) s.retention = tables::retentionHeader();
  if (s.permeability.empty()) s.permeability = tables::permeabilityHeader();
  return resumed;
}

std::int64_t totalSteps(const std::vector<SizeClass>& classes) {
  std::int64_t n = 0;
  for (const auto& cl : classes) n += cl.engine->stats().steps;
  return n;
}

/// Checkpoint: after frame `k`, once run.checkpoint_every engine steps have passed
/// since the last one, or when run.stop_after_frames asks the run to stop (then
/// RunStopped). Never after the last frame. `wall` is the run's wall time so far.
void checkpointIfDue(const RunControl& run, std::int64_t k, double wall, const fs::path& ckpt, const std::string& fp, RunnerState& s,
                     const std::vector<SizeClass>& classes, const DepositGrid& deposits, const MicromodelFlow& flow) {
  const std::int64_t steps = totalSteps(classes);
  const bool stop = run.stop_after > 0 && s.next_frame >= run.stop_after && k < run.frames;
  if (!stop && !(run.checkpoint_every > 0 && steps - s.steps_at_checkpoint >= run.checkpoint_every && k < run.frames)) return;
  s.steps_at_checkpoint = steps;
  RunnerState snapshot = s;
  snapshot.wall_before = wall;
  writeCheckpoint(ckpt, fp, snapshot, classes, deposits, flow);
  if (stop)
    throw RunStopped(fmt::format("stopped after {} output frames as asked (run.stop_after_frames); {} holds the checkpoint, "
                                 "continue with `mmval run --resume`",
                                 s.next_frame, ckpt.string()));
}

/// Outputs: trajectories.csv (sorted by particle, then frame), the particles'
/// .vtp series, retention.csv, permeability.csv and the picture deposits.png
/// (`radius_px`: the largest particle radius in mask pixels); the checkpoint removed.
/// Returns the files to list (particles.pvd stands for its snapshots).
std::vector<std::string> writeOutputs(const fs::path& dir, const RunnerState& s, const SceneGeometry& geo, const fs::path& ckpt,
                                      double radius_px) {
  const double pixel = geo.pixel, H = geo.height;
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
  writeTracksCsv(dir / "trajectories.csv", traj, pixel);
  // The particles as a .vtp series in the fields' frame (docs/outputs.md: metres, y up from
  // the image's bottom edge): the inverse of the pixel columns' x_px = X/p - 1/2, y_px = (H - Y)/p - 1/2.
  const std::vector<std::string> particle_series = vtk::writeParticleSeries(dir, "particles", traj, [&](const TrackPoint& q) {
    return std::array<double, 3>{(q.x_px + 0.5) * pixel, H - (q.y_px + 0.5) * pixel, std::isfinite(q.z) ? q.z : 0.0};
  });
  writeFileAtomic(dir / "retention.csv", s.retention);
  writeFileAtomic(dir / "permeability.csv", s.permeability);
  writeDepositPicture(dir / "deposits.png", geo.grains, traj, radius_px);
  std::error_code ec;
  fs::remove(ckpt, ec);
  std::vector<std::string> files = {"trajectories.csv", "retention.csv", "permeability.csv", "deposits.png"};
  if (!particle_series.empty()) files.push_back(particle_series.back());
  return files;
}

/// The size classes summed at the end: counts, engine statistics and settings,
/// and what the schedule called for by the run's planned end.
struct ClassTally {
  Counts n;
  EngineStats st;
  nlohmann::json settings = nlohmann::json::array(), per_class = nlohmann::json::array();
  std::int64_t deferred = 0, scheduled = 0;
};

ClassTally tallyClasses(const std::vector<SizeClass>& classes, const Schedule& sch, const RunControl& run) {
  ClassTally a;
  a.st.wall_seconds = 0;
  a.st.min_dt = std::numeric_limits<double>::infinity();
  // What the schedule called for by the run's planned end (a stall does not shorten the schedule).
  const double t_planned = static_cast<double>(run.frames) * run.dt_out;
  for (const auto& cl : classes) {
    const Counts nc = cl.engine->counts();
    const EngineStats e = cl.engine->stats();
    a.n.injected += nc.injected;
    a.n.inside += nc.inside;
    a.n.deposited += nc.deposited;
    a.n.left += nc.left;
    a.n.strained += nc.strained;
    a.st.steps += e.steps;
    a.st.particle_steps += e.particle_steps;
    a.st.wall_seconds += e.wall_seconds;
    a.st.min_dt = std::min(a.st.min_dt, e.min_dt);
    a.st.max_dt = std::max(a.st.max_dt, e.max_dt);
    a.settings.push_back(cl.engine->describe());
    a.deferred += cl.deferred;
    const std::int64_t sched = dueBy(sch.rate_per_s, cl.fraction, t_planned, sch.injection_time);
    a.scheduled += sched;
    a.per_class.push_back({{"diameter_um", cl.diameter * 1e6}, {"fraction", cl.fraction}, {"scheduled", sched}, {"injected", nc.injected},
                           {"never_injected", sched - nc.injected}, {"not_yet_placed", cl.deferred}, {"retained", nc.deposited},
                           {"attached", nc.attached()}, {"strained", nc.strained}, {"left", nc.left}, {"inside", nc.inside}});
  }
  return a;
}

/// Retention and the particle counts (retained / injected, the paper's definition).
void reportCounts(const ClassTally& a, double sample, RunOutput& out) {
  const Counts& n = a.n;
  const double inj = static_cast<double>(n.injected);
  out.metrics["retained_fraction"] = n.injected ? n.deposited / inj : 0.0;
  out.metrics["left_fraction"] = n.injected ? n.left / inj : 0.0;
  out.metrics["count_balance_error"] = static_cast<double>(n.injected - n.inside - n.deposited - n.left);
  out.metrics["injected"] = inj;
  out.metrics["retained"] = static_cast<double>(n.deposited);
  // Retained = attached + strained (deposition.straining): held by a surface, or by the flow in a
  // throat narrower than the particle.
  out.metrics["attached"] = static_cast<double>(n.attached());
  out.metrics["strained"] = static_cast<double>(n.strained);
  out.metrics["strained_fraction"] = n.injected ? n.strained / inj : 0.0;
  out.metrics["left"] = static_cast<double>(n.left);
  out.metrics["inside"] = static_cast<double>(n.inside);
  out.metrics["represented_particles"] = inj / sample;
  // Due by the end of injection but never placed because the inlet strip stayed full (inlet clogging); not part of "injected".
  out.metrics["not_placed"] = static_cast<double>(a.deferred);
  // The schedule against what entered: never-injected particles are in neither retained nor injected.
  out.metrics["scheduled"] = static_cast<double>(a.scheduled);
  out.metrics["never_injected"] = static_cast<double>(a.scheduled - n.injected);
  out.details["counts"] = {{"scheduled", a.scheduled}, {"injected", n.injected}, {"never_injected", a.scheduled - n.injected},
                           {"inside", n.inside}, {"deposited", n.deposited}, {"attached", n.attached()},
                           {"strained", n.strained}, {"left", n.left}};
}

/// Particles due but never placed (the inlet strip stayed full to the end): they
/// are retried every frame and never dropped, so at the end they are named with
/// the reason, in details.not_placed and as one line on stderr. A pump stall says
/// it itself (reportPump), so nothing is added then.
void reportNotPlaced(const ClassTally& a, const std::optional<PumpStall>& stall, double t_end, RunOutput& out) {
  if (a.deferred <= 0 || stall) return;
  const std::string why = fmt::format(
      "{} particles due by t = {:g} s found no free place in the inlet strip (grains, deposits or particles still there); they were "
      "retried every output frame to the end and are counted in never_injected, not in injected. A longer run, a longer "
      "particles.injection_time or a lower concentration places them",
      a.deferred, t_end);
  out.details["not_placed"] = {{"count", a.deferred}, {"reason", why}};
  std::fprintf(stderr, "mmval: %s\n", why.c_str());
}

/// Permeability over the run: k/k0, the time to the first 10 % loss, clogging,
/// closed pixels and the mean aperture loss.
void reportPermeability(const RunnerState& s, const DepositGrid& deposits, std::int64_t pore_pixels, RunOutput& out) {
  out.metrics["k_over_k0"] = s.k / s.k0;
  out.metrics["permeability_reduction"] = 1.0 - s.k / s.k0;
  out.units["permeability_reduction"] = "%";
  out.metrics["k0"] = s.k0;
  out.units["k0"] = "D";
  out.metrics["resolves"] = static_cast<double>(s.resolves);
  out.metrics["resolves_pattern_kept"] = static_cast<double>(s.resolves_pattern_kept);
  // Time to the first 10 % permeability loss (the paper's "time to bridging"
  // trend: shorter at higher velocity); absent when it never happened.
  const tables::TableColumns rows = tables::parseTable(s.permeability, "permeability.csv");
  const std::vector<double>& t = rows.at("t_s");
  const std::vector<double>& ratio = rows.at("k_over_k0");
  for (std::size_t i = 0; i < t.size(); ++i)
    if (ratio[i] < 0.9) {
      out.metrics["time_to_10pct_reduction"] = t[i];
      out.units["time_to_10pct_reduction"] = "s";
      break;
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
}

/// Cost: wall time (over all processes of a resumed run and of this one), fluid
/// solves, particle steps per second, time steps.
void reportCost(const RunnerState& s, const EngineStats& st, double wall, double wall_at_start, RunOutput& out) {
  out.metrics["wall_time"] = wall;
  out.units["wall_time"] = "s";
  out.metrics["fluid_solve_time"] = s.solve_seconds;
  out.units["fluid_solve_time"] = "s";
  out.metrics["particle_steps_per_second"] = wall > 0 ? static_cast<double>(st.particle_steps) / wall : 0.0;
  out.units["particle_steps_per_second"] = "Hz";
  out.metrics["engine_particle_steps_per_second"] = st.wall_seconds > 0 ? static_cast<double>(st.particle_steps) / st.wall_seconds : 0.0;
  out.units["engine_particle_steps_per_second"] = "Hz";
  out.details["steps"] = st.steps;
  out.details["particle_steps"] = st.particle_steps;
  out.details["dt_min_s"] = std::isfinite(st.min_dt) ? st.min_dt : 0.0;
  out.details["dt_max_s"] = st.max_dt;
  out.details["wall_time_this_process_s"] = wall - wall_at_start;
}

/// The scene's settings as run: engine, flow, injection, coupling, outputs.
void reportScene(const MicromodelSetup& set, const ClassTally& a, const RunnerState& s, const DepositGrid& deposits, RunOutput& out) {
  const double u_darcy = set.flow.darcy_velocity, porosity = set.geo.porosity;
  const Coupling& cp = set.coupling;
  out.metrics["porosity"] = porosity;
  out.details["engine"] = "overdamped";
  out.details["engine_reason"] = set.choice.reason;
  out.details["selection"] = set.choice.toJson();
  out.details["engine_settings"] = a.settings.size() == 1 ? a.settings[0] : a.settings;
  out.details["size_classes"] = a.per_class;
  out.details["darcy_velocity_m_s"] = u_darcy;
  out.details["interstitial_velocity_m_s"] = porosity > 0 ? u_darcy / porosity : u_darcy;
  out.details["injection_rate_per_s"] = set.schedule.rate_per_s;
  out.details["parcel_weight"] = cp.weight;
  // How many particles the scene stands for, in two readings: those simulated (the schedule over the
  // injection time) and the real particles of the suspension they sample (simulated / sample_fraction).
  // The paper's validation experiment states both a concentration and "about 6000" injected, which differ
  // by ~500x; a case chooses its reading through particles.sample_fraction and says so in its header.
  const double simulated = set.schedule.rate_per_s * set.schedule.injection_time;
  out.details["particle_count"] = {{"simulated", simulated},
                                   {"sample_fraction", set.sample},
                                   {"real_particles_delivered", set.sample > 0 ? simulated / set.sample : simulated},
                                   {"injection_time_s", set.schedule.injection_time}};
  setDetail(out.details, DetailField::coupling,
            {{"mode", cp.four_way ? "four-way" : "one-way"},
             {"resolve_threshold_pixels", cp.resolve_pixels},
             {"plate_deposits", cp.layers ? "layer" : "column"},
             {"layer_packing", cp.layer_model.packing},
             {"min_aperture_um", cp.layer_model.min_aperture * 1e6},
             {"deposits_at_walls", s.wall_deposits},
             {"deposits_on_plates", s.plate_deposits},
             {"pore_pixels", set.geo.pore_pixels},
             {"pixel_capacity_um3", deposits.capacity() * 1e18},
             {"deposited_volume_um3", deposits.depositedVolume() * 1e18},
             {"fluid_grid_cells",
              {std::lround(set.geo.grains.cols() * set.flow.cells_per_pixel), std::lround(set.geo.grains.rows() * set.flow.cells_per_pixel)}}});
  out.details["outputs"] = {
      {"trajectories.csv", "frame,particle,x,y,x_um,y_um,t_s,z_um,state (tracks schema; x, y pixels of the geometry image from the "
                           "top-left pixel centre, y down; x_um = x * pixel size; deposited particles appear once, state deposited)"},
      {"retention.csv", tables::retentionHeader().substr(0, tables::retentionHeader().size() - 1) + " (docs/outputs.md, Tables)"},
      {"permeability.csv", tables::permeabilityHeader().substr(0, tables::permeabilityHeader().size() - 1) + " (docs/outputs.md, Tables)"}};
}

/// The run: the scene read once, then per output frame transport -> deposit ->
/// re-solve -> insertion -> frame record (MicromodelStages.hpp), a checkpoint when
/// due; a pump stall ends the run at its frame. Then the outputs and the report.
RunOutput runMicromodel(const Case& c, const RunContext& ctx) {
  const auto t_start = std::chrono::steady_clock::now();
  RunOutput out;
  MicromodelSetup set = readSetup(c, out);
  std::vector<SizeClass>& classes = set.classes;
  const RunControl& run = set.run;
  MicromodelFlow flow(set.geo.grains, set.flow);
  makeEngines(classes, flow.field(), set.scene, set.seed);
  readCouplingAndSchedule(c, set);
  DepositGrid deposits(set.geo.grains, set.geo.pixel, set.geo.depth, set.coupling.fill_fraction, set.coupling.layer_model);

  const fs::path ckpt = ctx.out_dir / "checkpoint.bin";
  const std::string fp = checkpointFingerprint(c);
  RunnerState s;
  const bool resumed = startOrResume(c, ctx, ckpt, fp, set, s, classes, deposits, flow);
  setDetail(out.details, DetailField::resumed_from_frame, resumed ? s.next_frame : 0);
  if (!resumed && c.quantity("engines.compare_window") > 0) compareEnginesOnTheScene(c, flow.field(), set.scene, classes[0].diameter, out);

  const auto wall_now = [&] { return s.wall_before + std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count(); };
  const double wall_at_start = s.wall_before;
  // Set when a fluid solve finds that the pump cannot deliver the set rate: injection
  // stops, the frame is written and the run ends (Micromodel.hpp, "The pump").
  std::optional<PumpStall> stall;
  const bool final_resolve = c.flag("coupling.final_resolve");
  // Output frames still to run (a resumed run counts from its checkpoint): a bar on a terminal,
  // a line per tenth otherwise.
  const std::int64_t first_frame = s.next_frame;
  Progress progress(fmt::format("{} (output frames)", c.name()), static_cast<std::size_t>(std::max<std::int64_t>(0, run.frames + 1 - first_frame)),
                    ctx.quiet || !primaryRank());
  for (std::int64_t k = s.next_frame; k <= run.frames; ++k) {
    const double t = k * run.dt_out;
    ClassParticles ps = transport(classes, k, t);
    if (set.coupling.four_way) {
      deposit(classes, ps, *flow.field(), set.coupling, deposits, s.wall_deposits, s.plate_deposits);
      // The last frame re-solves on any aperture lost since the last solve (coupling.final_resolve),
      // before insertion and the frame record, so that the final k and the captures agree with them.
      Coupling cp = set.coupling;
      if (final_resolve && k == run.frames && deposits.lostColumns() > s.lost_at_solve) cp.resolve_pixels = 0;
      stall = resolve(flow, deposits, cp, set.max_pressure, t, classes, ps,
                      {s.resolves, s.resolves_pattern_kept, s.solve_seconds, s.lost_at_solve, s.k, s.pressure_drop, s.blocked_at});
    }
    if (!stall) insertDue(classes, *flow.field(), set.schedule, k, t, ps, s.next_id);
    recordFrame(classes, ps, k, t, {set.geo.pixel, set.geo.height}, run.dt_out, s);
    progress.update(static_cast<std::size_t>(k - first_frame + 1));
    if (stall) break;
    checkpointIfDue(run, k, wall_now(), ckpt, fp, s, classes, deposits, flow);
  }
  progress.finish();
  const double wall = wall_now();

  double largest = 0;
  for (const auto& cl : classes) largest = std::max(largest, cl.diameter);
  out.files = writeOutputs(ctx.out_dir, s, set.geo, ckpt, 0.5 * largest / set.geo.pixel);
  const ClassTally tally = tallyClasses(classes, set.schedule, run);
  reportCounts(tally, set.sample, out);
  const double t_end = static_cast<double>(s.next_frame - 1) * run.dt_out;  // the last frame written
  setDetail(out.details, DetailField::end_time_s, t_end);
  reportPump(s, stall, set.max_pressure, set.flow.viscosity * set.flow.darcy_velocity * set.geo.width, tally.scheduled, tally.n.injected, out);
  reportNotPlaced(tally, stall, t_end, out);
  if (!run.window.empty()) reportWindow(s, run.window, t_end, out);
  out.metrics["mean_speed"] = s.speed_n ? s.speed_sum / s.speed_n : 0.0;
  out.units["mean_speed"] = "um/s";
  reportPermeability(s, deposits, set.geo.pore_pixels, out);
  reportCost(s, tally.st, wall, wall_at_start, out);
  reportScene(set, tally, s, deposits, out);
  out.details["fluid_linear_solver"] = flow.linearSolver();  // and why, when not the kind's usual choice
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
