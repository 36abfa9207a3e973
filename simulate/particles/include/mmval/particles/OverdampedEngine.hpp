// The overdamped colloid engine (ours): for Stokes numbers << 1 a particle's
// inertia relaxes in tau_p (~1.5 us for 5 um polystyrene), far below any time
// that matters, so its velocity is the force balance
//   v = u_f(x, z) + u_lag(x, z) + M(z) F + Brownian,    (Ermak & McCammon 1978)
//   u_f = u_mean(x, y) [6 z (h - z) / h^2 - 2 a^2 / h^2]  (depth profile + Faxen's a^2/6 lap u)
//   u_lag: a free sphere's lag behind the shear near each plate (Goldman, Cox &
//          Brenner 1967; HydroModel::shearLag, the plates superposed)
//   M = diag(1/lambda_par, 1/lambda_par, 1/lambda_perp) / (6 pi mu a)
//       (Goldman-Cox-Brenner joined to Faxen for a sphere free to rotate, Brenner; two plates)
//   F = gravity - buoyancy along -z + the attraction to sticky surfaces (HydroModel::surfaceAttraction:
//       van der Waals under the capture rule, the attachment's own DLVO force under the dlvo rule)
//   dx_B = sqrt(2 D dt) xi with D = k_B T M, plus the drift k_B T dM/dz (Ito; SceneConfig::ito_drift,
//   off only in checks that show what leaving it out does).
//   Only M_zz depends on z in a way the drift sees (M_xx depends on z, not x), so the
//   drift is k_B T d(1/lambda_perp)/dz / (6 pi mu a) alone, unchanged by the parallel model.
// Contacts are hard: after each step overlaps with other particles, the plates
// and grains are removed by moving particles apart along the line of centres
// (Heyes & Melrose 1993, J. Non-Newtonian Fluid Mech. 46:1), so no contact
// stiffness limits the step. The step is chosen so that no particle moves more
// than `max_step_fraction` radii (flow, forces and Brownian rms), not by tau_p.
// A move that leaves a particle closer than a radius to a grain after three
// pushes along the wall normal (and one slide along the last wall when two walls
// close in at an angle) is refused: particles never squeeze through a throat
// narrower than themselves, to the wall distance's accuracy (kWallTolerance).
// Straining (SceneConfig::straining): a particle pinned there by its drift (its
// move refused, or pushed off two walls that close in ahead of it; on smooth grain walls two
// push normals within kSmoothWallOneWallDeg are one wall, not two) for the set
// time is deposited with Surface::strained. So is one held there by deposits (strained or
// attached particles) and walls together: a cake building upstream of a blocked throat.
// "There" is within max(anchor_fraction, max_step_fraction) radii of where it was first held
// (a deposit's push does not return it the way it came). An overlap with deposits the contact
// sweeps leave (a particle stacked over or under one in a throat, its push along z stopped by a
// plate) is removed by moving it back against its drift (backOutOfDeposits); a held particle
// that still overlaps one after the straining time is strained where it is.
// Attachment is decided after the contacts of the step are resolved, so that a
// particle never attaches overlapping a deposit: a particle whose gap to a sticky
// surface falls below the capture distance, that would have penetrated it, or that
// touched a deposit is an arrival. capture rule: it deposits and stays; on the
// plates optionally only when the adhesive torque holds against the shear's
// (AttachmentModel::torque_balance, HydroModel::plateAdhesionHolds). dlvo rule: the
// DLVO profile of the surface type decides (AttachmentModel::Rule, SurfaceChemistry), one draw
// per arrival, and a rejected particle arrives again at that surface only after leaving it to
// beyond the release distance (AttachmentModel::release_distance);
// a particle caught in a secondary minimum stays only while the well's pull-off force
// holds against the local shear's torque, at plates, grain walls and deposits alike
// (HydroModel::plateAdhesionHolds, surfaceAdhesionHolds): in flowing fluid it is carried
// on along the surface in the well, checked again every step, and held where the shear
// falls low enough (Torkzaban, Bradford & Walker 2007, Langmuir 23:9652: secondary-minimum
// colloids translate to low-velocity regions); it leaves the well when it leaves the
// surface's capture distance. While it translates it is mobile with secondary = true and
// held_by = the surface of the well.
// Charge heterogeneity of the glass (AttachmentModel::favourable_fraction): per arrival by
// default; with AttachmentModel::patch_size > 0 a fixed map of favourable cells
// (FavourablePatchMap) is read at the contact point every step a particle is within the capture
// distance of a plate or grain wall, and a favourable cell attaches it in the primary minimum.
// A particle that would attach still overlapping a deposit (a push undone at a
// grain) stays mobile for this step.
// Threads (SceneConfig::threads): the drift of each mobile particle and its move with the wall
// step are independent of the other particles', so a step computes them on several threads, each
// with its own memo of flow queries and scratch over the same flow; the step's normal draws are
// taken first, in mobile order, as one thread takes them. Results are bit for bit one thread's
// for any thread count. After the contact sweeps, which stay on one thread (a push moves the
// particles the next pair sees), each particle's undo of a push into a grain, its back-out of
// deposits, attachment and straining clock are again independent of the others' (they read the
// flow, the particle and deposits of earlier steps) and run on the threads; only the check that a
// new deposit does not overlap one made earlier in the same step goes in mobile order on one thread.
// Substeps (SceneConfig::substeps = K > 1): the step one particle's limit sets for all (the fastest,
// in a throat, ~10x the median's speed on the paper's strip) is most particles' waste. The engine's
// step is then up to K times the fastest one's, and each particle takes the number (up to K) of
// steps of its own within it that its own limit asks (ownStep): drift again at each substep's
// start, Brownian draws 3 per substep (taken first, in mobile order), the wall step after each. A
// particle goes on through its substeps at the walls (it slides, or is refused and tries again: the
// straining clock's "held" is the last substep's, as with one step for all; its touches of any
// substep are the step's arrivals) and stops short of the step's end only where it left or came
// nearer than a diameter to a deposit or to the place another mobile particle is predicted at (its place before the step
// plus its drift times the time; a held particle's place stays): no substep passes through another
// particle; the contact sweeps, attachment and straining then run once per engine step, as before.
// K = 1 is the single step for all, bit for bit.
// Not modelled: the wall correction of the lag for the parabola's curvature (the
// lag is that of the wall's linear shear), in-plane hindrance by grains,
// hydrodynamic interactions between particles, re-entrainment.
#pragma once
#include <array>
#include <functional>
#include <memory>
#include <unordered_map>

