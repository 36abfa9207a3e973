// The stages of a particles-micromodel run (Micromodel.hpp), each a function
// whose inputs and outputs are its arguments:
//
//   readSetup, readCouplingAndSchedule
//                 the case read once: geometry, size classes, flow, engine
//                 choice, coupling, injection schedule, run control
//   transport     every size class's engine advanced to the frame's time
//   deposit       deposits since the last frame added to the deposit grid
//   resolve       the flow solved again once enough aperture was lost; the pump's verdict
//   insertDue     the particles the schedule calls for placed in the inlet strip
//   recordFrame   the frame's trajectory rows, speeds, retention and permeability lines
//
// runMicromodel (Micromodel.cpp) loops transport -> deposit -> resolve ->
// insertDue -> recordFrame over the output frames, then checkpoints and writes
// the outputs. The order within a frame is part of the results (the random
// streams and the checkpoints depend on it).
#pragma once
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/particles/DepositGrid.hpp"
#include "mmval/particles/MicromodelBookkeeping.hpp"
#include "mmval/particles/MicromodelFlow.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
#include "mmval/particles/SceneSelection.hpp"

namespace mmval::particles::stages {

/// One trajectory row, POD so that checkpoints hold it as raw bytes.
struct TrajRow {
  std::int64_t frame, particle;
  double t, x_px, y_px, z;
  std::uint8_t deposited;
};
/// A mobile particle's position at the last frame (for its speed).
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
/// Bits of SizeClass::accounted.
constexpr std::uint8_t kVolumeBooked = 1, kRowWritten = 2;

/// Everything of the runner that a checkpoint must carry besides the engines and the deposits.
struct RunnerState {
  std::int64_t next_frame = 0, next_id = 1, resolves = 0, steps_at_checkpoint = 0;
  std::int64_t resolves_pattern_kept = 0;  ///< re-solves that were a numeric refactorisation in the kept pattern
  std::int64_t wall_deposits = 0, plate_deposits = 0;  ///< deposits booked as columns (at a grain) / as plate layers
  double lost_at_solve = 0;  ///< DepositGrid::lostColumns() at the last solve
  double blocked_at = -1;    ///< s: first re-solve that found no flow path (-1: never)
  double k = 0, k0 = 0, speed_sum = 0, solve_seconds = 0, wall_before = 0;
  double pressure_drop = 0;  ///< Pa at the last solve (FlowSolveResult::pressure_drop; +inf when blocked)
  std::int64_t speed_n = 0;
  std::vector<TrajRow> rows;
  std::vector<LastPos> last;  ///< sorted by id
  std::string retention, permeability;
};

/// The pore geometry as the run uses it.
struct SceneGeometry {
  PixelMask grains;            ///< solid pixels, isolated pores closed
  double porosity = 0;         ///< connected porosity
  double pixel = 0, depth = 0; ///< m
  double width = 0, height = 0;  ///< m: along the flow (x) and across it (y)
  std::int64_t pore_pixels = 0;
};

/// Four-way coupling: how deposits feed back on the flow.
struct Coupling {
  bool four_way = true;    ///< false: the flow never changes
  bool layers = true;      ///< plate deposits thin the aperture (else they fill columns like those at grains)
  double weight = 1;       ///< real particles per simulated one in the deposit volume
  double fill_fraction = 0.5;
  DepositLayerModel layer_model;
  std::int64_t resolve_pixels = 1;  ///< aperture lost since the last solve, in whole pixel columns, that triggers a re-solve
};

/// The injection schedule and where particles enter.
struct Schedule {
  double rate_per_s = 0;      ///< simulated particles per second, all classes
  double injection_time = 0;  ///< s: particles enter during [0, injection_time]
  double strip = 0;           ///< m: inlet strip the flow fills in one output interval
  double max_strip = 0;       ///< m: the strip never reaches beyond this
  std::uint64_t seed = 0;     ///< run.seed
};

/// Output frames, checkpoints and the retention window.
struct RunControl {
  double dt_out = 1;              ///< s between output frames
  std::int64_t frames = 0;        ///< last output frame (frame 0 is t = 0)
  std::int64_t checkpoint_every = 0, stop_after = 0;
  std::vector<double> window;     ///< s: [from, to] of analysis.retention_window; empty: none
};

/// The scene read from the case, once, before anything runs. Bad input is an
/// InputError naming the key, raised in the order the keys are read.
struct MicromodelSetup {
  SceneGeometry geo;
  std::vector<SizeClass> classes;  ///< without engines yet (makeEngines)
  double d_max = 0;                ///< m: the largest class's diameter
  MicromodelFlowOptions flow;
  double max_pressure = 0;         ///< Pa: the syringe pump's limit (0: none)
  EngineChoice choice;
  SceneConfig scene;               ///< shared by every class (diameter and seed set per class)
  std::uint64_t seed = 0;          ///< run.seed
  // Read by readCouplingAndSchedule:
  double sample = 1;               ///< particles.sample_fraction
  Coupling coupling;
  Schedule schedule;
  RunControl run;
};

/// Reads and checks the scene's keys (geometry, size classes, flow, engine
/// choice, engine settings); fills the geometry's details in `out`.
MicromodelSetup readSetup(const Case& c, RunOutput& out);
/// Reads and checks the rest (coupling, run control, injection schedule) into
/// `set`. Called after the engines are made, so that bad input is reported in
/// the order the run meets it.
void readCouplingAndSchedule(const Case& c, MicromodelSetup& set);
/// One overdamped engine per size class on `field`, class i seeded seed + 7919 i.
void makeEngines(std::vector<SizeClass>& classes, const std::shared_ptr<const FlowField>& field, const SceneConfig& scene,
                 std::uint64_t seed);

/// Particles of every class after the last stage that moved them.
using ClassParticles = std::vector<std::vector<ParticleState>>;

/// Transport: every class's engine advanced to time `t` (frame `k`; frame 0 is
/// not advanced); returns each class's particles.
ClassParticles transport(std::vector<SizeClass>& classes, std::int64_t k, double t);

/// Deposition: every particle that deposited since the last frame adds its
/// (parcel) volume to `deposits`: at a grain (in-plane gap to `field`'s walls
/// below one diameter: touching it, within the pixel staircase's resolution) it
/// fills columns, elsewhere it lies on a plate and thins the aperture by up to a
/// monolayer per pixel (layer mode). Counts it in `at_walls` or `on_plates` and
/// marks it kVolumeBooked.
void deposit(std::vector<SizeClass>& classes, const ClassParticles& ps, const FlowField& field, const Coupling& coupling,
             DepositGrid& deposits, std::int64_t& at_walls, std::int64_t& on_plates);

/// What a re-solve changes in the runner's state.
struct FlowRecord {
  std::int64_t& resolves;
  std::int64_t& resolves_pattern_kept;
  double& solve_seconds;
  double& lost_at_solve;
  double& k;
  double& pressure_drop;
  double& blocked_at;
};

/// Re-solve: once the aperture lost since the last solve reaches
/// coupling.resolve_pixels columns, the flow is solved with the closed pixels
/// and apertures of `deposits`, particles now inside closed pixels are captured
/// there (`ps` refreshed), `record` updated. Returns the pump's verdict on that
/// solve at time `t` (nothing when no solve was due).
std::optional<PumpStall> resolve(MicromodelFlow& flow, const DepositGrid& deposits, const Coupling& coupling, double max_pressure,
                                 double t, std::vector<SizeClass>& classes, ClassParticles& ps, FlowRecord record);

/// Seed strides of the inlet sampling: per output frame k, per size class, per
/// retry of one particle when the strip is full (primes, so streams do not repeat).
constexpr std::uint64_t kFrameSeedStride = 1000003ULL, kClassSeedStride = 7919ULL, kRetrySeedStride = 104729ULL;

/// Insertion: each class's particles due by `t` (frame `k`) placed in the inlet
/// strip; when the strip cannot take them all, as many as fit one by one and the
/// rest deferred (SizeClass::deferred) to the next frame. New particles get
/// output ids from `next_id` on; `ps` refreshed.
void insertDue(std::vector<SizeClass>& classes, const FlowField& field, const Schedule& schedule, std::int64_t k, double t,
               ClassParticles& ps, std::int64_t& next_id);

/// Image frame of the trajectories: pixel size and image height (m).
struct ImageFrame {
  double pixel = 0, height = 0;
};

/// Frame record: for frame `k` at `t`, one row per particle still in the chip
/// (a deposited particle only in the first frame after it deposited), mobile
/// particles' in-plane speeds since the last frame (`dt_out` apart) summed, and
/// one line each of retention.csv and permeability.csv (mmval/core/OutputTables.hpp).
/// std::logic_error when the counts do not balance. Returns the frame's counts.
Counts recordFrame(std::vector<SizeClass>& classes, const ClassParticles& ps, std::int64_t k, double t, const ImageFrame& image,
                   double dt_out, RunnerState& s);

}  // namespace mmval::particles::stages
