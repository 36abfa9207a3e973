// Unsteady flow around a cylinder in a channel with mmval's own solver
// (UnsteadyFlowSolver, BDF2): Schaefer & Turek (1996) 2D-2 and the paper's
// Re 100 set-up. Metrics over the last whole shedding periods: c_D max / min /
// mean, c_L max / min, Strouhal number f D / U_ref. Force history as CSV.
#include <sys/resource.h>

#include <cmath>
#include <optional>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "KindsCommon.hpp"
#include "MemoryBudget.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Checkpoint.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/VtkWriter.hpp"
#include "mmval/simulate/CylinderScene.hpp"
#include "mmval/simulate/FieldOutput.hpp"
#include "mmval/simulate/ForceHistory.hpp"
#include "mmval/simulate/Petsc.hpp"
#include "mmval/simulate/UnsteadyFlowSolver.hpp"

namespace mmval::simulate::detail {

namespace {
constexpr const char* kCheckpointFormat = "mmval-unsteady-cylinder-checkpoint-1";

/// The case's first acceptance entry on `metric` with a single, nonzero reference value (2D-2's
/// c_D max: FEATFLOW level 6, listed after the 1996 interval), or none.
const Acceptance* pointReference(const Case& c, const std::string& metric) {
  for (const Acceptance& a : c.acceptance())
    if (a.metric == metric && !a.reference.isInterval() && a.reference.value != 0) return &a;
  return nullptr;
}

std::string snapshotName(long long k) { return fmt::format("fields/fields-{:04d}.vtr", k); }

/// fields.pvd over the snapshots written (each one's own TimeValue gives its time, also for
/// those written before a resume); rank 0 only.
void writeSnapshotSeries(const std::filesystem::path& dir, long long snapshots) {
  if (PetscSession::rank() != 0) return;
  std::vector<vtk::PvdEntry> entries;
  for (long long k = 1; k <= snapshots; ++k) {
    const std::string name = snapshotName(k);
    if (std::filesystem::exists(dir / name)) entries.push_back({vtk::readArray(dir / name, "TimeValue").at(0), name});
  }
  vtk::writePvd(dir / "fields.pvd", entries);
}
}  // namespace

void declareUnsteadyCylinderKeys(Schema& s) {
  s.choice("numerics.unsteady_method", {"coupled", "projection"},
           "Unsteady (mmval): each step one coupled velocity-pressure solve (lagged LU + GMRES), or incremental pressure "
           "correction (velocity predictor, multigrid pressure Poisson solve, correction; no factorisation)")
      .def("coupled");
  s.real("numerics.projection_tolerance", "Unsteady (mmval), projection: relative tolerance of the velocity and pressure solves of a step")
      .def(1e-8).min(1e-14).max(1e-3);
  s.integer("numerics.projection_sweeps",
            "Unsteady (mmval), projection: predictor-correction sweeps per step (1: standard incremental pressure correction; each "
            "further sweep shrinks the splitting error towards the coupled solve)")
      .def(1).min(1).max(50);
  s.boolean("numerics.projection_rotational",
            "Unsteady (mmval), projection: the rotational pressure update p = p^n + dp - mu div u' (Timmermans, Minev & Van de Vosse "
            "1996), which removes the standard form's numerical pressure boundary layer at walls; measured effect small so far "
            "(docs/validation/cylinder-unsteady.md)")
      .def(false);
  s.real("numerics.max_courant", "Unsteady (mmval): Courant limit of the adaptive time step, max over cells of dt (|u|/dx + |v|/dy)").def(1.0).min(0.05).max(4.0);
  s.real("numerics.initial_perturbation",
         "Unsteady (mmval): strength eps of a Gaussian vortex placed 1.5 D behind the cylinder at t = 0; its peak speed is eps / 2 "
         "times the reference velocity (breaks the symmetry so shedding starts early; 0: none)")
      .def(0.0).min(0.0).max(1.0);
  s.quantity("numerics.statistics_from", "s", "Unsteady: start of the window for the periodic statistics (whole c_L periods after it); default: half the end time")
      .optional()
      .nonNegative();
  s.real("numerics.refine_downstream", "mmval: length of the uniformly refined box behind the cylinder centre, in diameters").def(1.5).min(0.6).max(100);
  s.real("numerics.refine_across", "mmval: half-height of the uniformly refined box around the cylinder centre, in diameters").def(0.75).min(0.6).max(100);
  s.real("run.checkpoint_minutes",
         "Unsteady: write checkpoint.bin every this many minutes of wall time (0: never); `mmval run --resume` continues from it")
      .def(5.0)
      .min(0.0);
  s.integer("output.snapshots",
            "Unsteady: flow fields written at this many times evenly spread over the finest level's run (the first step at or after "
            "each k end_time / n), as fields/fields-NNNN.vtr listed in fields.pvd for ParaView; 0 or 1: only the flow at the end time (fields.vtr)")
      .def(0)
      .min(0)
      .max(10000);
  s.integer("run.stop_after_steps", "Unsteady: stop (as if killed) after this many time steps of a level, leaving a checkpoint; a resumed run does not stop again (0: run to the end; tests)")
      .def(0)
      .min(0);
}

RunOutput runUnsteadyCylinder(const Case& c, const RunContext& ctx, const CylinderScene& scene,
                              const std::function<FlowProblem(int level)>& make_problem) {
  const double coef = scene.forceCoefficient(), Uref = scene.u_ref_m_s;
  const double D = scene.diameter_m, cx = scene.centre_x_m, cy = scene.centre_y_m;
  const double end_time = c.quantity("numerics.end_time"), dt0 = c.quantity("numerics.time_step");
  const double from = c.has("numerics.statistics_from") ? c.quantity("numerics.statistics_from") : 0.5 * end_time;
  if (from >= end_time)
    throw InputError(c.where("numerics.statistics_from"), "the statistics window starts after the end of the run", fmt::format("{} s", from),
                     fmt::format("a time below numerics.end_time = {} s", end_time));
  const std::vector<int> levels = levelsOf(c, "numerics.cells_around", 8, 4096);
  const std::string resolution_key = c.has("numerics.levels") ? "numerics.levels" : "numerics.cells_around";
  for (const int n : levels) {  // before the first step: the finest level must fit (steady per-cell figure; BDF2 keeps two more fields)
    const FlowProblem p = make_problem(n);
    requireSteadyFlowMemory(c, p.x.cells(), p.y.cells(), 0.0, resolution_key, "fewer cells around the cylinder");
  }
  UnsteadyOptions uo;
  uo.max_courant = c.real("numerics.max_courant");
  const bool projection = c.text("numerics.unsteady_method") == "projection";
  uo.method = projection ? UnsteadyMethod::projection : UnsteadyMethod::coupled;
  uo.projection_rtol = c.real("numerics.projection_tolerance");
  uo.projection_sweeps = static_cast<int>(c.integer("numerics.projection_sweeps"));
  uo.projection_rotational = c.flag("numerics.projection_rotational");
  const double eps = c.real("numerics.initial_perturbation");
  RunOutput out;
  out.details["solver"] = std::string(kSolverName) + (projection ? ", unsteady BDF2, pressure correction" : ", unsteady BDF2");
  out.details["time_scheme"] = std::string("BDF2 (variable step), convection linearised about the extrapolated velocity; adaptive dt (Courant limit); ") +
                               (projection ? "incremental pressure correction (velocity predictor, pressure Poisson solve: LU made once on one rank, CG + BoomerAMG on several; correction)"
                                           : "one coupled velocity-pressure solve per step (lagged LU + GMRES)");
  nlohmann::json ladder = nlohmann::json::array();
  SheddingStats last_stats;
  // Checkpoint (rank 0 writes, every rank reads): the finished levels' ladder rows, the level
  // under way with its wall time so far, the solver's state and the force history.
  const std::filesystem::path ckpt = ctx.out_dir.empty() ? std::filesystem::path{} : ctx.out_dir / "checkpoint.bin";
  const double checkpoint_s = 60 * c.real("run.checkpoint_minutes");
  const long long stop_after = c.integer("run.stop_after_steps");
  const std::string fingerprint = checkpointFingerprint(c);
  std::size_t first_level = 0;
  std::optional<CheckpointReader> resumed;
  double resumed_wall = 0;
  long long resumed_from = 0;  // steps of the level a resume continued (0: not resumed)
  const auto cannotResume = [&](const std::exception& e) {
    return InputError(c.where("run.checkpoint_minutes"), fmt::format("cannot resume from {}: {}", ckpt.string(), e.what()), {},
                      "delete the checkpoint (or the .partial folder) to start afresh");
  };
  if (ctx.resume && !ckpt.empty() && std::filesystem::exists(ckpt)) {
    try {
      CheckpointReader r(readBinaryFile(ckpt), ckpt.string());
      if (r.getString() != kCheckpointFormat) throw std::runtime_error("not an unsteady-cylinder checkpoint");
      if (r.getString() != fingerprint) throw std::runtime_error("it belongs to another version of this case");
      first_level = r.get<std::uint64_t>();
      ladder = nlohmann::json::parse(r.getString());
      resumed_wall = r.get<double>();
      if (first_level >= levels.size() || ladder.size() != first_level) throw std::runtime_error("its level does not fit the ladder");
      resumed.emplace(std::move(r));
      for (std::size_t k = 0; k < first_level; ++k) out.files.push_back(fmt::format("forces-level{}.csv", k));  // written before the stop
    } catch (const std::exception& e) {
      throw cannotResume(e);
    }
  }
  // A row's value is its c_D max; its error is against the case's first single-value reference on it.
  const Acceptance* reference = pointReference(c, "c_D_max");
  for (std::size_t li = first_level; li < levels.size(); ++li) {
    const auto t0 = std::chrono::steady_clock::now();
    const double cpu0 = processCpuSeconds();
    UnsteadyFlowSolver solver(make_problem(levels[li]), solverOptions(c), uo);
    ForceHistory hist;
    double wall_before = 0;  // this level's wall time before a resume
    if (resumed) {
      try {
        solver.loadState(*resumed);
        const auto t = resumed->getVector<double>(), cd = resumed->getVector<double>(), cl = resumed->getVector<double>();
        if (cd.size() != t.size() || cl.size() != t.size()) throw std::runtime_error("force history of unequal columns");
        for (std::size_t k = 0; k < t.size(); ++k) hist.add(t[k], cd[k], cl[k]);
      } catch (const std::exception& e) {
        throw cannotResume(e);
      }
      resumed.reset();
      wall_before = resumed_wall;
      resumed_from = solver.stepStats().steps;
      if (PetscSession::rank() == 0 && !ctx.quiet)
        spdlog::info("{}: resumed level {} at t = {:.6g} s (step {}) from {}", c.name(), li + 1, solver.time(), solver.stepStats().steps, ckpt.string());
    } else if (eps > 0) {
      const auto vortex = startVortex(cx, cy, D, eps, Uref);  // peak speed eps U / 2
      solver.setVelocity([=](double x, double y) {
        const auto u = vortex.velocity(x, y);
        return Eigen::Vector2d(u[0], u[1]);
      });
    }
    auto saveCheckpoint = [&] {
      if (PetscSession::rank() != 0) return;
      CheckpointWriter w;
      w.putString(kCheckpointFormat);
      w.putString(fingerprint);
      w.put<std::uint64_t>(li);
      w.putString(ladder.dump());
      w.put(wall_before + secondsSince(t0));
      solver.saveState(w);
      w.putVector(hist.times());
      w.putVector(hist.drag());
      w.putVector(hist.lift());
      writeFileAtomic(ckpt, w.bytes());
    };
    // Snapshots of the finest level (output.snapshots): the first state at or after each
    // k end_time / n. A resumed level continues from the next one still due.
    const bool final_level = li + 1 == levels.size();
    const long long snapshots = ctx.out_dir.empty() || !final_level ? 0 : c.integer("output.snapshots");
    long long next_snapshot = 1;
    while (snapshots >= 2 && next_snapshot <= snapshots && solver.time() >= end_time * next_snapshot / snapshots * (1 - 1e-12)) ++next_snapshot;
    auto last_checkpoint = std::chrono::steady_clock::now();
    Progress progress(fmt::format("fluid {} (level {}/{})", c.name(), li + 1, levels.size()), 1000, ctx.quiet);
    while (solver.time() < end_time * (1 - 1e-12)) {
      // numerics.time_step is the first step; later steps grow (<= max_growth per step) up to the Courant limit.
      const double request = solver.stepStats().steps == 0 ? dt0 : end_time - solver.time();
      try {
        solver.step(std::min(request, end_time - solver.time()));
      } catch (const FlowFailure& e) {
        throw e.withKey(resolution_key);  // the grid and the Courant limit are the user's to change
      }
      const BodyLoad L = solver.bodyLoads()[0];
      hist.add(solver.time(), coef * L.force.x(), coef * L.force.y());
      progress.update(static_cast<std::size_t>(1000 * solver.time() / end_time));
      if (snapshots >= 2 && next_snapshot <= snapshots && solver.time() >= end_time * next_snapshot / snapshots * (1 - 1e-12)) {
        if (PetscSession::rank() == 0) writeVtr(solver, ctx.out_dir / snapshotName(next_snapshot));
        ++next_snapshot;
      }
      if (ckpt.empty() || solver.time() >= end_time * (1 - 1e-12)) continue;
      const bool stop = stop_after > 0 && resumed_from == 0 && solver.stepStats().steps == stop_after;
      if (stop || (checkpoint_s > 0 && secondsSince(last_checkpoint) >= checkpoint_s)) {
        saveCheckpoint();
        last_checkpoint = std::chrono::steady_clock::now();
      }
      if (stop)
        throw RunStopped(fmt::format("stopped after {} time steps as asked (run.stop_after_steps); {} holds the checkpoint, continue with `mmval run --resume`",
                                     stop_after, ckpt.string()));
    }
    progress.finish();
    const SheddingStats st = hist.analyse(from, 4);
    last_stats = st;
    const double wall = wall_before + secondsSince(t0);
    const FlowStats& fs = solver.stats();
    nlohmann::json row = {{"level", li},
                          {"resolution", levels[li]},
                          {"cells", fs.cells},
                          {"nx", solver.nx()},
                          {"ny", solver.ny()},
                          {"unknowns", fs.unknowns},
                          {"h_over_D", M_PI / levels[li]},
                          {"time_steps", solver.stepStats().steps},
                          {"max_courant", solver.stepStats().max_courant},
                          {"wall_seconds", wall},
                          {"assemble_seconds", fs.assemble_seconds},
                          {"solve_seconds", fs.solve_seconds},
                          {"linear_iterations", fs.linear_iterations},
                          {"velocity_seconds", solver.stepStats().velocity_seconds},
                          {"pressure_seconds", solver.stepStats().pressure_seconds},
                          {"velocity_iterations", solver.stepStats().velocity_iterations},
                          {"pressure_iterations", solver.stepStats().pressure_iterations},
                          {"peak_memory_bytes", peakMemoryBytes()},
                          {"ranks", PetscSession::size()},
                          {"shedding_periods", st.periods},
                          {"St", st.frequency_hz * D / Uref},
                          {"c_D_max", st.cd_max},
                          {"c_D_mean", st.cd_mean},
                          {"c_L_max", st.cl_max},
                          {"c_L_amplitude_drift", st.cl_amplitude_drift},
                          {"value", st.cd_max}};
    if (resumed_from == 0 || li != first_level) row["cpu_seconds"] = processCpuSeconds() - cpu0;  // rank 0's; none for a level resumed part-way
    if (reference != nullptr) row["error"] = (st.cd_max - reference->reference.value) / reference->reference.value;
    ladder.push_back(row);
    if (!ctx.out_dir.empty()) {
      const std::string name = final_level ? "forces.csv" : fmt::format("forces-level{}.csv", li);
      if (PetscSession::rank() == 0) {
        hist.writeCsv(ctx.out_dir / name);
        if (final_level) {  // the flow at the end time
          writeVtr(solver, ctx.out_dir / "fields.vtr");
          writeSpeedPng(solver, ctx.out_dir / "fields-speed.png");
        }
      }
      out.files.push_back(name);
      if (final_level) {
        out.files.push_back("fields.vtr");
        out.files.push_back("fields-speed.png");
        if (snapshots >= 2) {
          writeSnapshotSeries(ctx.out_dir, snapshots);
          out.files.push_back("fields.pvd");  // stands for its snapshots (the report lists files one by one)
        }
      }
    }
    out.details["cells"] = fs.cells;
    out.details["time_steps"] = solver.stepStats().steps;
    out.details["max_relative_divergence"] = solver.maxRelativeDivergence();
  }
  if (!ckpt.empty() && PetscSession::rank() == 0) std::filesystem::remove(ckpt);  // complete: the results replace it
  addObservedOrder(ladder, levels);
  out.details["ladder"] = ladder;
  out.details["resumed_from_step"] = resumed_from;
  out.details["statistics_window_s"] = {last_stats.window_start_s, last_stats.window_end_s};
  out.details["shedding_periods"] = last_stats.periods;
  std::string warning;
  if (last_stats.periods == 0) warning = "no periodic shedding detected in the statistics window: St is 0 and the extrema are over the whole window";
  out.metrics["c_D_max"] = last_stats.cd_max;
  out.metrics["c_D_min"] = last_stats.cd_min;
  out.metrics["c_D_mean"] = last_stats.cd_mean;
  out.metrics["c_L_max"] = last_stats.cl_max;
  out.metrics["c_L_min"] = last_stats.cl_min;
  out.metrics["c_L_amplitude"] = last_stats.cl_amplitude;
  out.metrics["c_L_amplitude_drift"] = last_stats.cl_amplitude_drift;
  // The start-up approaches the periodic state geometrically (2D-2: the c_L amplitude grew 0.3 % in
  // the period before 4.5 s and 0.7 % in all after it): extrema read before then are too small.
  if (last_stats.periods >= 2 && std::abs(last_stats.cl_amplitude_drift) > 2e-3)
    warning = fmt::format("the shedding has not reached its periodic state: the c_L amplitude changed {:+.2f} % over the last period; "
                                         "run longer (numerics.end_time) and start the statistics later (numerics.statistics_from)",
                          100 * last_stats.cl_amplitude_drift);
  if (!warning.empty()) {
    setDetail(out.details, DetailField::warnings, nlohmann::json::array({warning}));
    if (PetscSession::rank() == 0) spdlog::warn("{}: {}", c.name(), warning);
  }
  out.metrics["St"] = last_stats.frequency_hz * D / Uref;
  out.metrics["frequency"] = last_stats.frequency_hz;
  out.units["frequency"] = "Hz";
  return out;
}

}  // namespace mmval::simulate::detail