#include "mmval/core/Checkpoint.hpp"
#include "mmval/particles/HydroModel.hpp"
#include "mmval/particles/Scene.hpp"

namespace mmval::particles {

/// Attachment of one surface type under the dlvo rule, computed once per engine from
/// the chemistry (Dlvo.hpp): the profile's features, the IFBL efficiency alpha of
/// primary-minimum attachment, and the secondary minimum's capture probability
/// (Maxwell fraction, 0 unless the well is deeper than 1 kT) and holding force.
struct SurfaceChemistry {
  DlvoParameters parameters;
  DlvoProfileFeatures profile;
  DlvoAttachment attachment;
  double alpha = 0;                ///< primary-minimum attachment per arrival
  double secondary_capture = 0;    ///< probability of capture in the secondary minimum, given no primary attachment
  double secondary_force = 0;      ///< N, largest attraction beyond the secondary minimum (pull-off force of a held particle)
  nlohmann::json describe() const;
};

class OverdampedEngine final : public ParticleEngine {
 public:
  /// Smooth grain walls (GriddedFlow::setSmoothWalls): two push normals of the walls count as
  /// two walls in the held tests (kPinned, heldByDeposits) only if they are more than this many
  /// degrees apart; closer, they are one wall seen at two points of its polyline contour, whose
  /// adjacent segments kink by 2-21 degrees on the paper strip (the smoothed level's ripple;
  /// docs/validation/paper-scenes.md) and whose normal strays up to 26 degrees from a rasterised
  /// disc's (SmoothWallsTest, bound 30). A real hold on such walls is two grains (or a grain and a
  /// closed pixel or side wall) meeting at more than this: a 5 um sphere in a gap narrower than
  /// itself between discs of radius R touches both with normals at least 2 acos(R / (R + a)) apart
  /// (74 degrees at R = 4 a; 30 degrees only at R = 28 a). Exact walls (pixel edges, where a
  /// staircase notch's 65-90 degrees is the rendered geometry; analytic fields) keep every pair.
  static constexpr double kSmoothWallOneWallDeg = 30.0;
  OverdampedEngine(std::shared_ptr<const FlowField> flow, SceneConfig config);
  ~OverdampedEngine() override;
  OverdampedEngine(const OverdampedEngine&) = delete;
  OverdampedEngine& operator=(const OverdampedEngine&) = delete;

  std::string name() const override { return "overdamped"; }
  void insert(const std::vector<Vec3>& positions) override;
  void advance(double t_end) override;
  double time() const override { return m_t; }
  std::vector<ParticleState> particles() const override { return m_particles; }
  Counts counts() const override { return countParticles(m_particles); }
  EngineStats stats() const override { return m_stats; }
  nlohmann::json describe() const override;

  /// Deterministic velocity (flow + M F + Ito drift) of a particle at x, m/s. For tests.
  Vec3 driftVelocity(const Vec3& x) const;
  const HydroModel& model() const { return m_model; }
  /// Threads the per-particle loops run on (SceneConfig::threads resolved; 0 there: auto).
  int threads() const { return m_threads; }
  /// Fewer mobile particles than this: a step's loops run on one thread (the hand-over costs more).
  static constexpr std::size_t kMinParallelMobile = 48;
  static constexpr int kMaxThreads = 64;  ///< numerics.threads' largest value
  /// dlvo rule: the attachment of plates (and grains: the chip's material) or deposits
  /// (Surface::bottom, top and grain share one); nullptr under the capture rule.
  const SurfaceChemistry* chemistry(Surface s) const;
  /// dlvo rule with chemistry.patch_size > 0 and favourable_fraction > 0: the contact point of a
  /// particle centred at x with glass surface s (plates: (x, y); grain walls: the nearest wall
  /// point at the centre's height) lies on a favourable cell of the map (FavourablePatchMap).
  /// false otherwise (deposits, the per-arrival model).
  bool favourablePatchAt(Surface s, const Vec3& x) const;

  /// After the flow field changed (deposits turned cells solid): mobile
  /// particles now inside solid are deposited there (they are part of the
  /// deposit that closed the cell). Returns how many.
  std::int64_t captureInSolid();
  /// Everything that determines the future of the run (time, particles,
  /// statistics, the random generator's state), for checkpoints: a run
  /// restored with loadState() continues bit for bit like the original.
  void saveState(CheckpointWriter& w) const;
  /// Throws std::runtime_error when the data do not fit this engine.
  void loadState(CheckpointReader& r);

 private:
  void step(double dt);
  /// Surfaces a particle touched in a step (bits of m_touch).
  /// kPinned: the walls held it against its drift (a refused move, or two walls closing in ahead).
  enum Touch : std::uint8_t { kGrain = 1, kBottom = 2, kTop = 4, kDeposit = 8, kPinned = 16 };
  /// The contact sweeps (one thread): every overlap pushed apart, the plates' clamp after each
  /// sweep; m_start keeps the positions before them. The rest of the contact step is per particle
  /// (afterContacts).
  void resolveContacts();
  /// What one thread of a step's per-particle loops reads the flow through and writes scratch to.
  struct Worker;
  class Pool;
  /// Runs body(k, worker) for k in [0, n) over the workers (worker 0 on the calling thread).
  void forEachMobile(std::size_t n, const std::function<void(std::size_t, Worker&)>& body);
  /// Per particle after the contact sweeps (any thread, `w` its worker): a push that carried the
  /// particle into a grain or a throat narrower than itself undone in the plane (k: its place in
  /// m_mobile), its back-out of deposits (straining), the mirror planes.
  void afterContacts(std::size_t k, Worker& w);
  /// Grains, side walls, outlet and plates: pushes the particle back into the fluid and
  /// returns the Touch bits of the surfaces it hit (or marks it left). `flow` and `normals`: the
  /// calling thread's (Worker).
  std::uint8_t applyWalls(ParticleState& p, const Vec3& before, const FlowField& flow, std::vector<Vec2>& normals) const;
  /// SceneConfig::mirror_sides: a particle beyond the field's y0 or y1 reflected back across it.
  void reflectAtMirrors(ParticleState& p) const;
  /// Two walls closer than a radius: from p (a radius from the wall of normal `last`), the slide
  /// along that wall that puts it a radius from the other as well; p moved and true when the slid
  /// position (and the way there from `before`) keeps a radius from every wall.
  bool slideBetweenWalls(ParticleState& p, const Vec3& before, const Vec2& last, std::vector<Vec2>& normals, const FlowField& flow) const;
  /// Straining: the pinned particle's clock (StrainingModel); deposits it as strained at time t.
  void updateStraining(ParticleState& p, bool pinned, double t) const;
  /// Straining at deposits: after the contact sweeps, the drift of mobile particle i is held by
  /// the contact normals of the deposits it touched in this step and of a wall within one step's
  /// travel (the cone test of the walls' kPinned: two normals whose cone holds -drift; one
  /// deposit head-on is not a hold, the particle slides round it), with the drift beating
  /// diffusion over a radius. Deposit normals are taken in the plane: a particle that can ride
  /// over or under the deposit in z moves on and leaves the straining anchor. Where it cannot (a
  /// plate or a deposit closes z) this is the three-dimensional test: -u = sum l_k n_k with l_k > 0
  /// over three independent 3D normals, one of them a plate's (no in-plane part), leaves -u_xy a
  /// positive sum of the other two normals' in-plane parts, which is this cone (a stacked deposit's
  /// in-plane part has the direction of the offset, whatever its length). A 3D cone test added to
  /// it changed no bit of the paper strip's 240 s run (2026-12-05, issue 26), so there is none.
  bool heldByDeposits(const ParticleState& p, int i, Worker& w) const;
  /// The dot product above which two wall normals of the held tests are one wall: cos of
  /// kSmoothWallOneWallDeg on smooth grain walls, 2 (never) on exact walls.
  double oneWallCos() const;
  /// Straining only: a mobile particle the contact sweeps left overlapping deposits (stacked over
  /// or under one, its push stopped by a plate and undone by the walls) is moved back against its
  /// in-plane drift by the least distance that clears them, where it fits.
  void backOutOfDeposits(ParticleState& p, Worker& w) const;
  /// After contacts: attaches a particle that arrived at a sticky surface (either rule). Reads the
  /// flow and the model through worker `w`; writes p only.
  void decideAttachment(ParticleState& p, std::uint8_t touched, const Worker& w);
  /// dlvo rule: one draw for an arrival on surface `s`; true when the particle attaches. A
  /// particle caught in the secondary minimum but not held is marked as translating in that
  /// well (secondary = true, held_by = s, still mobile).
  bool dlvoArrival(ParticleState& p, Surface s, const SurfaceChemistry& sc, const HydroModel& model);
  /// dlvo rule: the gap (m) a rejected particle must exceed before its next arrival at the same
  /// surface draws (AttachmentModel::release_distance; < 0 there: one radius).
  double releaseDistance() const;
  /// dlvo rule: p is farther than `release` from surface s (deposits: from every indexed deposit).
  bool beyondRelease(const ParticleState& p, Surface s, double release, const FlowField& flow) const;
  /// dlvo rule: the secondary minimum of `s` holds p against the local shear's torque.
  bool secondaryHolds(const ParticleState& p, Surface s, const SurfaceChemistry& sc, const HydroModel& model) const;
  /// favourablePatchAt with the flow of the calling thread.
  bool favourablePatchAt(Surface s, const Vec3& x, const FlowField& flow) const;
  bool overlapsDeposit(const ParticleState& p, const std::vector<int>& fresh) const;
  /// Uniform [0, 1) draw of a particle's n-th plate arrival (plate attachment efficiency).
  double arrivalDraw(std::int64_t id, std::uint32_t arrival) const;
  /// The step mobile particle k (its place in m_mobile) may take at drift v: max_step_fraction
  /// radii of travel, of the gap to the plate it approaches, and of Brownian rms, and max_dt.
  double ownStep(std::size_t k, const Vec3& v) const;
  /// Substeps: mobile particle k, moved from `from` to p.x in the substep from tau_from to tau
  /// into the engine's step, came nearer than a diameter to a deposit or to another mobile
  /// particle's place predicted then (its place before the step, m_snapshot, plus its drift times
  /// the time; a particle whose straining clock runs, held by walls or deposits, stays there),
  /// and nearer than at the substep's start.
  bool meetsNeighbour(const ParticleState& p, std::size_t k, const Vec3& from, double tau_from, double tau, const std::vector<Vec3>& drift) const;
  std::int64_t cellKey(const Vec3& x) const;
  /// The key of contact column (ix, iy) (cellKey's columns).
  static std::int64_t columnKey(std::int64_t ix, std::int64_t iy) { return (ix * 73856093) ^ (iy * 19349663); }
  /// Visits the deposited particles (indices) of the contact columns within `reach` of x's (x, y)
  /// (m_dep_cells), until `visit` returns true; returns whether it did.
  template <class Visit>
  bool anyDepositNear(const Vec3& x, double reach, Visit&& visit) const {
    const double cs = 4 * m_radius;
    const auto x0 = static_cast<std::int64_t>(std::floor((x.x() - reach) / cs)), x1 = static_cast<std::int64_t>(std::floor((x.x() + reach) / cs));
    const auto y0 = static_cast<std::int64_t>(std::floor((x.y() - reach) / cs)), y1 = static_cast<std::int64_t>(std::floor((x.y() + reach) / cs));
    for (auto ix = x0; ix <= x1; ++ix)
      for (auto iy = y0; iy <= y1; ++iy)
        if (const std::int64_t key = columnKey(ix, iy); m_dep_filter.mayHold(key))
          if (const auto it = m_dep_cells.find(key); it != m_dep_cells.end())
            for (const int j : it->second)
              if (visit(j)) return true;
    return false;
  }
  /// A filter of contact-column keys, a bit per key's low bits: mayHold is false only for a key never
  /// added, so that the many empty columns skip the look-up behind it.
  template <std::size_t Bits>
  struct KeyFilter {
    std::array<std::uint64_t, Bits / 64> words{};
    static std::size_t bit(std::int64_t key) { return static_cast<std::size_t>(key) & (Bits - 1); }
    void add(std::int64_t key) { words[bit(key) / 64] |= std::uint64_t{1} << (bit(key) % 64); }
    bool mayHold(std::int64_t key) const { return (words[bit(key) / 64] >> (bit(key) % 64)) & 1u; }
  };
  /// m_dep_cells' keys (set by indexDeposited).
  KeyFilter<(1u << 14)> m_dep_filter;
  void indexDeposited(int i);
  void compactMobile(double t_event);

  std::shared_ptr<const FlowField> m_flow;
  const GriddedFlow* m_grid = nullptr;  ///< the field behind m_flow's memo when it is a GriddedFlow (oneWallCos)
  SceneConfig m_cfg;
  HydroModel m_model;
  double m_radius, m_outlet;
  std::vector<ParticleState> m_particles;
  std::vector<int> m_mobile;  ///< indices of mobile particles, ascending
  std::unordered_map<std::int64_t, std::vector<int>> m_dep_cells;  ///< deposited particles by contact cell
  std::vector<std::uint8_t> m_touch;  ///< Touch bits of this step, by particle index
  /// By particle index: the plates' clamp of resolveContacts may change it (moved by a push in
  /// this sweep, or left by the wall step where the clamp does not hold: depth below a diameter).
  /// The clamp leaves every other particle's z as it is, so it visits only these.
  std::vector<std::uint8_t> m_clamp;
  std::vector<Vec3> m_start;  ///< positions before the contact sweeps, indexed like m_mobile
  /// (mobile, deposited) pairs pushed apart in this step's contact sweeps, sorted after them (straining only)
  std::vector<std::pair<int, int>> m_deposit_contacts;
  std::unique_ptr<SurfaceChemistry> m_plate_chem, m_deposit_chem;  ///< dlvo rule only
  FavourablePatchMap m_patches;  ///< dlvo rule, patches placed in space; size 0: none (per-arrival model)
  std::vector<int> m_dep_order;  ///< deposited particles in the order they were indexed (restores m_dep_cells exactly)
  double m_t = 0.0;
  EngineStats m_stats;
  struct Rng;
  std::unique_ptr<Rng> m_rng;
  int m_threads = 1;
  std::vector<std::unique_ptr<Worker>> m_workers;  ///< one per thread; [0]: the calling thread's (m_flow, m_model)
  std::unique_ptr<Pool> m_pool;                    ///< threads 1.. of the loops (none with one thread)
  std::vector<double> m_draws;                     ///< a step's normal draws, 3 per substep of each mobile particle in mobile order
  std::vector<double> m_own;                       ///< a step's own step of each mobile particle (ownStep)
  std::vector<int> m_substeps;                     ///< a step's substeps per mobile particle (taken, after the moves)
  std::vector<std::size_t> m_draw_offset;          ///< a step's first draw of each mobile particle
  /// Substeps: the mobile particles' places before the step, and (contact column, place in m_mobile)
  /// pairs sorted, for meetsNeighbour.
  std::vector<Vec3> m_snapshot;
  std::vector<std::pair<std::int64_t, int>> m_snapshot_cells;
};

}  // namespace mmval::particles
