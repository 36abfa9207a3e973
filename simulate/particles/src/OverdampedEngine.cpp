#include "mmval/particles/OverdampedEngine.hpp"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <mutex>
#include <thread>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <unordered_map>
#include <utility>

#include <fmt/format.h>
#include <gsl/gsl_randist.h>
#include <gsl/gsl_rng.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/Resources.hpp"

namespace mmval::particles {

struct OverdampedEngine::Rng {
  gsl_rng* r = nullptr;
  explicit Rng(std::uint64_t seed) : r(gsl_rng_alloc(gsl_rng_mt19937)) { gsl_rng_set(r, static_cast<unsigned long>(seed)); }
  ~Rng() { gsl_rng_free(r); }
  double normal() { return gsl_ran_gaussian_ziggurat(r, 1.0); }
};

namespace {

/// The flow seen through a memo of its point queries. Per particle and step the engine asks the
/// flow about the same point several times (the drift's velocity, lag, attraction and wall normal;
/// the wall check and the attachment after the move, which is the next step's drift point), and
/// near grain walls each velocity and distance query searches the wall cells (GriddedFlow's
/// near-wall layer velocity bisects along the wall normal). The memo returns the flow's own value
/// for a point (x, y) it has seen at the flow's current version() and asks the flow otherwise, so
/// results are bit for bit those of the flow; a re-solve bumps version() and empties it.
/// Direct-mapped, 2^12 points: a few hundred mobile particles keep two points each.
class FlowQueryMemo final : public FlowField {
 public:
  explicit FlowQueryMemo(std::shared_ptr<const FlowField> flow) : m_flow(std::move(flow)), m_slots(kSlots) {}
  Vec2 meanVelocity(double x, double y) const override {
    return remembered(x, y, kVelocity, &Entry::u, [&] { return m_flow->meanVelocity(x, y); });
  }
  double depth(double x, double y) const override {
    return remembered(x, y, kDepth, &Entry::h, [&] { return m_flow->depth(x, y); });
  }
  bool isSolid(double x, double y) const override {
    return remembered(x, y, kSolid, &Entry::solid, [&] { return m_flow->isSolid(x, y); });
  }
  double wallDistance(double x, double y) const override {
    return remembered(x, y, kDistance, &Entry::d, [&] { return m_flow->wallDistance(x, y); });
  }
  Vec2 wallNormal(double x, double y) const override {
    return remembered(x, y, kNormal, &Entry::n, [&] { return m_flow->wallNormal(x, y); });
  }
  std::uint64_t version() const override { return m_flow->version(); }
  Bounds2 bounds() const override { return m_flow->bounds(); }
  /// The flow behind the memo.
  const FlowField& inner() const { return *m_flow; }
  const std::shared_ptr<const FlowField>& shared() const { return m_flow; }

 private:
  static constexpr std::size_t kSlots = 4096;
  enum : std::uint8_t { kVelocity = 1, kDepth = 2, kSolid = 4, kDistance = 8, kNormal = 16 };
  struct Entry {
    std::uint64_t bx = 0, by = 0, version = 0;
    std::uint8_t have = 0;  // which of the values below are the flow's at (bx, by, version)
    bool solid = false;
    double h = 0, d = 0;
    Vec2 u = Vec2::Zero(), n = Vec2::Zero();
  };
  /// The flow's value of one query at (x, y): the entry's `slot` when its `bit` says it holds it,
  /// else `ask()`, kept there.
  template <typename T, typename Ask>
  T remembered(double x, double y, std::uint8_t bit, T Entry::*slot, Ask ask) const {
    Entry& e = at(x, y);
    if (!(e.have & bit)) {
      e.*slot = ask();
      e.have |= bit;
    }
    return e.*slot;
  }
  Entry& at(double x, double y) const {
    std::uint64_t bx = 0, by = 0;
    std::memcpy(&bx, &x, sizeof bx);
    std::memcpy(&by, &y, sizeof by);
    const std::uint64_t v = m_flow->version();
    const std::uint64_t hash = (bx * 0x9E3779B97F4A7C15ULL) ^ (by * 0xC2B2AE3D27D4EB4FULL);
    Entry& e = m_slots[(hash >> 40) % kSlots];
    if (e.have == 0 || e.bx != bx || e.by != by || e.version != v) {
      e.bx = bx;
      e.by = by;
      e.version = v;
      e.have = 0;
    }
    return e;
  }
  std::shared_ptr<const FlowField> m_flow;
  mutable std::vector<Entry> m_slots;
};

/// The attachment of one surface type from its DLVO profile (Dlvo.hpp); ~20 ms.
SurfaceChemistry surfaceChemistry(const DlvoParameters& p) {
  SurfaceChemistry sc;
  sc.parameters = p;
  const DlvoInteraction v(p);
  sc.profile = profileFeatures(v);
  sc.attachment = attachmentEfficiency(v);
  // IFBL alpha is the ratio of rates with and without the double layer; a double layer that
  // attracts (opposite charges) can make it exceed 1, where every arrival attaches.
  sc.alpha = sc.attachment.primary_minimum_reachable ? std::min(1.0, sc.attachment.alpha()) : 0.0;
  // A well shallower than ~1 kT holds nothing against Brownian motion: no secondary capture.
  const double depth = sc.profile.has_secondary_minimum ? -sc.profile.secondary_minimum_kT : 0.0;
  sc.secondary_capture = depth > 1.0 ? secondaryMinimumCaptureProbability(depth) : 0.0;
  if (sc.secondary_capture > 0) {
    // Pull-off force of the secondary minimum: the largest attraction -dV/dh < 0 between the
    // well and the far field (a particle pulled harder than this leaves the well).
    const double g0 = sc.profile.secondary_minimum_gap, g1 = std::max(5e-6, 10 * g0);
    const int n = 400;
    for (int k = 1; k <= n; ++k) sc.secondary_force = std::max(sc.secondary_force, -v.force(g0 * std::pow(g1 / g0, static_cast<double>(k) / n)));
  }
  return sc;
}

}  // namespace

struct OverdampedEngine::Worker {
  const FlowField* flow = nullptr;  ///< this thread's memo of the engine's flow
  const HydroModel* model = nullptr;
  std::vector<Vec2> normals;  ///< applyWalls' and heldByDeposits' scratch
  std::vector<int> near;      ///< backOutOfDeposits' scratch
  std::shared_ptr<const FlowField> own_flow;  ///< threads 1..: a memo of their own over the same flow
  std::unique_ptr<HydroModel> own_model;      ///< threads 1..: the engine's model over own_flow
};

/// Threads 1..n-1 of the per-particle loops, kept for the engine's life. A job is split into
/// kChunksPerThread contiguous chunks per thread, thread w owning the w-th run of them (so a
/// particle's flow queries of one step mostly meet the same thread's memo in the next). Each thread
/// takes its own chunks first, in order, then any chunk no thread has taken yet, from the far end
/// of another thread's run: a thread that meets slow particles (near walls, with many substeps) or
/// that the machine has not scheduled yet never holds up the step while the other waits.
class OverdampedEngine::Pool {
 public:
  using Body = std::function<void(std::size_t, Worker&)>;
  explicit Pool(std::vector<std::unique_ptr<Worker>>& workers) : m_workers(workers) {
    for (std::size_t w = 1; w < workers.size(); ++w) m_threads.emplace_back([this, w] { loop(w); });
  }
  ~Pool() {
    {
      const std::lock_guard<std::mutex> lock(m_mutex);
      m_stop = true;
      m_stop_seen.store(true);
    }
    m_wake.notify_all();
    for (auto& t : m_threads) t.join();
  }
  Pool(const Pool&) = delete;
  Pool& operator=(const Pool&) = delete;
  void run(std::size_t n, const Body& body) {
    {
      const std::lock_guard<std::mutex> lock(m_mutex);
      m_body = &body;
      m_n = n;
      m_taken.store(0);
      m_failed = nullptr;
      m_open = true;
      m_generation.fetch_add(1);
    }
    m_wake.notify_all();
    work(0);
    std::unique_lock<std::mutex> lock(m_mutex);
    m_open = false;  // every chunk is taken: threads that wake from now on skip this job
    if (m_active.load() > 0) {
      lock.unlock();
      for (int spin = 0; spin < kSpins && m_active.load() > 0; ++spin) pause();
      lock.lock();
    }
    m_done.wait(lock, [&] { return m_active.load() == 0; });
    if (m_failed) std::rethrow_exception(m_failed);
  }

 private:
  /// Busy-wait rounds (~10 us) before a thread sleeps: a step's next loop usually comes sooner, and
  /// waking a sleeping thread costs more than a step's share of a few dozen particles.
  static constexpr int kSpins = 2000;
  static void pause() {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#else
    std::this_thread::yield();
#endif
  }
  void loop(std::size_t w) {
    std::unique_lock<std::mutex> lock(m_mutex);
    std::uint64_t seen = 0;
    for (;;) {
      if (!m_stop && m_generation.load() == seen) {
        lock.unlock();
        for (int spin = 0; spin < kSpins && m_generation.load() == seen && !m_stop_seen.load(); ++spin) pause();
        lock.lock();
      }
      m_wake.wait(lock, [&] { return m_stop || m_generation.load() != seen; });
      if (m_stop) return;
      seen = m_generation.load();
      if (!m_open) continue;
      ++m_active;
      lock.unlock();
      work(w);
      lock.lock();
      if (--m_active == 0) m_done.notify_all();
    }
  }
  /// Chunks per thread: enough that the last chunks even out the threads' loads, few enough that
  /// stolen chunks seldom leave a particle's memo on another thread.
  static constexpr std::size_t kChunksPerThread = 8;
  /// Chunk c of the job: [n c / C, n (c + 1) / C) with C chunks in all (at most 64, the bits of
  /// m_taken); thread w owns chunks [w C / T, (w + 1) C / T) of T threads.
  void work(std::size_t w) {
    const std::size_t threads = m_workers.size(), chunks = std::min<std::size_t>(64, kChunksPerThread * threads);
    const auto take = [&](std::size_t c) { return (m_taken.fetch_or(std::uint64_t{1} << c) >> c & 1u) == 0; };
    const auto run = [&](std::size_t c) {
      if (!take(c)) return;
      try {
        for (std::size_t i = m_n * c / chunks, end = m_n * (c + 1) / chunks; i < end; ++i) (*m_body)(i, *m_workers[w]);
      } catch (...) {
        const std::lock_guard<std::mutex> lock(m_mutex);
        if (!m_failed) m_failed = std::current_exception();
      }
    };
    for (std::size_t c = w * chunks / threads; c < (w + 1) * chunks / threads; ++c) run(c);
    for (std::size_t k = 1; k < threads; ++k) {
      const std::size_t v = (w + k) % threads;
      for (std::size_t c = (v + 1) * chunks / threads; c-- > v * chunks / threads;) run(c);
    }
  }
  std::vector<std::unique_ptr<Worker>>& m_workers;
  std::vector<std::thread> m_threads;
  std::mutex m_mutex;
  std::condition_variable m_wake, m_done;
  const Body* m_body = nullptr;
  std::size_t m_n = 0;
  std::atomic<std::uint64_t> m_taken{0};  ///< bit c: chunk c taken
  std::exception_ptr m_failed;
  std::atomic<std::uint64_t> m_generation{0};  ///< changed under m_mutex; read without it while spinning
  std::atomic<int> m_active{0};                ///< threads inside the current job (changed under m_mutex)
  std::atomic<bool> m_stop_seen{false};        ///< m_stop, for the spinning threads
  bool m_open = false, m_stop = false;
};

void OverdampedEngine::forEachMobile(std::size_t n, const std::function<void(std::size_t, Worker&)>& body) {
  if (m_pool && n >= kMinParallelMobile) return m_pool->run(n, body);
  for (std::size_t k = 0; k < n; ++k) body(k, *m_workers[0]);
}

OverdampedEngine::OverdampedEngine(std::shared_ptr<const FlowField> flow, SceneConfig config)
    : m_flow(flow ? std::make_shared<const FlowQueryMemo>(std::move(flow)) : nullptr), m_cfg(std::move(config)), m_model(m_flow, m_cfg) {
  const auto& p = m_cfg.particle;
  if (!(p.diameter > 0) || !(p.density > 0) || !(m_cfg.fluid.viscosity > 0) || !(m_cfg.fluid.temperature > 0))
    throw InputError(keyLocation("particles"), "diameter, densities, viscosity and temperature must be > 0");
  if (!(m_cfg.max_step_fraction > 0) || m_cfg.max_step_fraction > 1)
    throw InputError(keyLocation("numerics.max_step_fraction"), "out of range", std::to_string(m_cfg.max_step_fraction), "(0, 1]");
  m_radius = p.radius();
  if (m_flow) m_grid = dynamic_cast<const GriddedFlow*>(&static_cast<const FlowQueryMemo&>(*m_flow).inner());
  m_outlet = std::isnan(m_cfg.outlet_x) ? m_flow->bounds().x1 : m_cfg.outlet_x;
  m_rng = std::make_unique<Rng>(m_cfg.seed);
  if (m_cfg.attachment.rule == AttachmentModel::Rule::dlvo) {
    // Plates and grains are the chip's material (sphere-plate against the collector
    // potential); deposits are the particle's own (sphere-sphere, both at its potential).
    DlvoParameters plate = m_cfg.attachment.chemistry;
    plate.particle_radius = m_radius;
    plate.collector_radius = std::numeric_limits<double>::infinity();
    DlvoParameters deposit = plate;
    deposit.collector_radius = m_radius;
    deposit.collector_potential = plate.particle_potential;
    deposit.collector_charge.regulated = false;  // a deposit is latex at the particle's (fixed) potential, not glass
    m_plate_chem = std::make_unique<SurfaceChemistry>(surfaceChemistry(plate));
    m_deposit_chem = std::make_unique<SurfaceChemistry>(surfaceChemistry(deposit));
    const double ps = m_cfg.attachment.patch_size;
    if (!(ps >= 0) || std::isinf(ps))
      throw std::invalid_argument("OverdampedEngine: patch size " + std::to_string(ps) + " m, need a finite value >= 0 (0: a patch drawn per arrival)");
    // Patches placed in space only where there are any: lambda = 0 leaves the per-arrival rule.
    if (ps > 0 && m_cfg.attachment.favourable_fraction > 0) m_patches = {m_cfg.attachment.favourable_fraction, ps, m_cfg.seed};
  }
  if (m_cfg.threads < 0 || m_cfg.threads > kMaxThreads)
    throw InputError(keyLocation("numerics.threads"), "not a thread count", std::to_string(m_cfg.threads),
                     fmt::format("1 to {}, or 0 (auto: the hardware's cores, 2 to 8)", kMaxThreads));
  if (m_cfg.substeps < 1 || m_cfg.substeps > 64 || (m_cfg.substeps & (m_cfg.substeps - 1)) != 0)
    throw InputError(keyLocation("numerics.substeps"), "not a substep count", std::to_string(m_cfg.substeps), "a power of 2 from 1 to 64");
  m_threads = m_cfg.threads > 0 ? m_cfg.threads : mmval::autoThreads(kMaxThreads);
  auto first = std::make_unique<Worker>();
  first->flow = m_flow.get();
  first->model = &m_model;
  m_workers.push_back(std::move(first));
  for (int w = 1; w < m_threads; ++w) {
    auto more = std::make_unique<Worker>();
    more->own_flow = std::make_shared<const FlowQueryMemo>(static_cast<const FlowQueryMemo&>(*m_flow).shared());
    more->own_model = std::make_unique<HydroModel>(more->own_flow, m_cfg);
    more->flow = more->own_flow.get();
    more->model = more->own_model.get();
    m_workers.push_back(std::move(more));
  }
  if (m_threads > 1) m_pool = std::make_unique<Pool>(m_workers);
}

bool OverdampedEngine::favourablePatchAt(Surface s, const Vec3& x) const { return favourablePatchAt(s, x, *m_flow); }

bool OverdampedEngine::favourablePatchAt(Surface s, const Vec3& x, const FlowField& flow) const {
  if (!(m_patches.size > 0)) return false;
  using Sheet = FavourablePatchMap::Sheet;
  switch (s) {
    case Surface::bottom: return m_patches.favourableAt(Sheet::bottom, x.x(), x.y(), 0.0);
    case Surface::top: return m_patches.favourableAt(Sheet::top, x.x(), x.y(), 0.0);
    case Surface::grain: {
      // The contact point: the nearest wall point in the plane, at the particle centre's height.
      if (flow.isSolid(x.x(), x.y())) return m_patches.favourableAt(Sheet::walls, x.x(), x.y(), x.z());
      const double d = flow.wallDistance(x.x(), x.y());
      const Vec2 n = flow.wallNormal(x.x(), x.y());
      return m_patches.favourableAt(Sheet::walls, x.x() - d * n.x(), x.y() - d * n.y(), x.z());
    }
    default: return false;  // deposits are latex: no glass patches
  }
}

const SurfaceChemistry* OverdampedEngine::chemistry(Surface s) const {
  if (s == Surface::deposit) return m_deposit_chem.get();
  if (s == Surface::bottom || s == Surface::top || s == Surface::grain) return m_plate_chem.get();
  return nullptr;
}

namespace {

/// Where the collector potential came from: an input, or charge regulation (with its inputs and state).
nlohmann::json collectorChargeJson(const DlvoParameters& p) {
  const auto& cc = p.collector_charge;
  if (!cc.regulated) return {{"model", "fixed"}, {"zeta_mV", p.collector_potential * 1e3}};
  const RegulatedCharge r = regulatedCharge(cc.surface, p.electrolyte, cc.ph);
  return {{"model", "regulated (Basic Stern model of silanol dissociation, Behrens & Grier 2001); zeta = diffuse-layer potential"},
          {"zeta_mV", p.collector_potential * 1e3},  // the value used: r.diffuse_potential at this electrolyte
          {"surface_potential_mV", r.surface_potential * 1e3},
          {"surface_charge_mC_m2", r.surface_charge * 1e3},
          {"dissociated_fraction", r.dissociated_fraction},
          {"pH", cc.ph},
          {"pK", cc.surface.pK},
          {"sites_per_nm2", cc.surface.site_density * 1e-18},
          {"stern_capacitance_F_m2", cc.surface.capacitance}};
}

}  // namespace

nlohmann::json SurfaceChemistry::describe() const {
  const auto& p = parameters;
  const auto& f = profile;
  nlohmann::json j = {{"geometry", std::isinf(p.collector_radius) ? "sphere-plate" : "sphere-sphere"},
                      {"particle_zeta_mV", p.particle_potential * 1e3},
                      {"collector_zeta_mV", p.collector_potential * 1e3},
                      {"collector_charge", collectorChargeJson(p)},
                      {"ionic_strength_mM", p.electrolyte.ionic_strength},
                      {"valence", p.electrolyte.valence},
                      {"temperature_K", p.electrolyte.temperature},
                      {"hamaker_J", p.hamaker},
                      {"double_layer", p.double_layer == DoubleLayerModel::hhf ? "HHF" : "LSA"},
                      {"born", p.born},
                      {"has_barrier", f.has_barrier},
                      {"has_secondary_minimum", f.has_secondary_minimum},
                      {"has_primary_minimum", f.has_primary_minimum},
                      {"primary_minimum_reachable", attachment.primary_minimum_reachable},
                      {"alpha", alpha},
                      {"ln_alpha", std::isfinite(attachment.ln_alpha) ? nlohmann::json(attachment.ln_alpha) : nlohmann::json("-inf")},
                      {"secondary_capture_probability", secondary_capture},
                      {"secondary_minimum_force_N", secondary_force}};
  if (f.has_barrier) j["barrier_kT"] = f.barrier_kT, j["barrier_gap_nm"] = f.barrier_gap * 1e9;
  if (f.has_secondary_minimum) j["secondary_minimum_kT"] = f.secondary_minimum_kT, j["secondary_minimum_gap_nm"] = f.secondary_minimum_gap * 1e9;
  if (f.has_primary_minimum) j["primary_minimum_kT"] = f.primary_minimum_kT, j["primary_minimum_gap_nm"] = f.primary_minimum_gap * 1e9;
  return j;
}

OverdampedEngine::~OverdampedEngine() = default;

namespace {

/// OverdampedEngine::driftVelocity at x, and the hindrance factors (parallel, perpendicular) at x
/// (the Brownian step's, computed once for both).
Vec3 driftAndHindrance(const FlowField& flow, const HydroModel& model, const SceneConfig& cfg, double a, const Vec3& x,
                       std::pair<double, double>& hindrance) {
  const double h = flow.depth(x.x(), x.y());
  hindrance = model.hindrance(x.z(), h);
  if (flow.isSolid(x.x(), x.y())) return Vec3::Zero();
  const double g0 = model.drag0();
  const auto [par, perp] = hindrance;
  const Vec3 f = model.force(x);
  Vec3 v = model.fluidVelocity(x) + model.shearLag(x) + Vec3(f.x() / (g0 * par), f.y() / (g0 * par), f.z() / (g0 * perp));
  if (cfg.brownian && cfg.wall_hindrance && cfg.ito_drift) {
    // Ito drift k_B T d(1/(6 pi mu a lambda_perp))/dz keeps the equilibrium distribution right.
    const double e = 1e-3 * a;
    const double zm = std::max(x.z() - e, a), zp = std::min(x.z() + e, h - a);
    if (zp > zm) v.z() += model.diffusivity() * (1.0 / model.normalHindrance(zp, h) - 1.0 / model.normalHindrance(zm, h)) / (zp - zm);
  }
  return v;
}

/// The step's drift velocity under Heun's predictor-corrector (SceneConfig::heun_drift): the mean
/// of v (the drift at x) and the drift at the Euler predictor x + v h, where that predictor is in
/// the fluid with the sphere clear of the plates and grain walls; else v (Euler: a step that
/// reaches a wall is the wall step's to resolve, and the drift inside one is not defined).
Vec3 heunDrift(const FlowField& flow, const HydroModel& model, const SceneConfig& cfg, double a, const Vec3& x, const Vec3& v, double h) {
  const Vec3 xp = x + v * h;
  if (flow.isSolid(xp.x(), xp.y())) return v;
  const double depth = flow.depth(xp.x(), xp.y());
  if (xp.z() < a || xp.z() > depth - a || flow.wallDistance(xp.x(), xp.y()) < a) return v;
  std::pair<double, double> unused;
  return 0.5 * (v + driftAndHindrance(flow, model, cfg, a, xp, unused));
}

}  // namespace

Vec3 OverdampedEngine::driftVelocity(const Vec3& x) const {
  std::pair<double, double> hindrance;
  return driftAndHindrance(*m_flow, m_model, m_cfg, m_radius, x, hindrance);
}

void OverdampedEngine::insert(const std::vector<Vec3>& positions) {
  std::vector<ParticleState> trial = m_particles;
  for (std::size_t k = 0; k < positions.size(); ++k) {
    const std::string why = insertionProblem(*m_flow, m_radius, positions[k], trial);
    if (!why.empty()) throw InputError(keyLocation("particles.insert"), fmt::format("particle {} of this insertion cannot be placed: {}", k, why));
    ParticleState s;
    s.id = static_cast<std::int64_t>(trial.size()) + 1;
    s.x = positions[k];
    trial.push_back(s);
  }
  for (std::size_t k = m_particles.size(); k < trial.size(); ++k) m_mobile.push_back(static_cast<int>(k));
  m_particles = std::move(trial);
}

double OverdampedEngine::ownStep(std::size_t k, const Vec3& v) const {
  const double lim = m_cfg.max_step_fraction * m_radius;
  // Approaching a plate the mobility changes over the gap, not the radius: the
  // drift across the depth may cover only the same fraction of the gap (floored
  // at the capture distance, or 1 % of a radius), else explicit steps overshoot.
  const double floor = std::max(m_cfg.attachment.capture_distance, 0.01 * m_radius);
  double dt = m_cfg.max_dt;
  const double speed = v.norm();
  if (speed > 0) dt = std::min(dt, lim / speed);
  const double vz = std::abs(v.z());
  if (vz > 0) {
    const auto& x = m_particles[m_mobile[k]].x;
    const double h = m_flow->depth(x.x(), x.y());
    const double gap = v.z() < 0 ? x.z() - m_radius : h - x.z() - m_radius;
    dt = std::min(dt, m_cfg.max_step_fraction * std::max(gap, floor) / vz);
  }
  if (m_cfg.brownian) dt = std::min(dt, lim * lim / (2.0 * m_model.diffusivity()));
  return dt;
}

bool OverdampedEngine::meetsNeighbour(const ParticleState& p, std::size_t k, const Vec3& from, double tau_from, double tau,
                                      const std::vector<Vec3>& drift) const {
  // Nearer than a diameter (the contact sweeps' tolerance) and nearer than at the substep's start:
  // particles that start in contact and move apart, or side by side, go on.
  const double dmin = 2 * m_radius * (1 - 1e-3);
  const auto meets = [&](const Vec3& y, const Vec3& y_before) {
    const double now = (p.x - y).norm();
    return now < dmin && now < (from - y_before).norm();
  };
  const auto deposit = [&](int j) { return meets(m_particles[j].x, m_particles[j].x); };
  if (anyDepositNear(p.x, 2 * m_radius, deposit)) return true;
  const double cs = 4 * m_radius;
  const auto ix = static_cast<std::int64_t>(std::floor(p.x.x() / cs)), iy = static_cast<std::int64_t>(std::floor(p.x.y() / cs));
  for (auto cx = ix - 1; cx <= ix + 1; ++cx)
    for (auto cy = iy - 1; cy <= iy + 1; ++cy) {
      const std::int64_t key = columnKey(cx, cy);
      auto it = std::lower_bound(m_snapshot_cells.begin(), m_snapshot_cells.end(), std::make_pair(key, -1));
      for (; it != m_snapshot_cells.end() && it->first == key; ++it) {
        const auto j = static_cast<std::size_t>(it->second);
        if (j == k) continue;
        // Along its drift, unless the walls or deposits hold it (its straining clock runs): there.
        const Vec3 v = std::isnan(m_particles[m_mobile[j]].pinned_since) ? drift[j] : Vec3::Zero();
        const Vec3 y = m_snapshot[j] + v * tau, y_before = m_snapshot[j] + v * tau_from;
        if (meets(y, y_before)) return true;
      }
    }
  return false;
}

void OverdampedEngine::indexDeposited(int i) {
  const std::int64_t key = cellKey(m_particles[i].x);
  m_dep_cells[key].push_back(i);
  m_dep_filter.add(key);
  m_dep_order.push_back(i);
}

std::int64_t OverdampedEngine::cellKey(const Vec3& x) const {
  // Contact cells are columns (x, y) of side 2 d: a particle's partners within
  // one diameter lie in the 2 x 2 columns around it (4 look-ups, not 27), and
  // the chip is only a few diameters deep.
  const double cs = 4 * m_radius;
  const auto ix = static_cast<std::int64_t>(std::floor(x.x() / cs)), iy = static_cast<std::int64_t>(std::floor(x.y() / cs));
  return columnKey(ix, iy);
}

void OverdampedEngine::compactMobile(double t_event) {
  // Particles that stopped in this step: time-stamp them, index the deposited
  // ones for contacts, keep the mobile list sorted by index (RNG order).
  std::size_t w = 0;
  for (const int i : m_mobile) {
    auto& p = m_particles[i];
    if (p.status == ParticleStatus::mobile) {
      m_mobile[w++] = i;
      continue;
    }
    if (std::isnan(p.t_event)) p.t_event = t_event;
    if (p.status == ParticleStatus::deposited) indexDeposited(i);
  }
  m_mobile.resize(w);
}

void OverdampedEngine::advance(double t_end) {
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<Vec3> drift;
  std::vector<std::pair<double, double>> hindrance;  // at each drift point: the Brownian step's
  while (m_t < t_end * (1 - 1e-14)) {
    // Only mobile particles cost anything per step: deposited and departed ones
    // are never visited (long runs hold thousands of them).
    drift.resize(m_mobile.size());
    hindrance.resize(m_mobile.size());
    forEachMobile(m_mobile.size(), [&](std::size_t k, Worker& w) {
      drift[k] = driftAndHindrance(*w.flow, *w.model, m_cfg, m_radius, m_particles[m_mobile[k]].x, hindrance[k]);
    });
    const auto mobile = static_cast<std::int64_t>(m_mobile.size());
    // Each particle's own step once; the engine's is the smallest, or with substeps up to K times it,
    // each particle then taking as many steps of its own within it as its own limit asks (up to K).
    const int K = std::max(1, m_cfg.substeps);
    double dt = t_end - m_t;
    if (mobile) {
      m_own.resize(m_mobile.size());
      dt = m_cfg.max_dt;
      for (std::size_t k = 0; k < m_mobile.size(); ++k) dt = std::min(dt, m_own[k] = ownStep(k, drift[k]));
      if (K > 1) dt = std::min(K * dt, m_cfg.max_dt);
    }
    dt = std::min(dt, t_end - m_t);
    if (mobile) {
      const auto& c = m_cfg;
      m_touch.assign(m_particles.size(), 0);
      m_clamp.assign(m_particles.size(), 0);
      m_substeps.assign(m_mobile.size(), 1);
      bool any_substeps = false;
      if (K > 1)
        for (std::size_t k = 0; k < m_mobile.size(); ++k) {
          // As many as its own limit asks, up to K: the ceiling of dt / own (an integer, not a power
          // of 2, which took up to twice the steps a particle needed where the own steps are alike).
          const double need = m_own[k] > 0 ? std::ceil(dt / m_own[k] * (1 - 1e-12)) : static_cast<double>(K);
          m_substeps[k] = static_cast<int>(std::clamp(need, 1.0, static_cast<double>(K)));
          any_substeps = any_substeps || m_substeps[k] > 1;
        }
      if (any_substeps) {
        // The places before the step, indexed by contact column, for meetsNeighbour.
        m_snapshot.resize(m_mobile.size());
        m_snapshot_cells.resize(m_mobile.size());
        for (std::size_t k = 0; k < m_mobile.size(); ++k) {
          m_snapshot[k] = m_particles[m_mobile[k]].x;
          m_snapshot_cells[k] = {cellKey(m_snapshot[k]), static_cast<int>(k)};
        }
        std::sort(m_snapshot_cells.begin(), m_snapshot_cells.end());
      }
      // The step's normal draws first, in mobile order (one thread's order), 3 per substep, then the
      // moves and wall steps, which are independent per particle (each writes its own particle and
      // touch bits).
      if (c.brownian) {
        m_draw_offset.resize(m_mobile.size());
        std::size_t n = 0;
        for (std::size_t k = 0; k < m_mobile.size(); ++k) {
          m_draw_offset[k] = n;
          n += 3 * static_cast<std::size_t>(m_substeps[k]);
        }
        m_draws.resize(n);
        for (double& r : m_draws) r = m_rng->normal();
      }
      forEachMobile(m_mobile.size(), [&](std::size_t k, Worker& w) {
        auto& p = m_particles[m_mobile[k]];
        const int i = m_mobile[k], n = m_substeps[k];
        const double h = dt / n;
        Vec3 v = drift[k];
        std::pair<double, double> hind = hindrance[k];  // at p.x: the drift's point, not moved since
        std::uint8_t touched = 0;
        int taken = 0;
        while (taken < n) {
          if (taken > 0) v = driftAndHindrance(*w.flow, *w.model, m_cfg, m_radius, p.x, hind);
          const Vec3 before = p.x;
          Vec3 dx = (c.heun_drift ? heunDrift(*w.flow, *w.model, m_cfg, m_radius, p.x, v, h) : v) * h;
          if (c.brownian) {
            const auto [par, perp] = hind;
            const double sp = std::sqrt(2.0 * m_model.diffusivity() * h / par), sz = std::sqrt(2.0 * m_model.diffusivity() * h / perp);
            // z, y, x from the substep's three draws: the order GCC evaluated the three draws of the
            // single-threaded step (Vec3(sp * normal(), sp * normal(), sz * normal()), its arguments
            // right to left), so runs keep the random paths of the binaries before threads.
            const double* r = &m_draws[m_draw_offset[k] + 3 * static_cast<std::size_t>(taken)];
            dx += Vec3(sp * r[2], sp * r[1], sz * r[0]);
          }
          p.x += dx;
          p.v = v;
          // The surfaces it touched in any substep (arrivals for the step's attachment); held by the
          // walls (kPinned, the straining clock's test) only as the last substep left it, as one step
          // for all would: a particle held in one substep and freed in the next is not held.
          const std::uint8_t now = applyWalls(p, before, *w.flow, w.normals);
          touched = static_cast<std::uint8_t>((touched & ~kPinned) | now);
          ++taken;
          // The rest of the step waits for the contact sweeps where the particle left or came to a
          // deposit or another particle (no substep passes through one).
          if (taken == n || p.status != ParticleStatus::mobile) break;
          if (meetsNeighbour(p, k, before, (taken - 1) * h, taken * h, drift)) break;
        }
        m_substeps[k] = taken;
        m_touch[i] = touched;
        // Where the plates' clamp of the contact sweeps would move a particle no push moves (the
        // depth there below a diameter), it is marked for it; every other one it leaves as it is.
        if (p.status != ParticleStatus::left) {
          const double h = w.flow->depth(p.x.x(), p.x.y());
          m_clamp[i] = std::clamp(p.x.z(), m_radius, std::max(m_radius, h - m_radius)) != p.x.z();
        }
      });
      // Attachment only once every overlap of the step is removed: a particle attached
      // earlier would be left out of the contact sweeps and could stay inside a deposit.
      resolveContacts();
      std::sort(m_deposit_contacts.begin(), m_deposit_contacts.end());
      // Per particle, on the threads: the contacts' undo and back-out, the mirror planes, then
      // attachment and the straining clock. Each reads the flow, itself and deposits indexed in
      // earlier steps (m_dep_cells, m_deposit_contacts' partners), never another mobile particle or
      // one deposited in this step, and writes only itself: the order of particles does not matter.
      const double t_next = m_t + dt;
      forEachMobile(m_mobile.size(), [&](std::size_t k, Worker& w) {
        afterContacts(k, w);
        const int i = m_mobile[k];
        auto& p = m_particles[i];
        if (p.status != ParticleStatus::mobile) return;
        decideAttachment(p, m_touch[i], w);
        updateStraining(p, (m_touch[i] & kPinned) != 0 || heldByDeposits(p, i, w), t_next);
      });
      // In mobile order, on one thread: a new deposit (not strained) that overlaps one made earlier in
      // this step, or an indexed one, stays mobile.
      std::vector<int> fresh;  // deposited in this step, not yet in m_dep_cells
      for (const int i : m_mobile) {
        auto& p = m_particles[i];
        if (p.status != ParticleStatus::deposited) continue;  // deposited only just now: mobile before this step
        // An attachment that overlaps a deposit waits for the next step's pushes. A strained particle
        // does not: it has been held in place for the straining time, pushes that never removed the
        // overlap (stopped by a plate, undone at the walls, no place to back out to) will not now,
        // and as a mobile particle it would stay there, stepped, to the end of the run.
        if (p.held_by != Surface::strained && overlapsDeposit(p, fresh)) {
          p.status = ParticleStatus::mobile;  // a push undone at a grain left an overlap: try again next step
          p.held_by = Surface::none;
          p.secondary = false;
          continue;
        }
        fresh.push_back(i);
      }
      compactMobile(m_t + dt);
      for (const int n : m_substeps) m_stats.particle_steps += n;
      ++m_stats.steps;
      m_stats.last_dt = dt;
      m_stats.min_dt = std::min(m_stats.min_dt, dt);
      m_stats.max_dt = std::max(m_stats.max_dt, dt);
    }
    m_t += dt;
  }
  m_t = std::max(m_t, t_end);
  m_stats.wall_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::int64_t OverdampedEngine::captureInSolid() {
  std::int64_t n = 0;
  for (const int i : m_mobile) {
    auto& p = m_particles[i];
    if (!m_flow->isSolid(p.x.x(), p.x.y())) continue;
    p.status = ParticleStatus::deposited;
    p.held_by = Surface::solid;
    p.t_event = m_t;
    ++n;
  }
  compactMobile(m_t);
  return n;
}

namespace {
/// A wall position is admissible at a wall distance >= (1 - kWallTolerance) a: the walls are
/// exact (pixel edges, GridWalls::cells / brinkman; analytic fields), so only round-off of the
/// pushes is forgiven. Particles pass gaps wider than (2 - kWallTolerance) a and stop at narrower.
constexpr double kWallTolerance = 1e-3;
/// Normal pushes per move; curved walls and corners settle in two or three.
constexpr int kWallPasses = 3;
/// Slides along a wall at a shallower angle than this to the other wall (sin, ~3 deg) are not
/// tried: the walls are parallel and the gap between them is what it is.
constexpr double kMinSlideSine = 0.05;
/// Largest slide, radii (a slide that long is a different place, not a settled contact).
constexpr double kMaxSlide = 0.5;

double cross(const Vec2& u, const Vec2& v) { return u.x() * v.y() - u.y() * v.x(); }

/// The drift u is held by walls of these normals: -u lies strictly inside the cone of two of
/// them (u = -(l1 n1 + l2 n2), l1, l2 > 0), so every direction that leaves both walls goes
/// against the drift. normals[first_wall..] are grain or side walls' (the others deposits'): two
/// of those whose dot product exceeds one_wall_cos are one wall seen twice within the walls'
/// normal accuracy (OverdampedEngine::kSmoothWallOneWallDeg), not a cone.
bool heldAgainst(const Vec2& u, const std::vector<Vec2>& normals, std::size_t first_wall = 0, double one_wall_cos = 2.0) {
  for (std::size_t i = 0; i < normals.size(); ++i)
    for (std::size_t j = i + 1; j < normals.size(); ++j) {
      if (i >= first_wall && normals[i].dot(normals[j]) > one_wall_cos) continue;
      const double det = cross(normals[i], normals[j]);
      if (std::abs(det) < 1e-9) continue;
      const double l1 = cross(-u, normals[j]) / det, l2 = cross(normals[i], -u) / det;
      if (l1 > 0 && l2 > 0) return true;
    }
  return false;
}
}  // namespace

bool OverdampedEngine::slideBetweenWalls(ParticleState& p, const Vec3& before, const Vec2& last, std::vector<Vec2>& normals,
                                         const FlowField& flow) const {
  const double a = m_radius, accept = (1 - kWallTolerance) * a;
  const double d = flow.wallDistance(p.x.x(), p.x.y());
  const Vec2 n = flow.wallNormal(p.x.x(), p.x.y());
  normals.push_back(n);
  // Along the last wall (planar: its distance stays a) towards the side the other wall recedes.
  Vec2 t(-last.y(), last.x());
  double c = t.dot(n);
  if (c < 0) t = -t, c = -c;
  if (c < kMinSlideSine) return false;
  const double s = (a - d) / c;
  if (s > kMaxSlide * a) return false;
  const Vec2 q = Vec2(p.x.x(), p.x.y()) + s * t;
  const Vec2 mid = 0.5 * (q + Vec2(before.x(), before.y()));
  for (const Vec2& r : {q, mid})
    if (flow.isSolid(r.x(), r.y()) || flow.wallDistance(r.x(), r.y()) < accept) return false;
  p.x.x() = q.x();
  p.x.y() = q.y();
  return true;
}

void OverdampedEngine::reflectAtMirrors(ParticleState& p) const {
  if (!m_cfg.mirror_sides) return;
  const Bounds2 b = m_flow->bounds();  // the memo's bounds are its flow's: no memo state, safe on any thread
  // A step is a fraction of a radius, far below the strip's width: at most a reflection or two.
  for (int k = 0; k < 4 && (p.x.y() < b.y0 || p.x.y() > b.y1); ++k) p.x.y() = p.x.y() < b.y0 ? 2 * b.y0 - p.x.y() : 2 * b.y1 - p.x.y();
}

std::uint8_t OverdampedEngine::applyWalls(ParticleState& p, const Vec3& before, const FlowField& flow, std::vector<Vec2>& normals) const {
  const double a = m_radius;
  std::uint8_t touched = 0;
  // Mirror sides: the field beyond a plane is the mirror image of the pore space, so the move and
  // its reflection see the same walls; the reflected one stays in the chip.
  reflectAtMirrors(p);
  // Grains and side walls: a step into solid is taken back in-plane; a particle
  // closer than a radius is pushed out along the wall normal.
  if (flow.isSolid(p.x.x(), p.x.y())) {
    p.x.x() = before.x();
    p.x.y() = before.y();
    touched |= kGrain;
  }
  const Bounds2 b = flow.bounds();
  if (p.x.x() > m_outlet || p.x.x() < b.x0 || p.x.y() < b.y0 || p.x.y() > b.y1) {
    p.status = ParticleStatus::left;
    return touched;
  }
  double d = flow.wallDistance(p.x.x(), p.x.y());
  if (d < a) {
    // Pushed out along the wall normal; a few passes settle curved walls and
    // corners, and a slide along the last wall settles two walls closing in at an
    // angle. Where nothing helps (a throat narrower than the particle: walls on
    // both sides) the move is refused, so a particle never squeezes through a gap
    // smaller than itself.
    touched |= kGrain;
    normals.clear();
    for (int pass = 0; pass < kWallPasses && d < a; ++pass) {
      const Vec2 n = flow.wallNormal(p.x.x(), p.x.y());
      normals.push_back(n);
      p.x.x() += n.x() * (a - d);
      p.x.y() += n.y() * (a - d);
      d = flow.isSolid(p.x.x(), p.x.y()) ? 0.0 : flow.wallDistance(p.x.x(), p.x.y());
    }
    const double accept = (1 - kWallTolerance) * a;
    const bool settled = d >= accept || (!flow.isSolid(p.x.x(), p.x.y()) && slideBetweenWalls(p, before, normals.back(), normals, flow));
    if (!settled) {
      p.x.x() = before.x();
      p.x.y() = before.y();
    }
    // Held by the walls: refused, or pushed off two walls that close in ahead of its drift, with
    // the drift beating diffusion over a radius (else Brownian motion, not the flow, decides).
    const Vec2 u(p.v.x(), p.v.y());
    if (u.norm() * a >= m_model.diffusivity() && (!settled || heldAgainst(u, normals, 0, oneWallCos()))) touched |= kPinned;
  }
  const double h = flow.depth(p.x.x(), p.x.y());
  if (p.x.z() < a) {
    p.x.z() = a;
    touched |= kBottom;
  }
  if (p.x.z() > h - a) {
    p.x.z() = h - a;
    touched |= kTop;
  }
  reflectAtMirrors(p);  // a wall's push can carry it across a plane
  return touched;
}

void OverdampedEngine::updateStraining(ParticleState& p, bool pinned, double t) const {
  const StrainingModel& sm = m_cfg.straining;
  if (!sm.enabled || p.status != ParticleStatus::mobile) return;
  const double moved = std::hypot(p.x.x() - p.pin_anchor.x(), p.x.y() - p.pin_anchor.y());
  // A held particle's place after the contact pushes varies by up to one step's travel: the drift
  // moves it up to max_step_fraction radii into its contacts and a deposit pushes it back along
  // the line of centres, not the way it came (a refused move at the walls returns it exactly). So
  // the anchor allows at least one step's travel, else a fast particle held by deposits (0.5 a
  // per step in the micromodel scenes against a quarter radius) restarts its clock again and again.
  const bool anchored = !std::isnan(p.pinned_since) && moved <= std::max(sm.anchor_fraction, m_cfg.max_step_fraction) * m_radius;
  if (!anchored) p.pinned_since = std::numeric_limits<double>::quiet_NaN();
  if (!pinned) return;
  if (!anchored) {
    p.pinned_since = t;
    p.pin_anchor = p.x;
    return;
  }
  if (t - p.pinned_since >= sm.time * (1 - 1e-12)) {
    p.status = ParticleStatus::deposited;
    p.held_by = Surface::strained;
    p.secondary = false;
  }
}

double OverdampedEngine::oneWallCos() const {
  // Smooth grain walls: push normals within the contour's normal accuracy are one wall. Other
  // walls (pixel edges, closed squares, analytic fields) are exact: every pair counts, as before.
  static const double kCos = std::cos(kSmoothWallOneWallDeg * 3.14159265358979323846 / 180);
  return m_grid && m_grid->smoothWalls() ? kCos : 2.0;
}

bool OverdampedEngine::heldByDeposits(const ParticleState& p, int i, Worker& w) const {
  if (!m_cfg.straining.enabled || p.status != ParticleStatus::mobile || (m_touch[i] & kDeposit) == 0) return false;
  const double a = m_radius;
  const Vec2 u(p.v.x(), p.v.y());
  if (u.norm() * a < m_model.diffusivity()) return false;  // diffusion, not the flow, decides
  // In-plane contact normals, from each deposit touched in this step's contact sweeps to the
  // particle (one per deposit, at its final position), and the nearest wall's when the wall is
  // within one step's travel (max_step_fraction radii: the drift presses it there again next step).
  std::vector<Vec2>& normals = w.normals;  // reused: no allocation per contact
  normals.clear();
  const auto range = std::equal_range(m_deposit_contacts.begin(), m_deposit_contacts.end(), std::pair<int, int>(i, 0),
                                      [](const std::pair<int, int>& l, const std::pair<int, int>& r) { return l.first < r.first; });
  int last = -1;
  for (auto it = range.first; it != range.second; ++it) {
    if (it->second == last) continue;
    last = it->second;
    const Vec3& q = m_particles[it->second].x;
    const Vec2 n(p.x.x() - q.x(), p.x.y() - q.y());
    if (n.norm() > 1e-9 * a) normals.push_back(n / n.norm());
  }
  // The deposits' normals are real spheres': only wall-wall pairs would be thinned (there is one wall normal at most).
  const std::size_t first_wall = normals.size();
  const FlowField& flow = *w.flow;
  if (!flow.isSolid(p.x.x(), p.x.y()) && flow.wallDistance(p.x.x(), p.x.y()) < (1 + m_cfg.max_step_fraction) * a)
    normals.push_back(flow.wallNormal(p.x.x(), p.x.y()));
  return heldAgainst(u, normals, first_wall, oneWallCos());
}

void OverdampedEngine::decideAttachment(ParticleState& p, std::uint8_t touched, const Worker& w) {
  const auto& at = m_cfg.attachment;
  if (!(at.capture_distance > 0)) return;
  const FlowField& flow = *w.flow;
  const HydroModel& model = *w.model;
  const double a = m_radius, cd = at.capture_distance;
  const double h = flow.depth(p.x.x(), p.x.y());
  const bool on_bottom = at.bottom && ((touched & kBottom) != 0 || p.x.z() - a <= cd);
  const bool on_top = at.top && ((touched & kTop) != 0 || h - p.x.z() - a <= cd);
  const bool on_grain = at.grains && ((touched & kGrain) != 0 || flow.wallDistance(p.x.x(), p.x.y()) - a <= cd);
  const bool on_deposit = at.deposited && (touched & kDeposit) != 0;
  const auto hold = [&](Surface s) {
    p.status = ParticleStatus::deposited;
    p.held_by = s;
  };
  if (at.rule == AttachmentModel::Rule::dlvo) {
    // One draw per arrival and surface type. An arrival is an encounter with the surface from the
    // bulk: after a rejection the particle must first leave to beyond the release distance
    // (AttachmentModel::release_distance, default one radius) before a new arrival at that surface
    // draws again. ASSUMPTION: alpha (IFBL) and the Maxwell fraction are per encounter from outside
    // the surface force's range; a particle lingering near the surface is one encounter however
    // often its path crosses the capture distance (those crossings multiply as dt^-1/2). Hysteresis
    // between two separated levels makes the count of arrivals a property of the path, not the step.
    const std::pair<Surface, bool> near[] = {{Surface::deposit, on_deposit}, {Surface::grain, on_grain}, {Surface::bottom, on_bottom}, {Surface::top, on_top}};
    const double release = releaseDistance();
    for (const auto& [s, is_near] : near) {
      const auto bit = static_cast<std::uint8_t>(1u << static_cast<unsigned>(s));
      if ((p.rejected & bit) != 0 && !is_near && (release <= cd || beyondRelease(p, s, release, flow)))
        p.rejected = static_cast<std::uint8_t>(p.rejected & ~bit);
    }
    const bool spatial = m_patches.size > 0;
    for (const auto& [s, is_near] : near) {
      const auto bit = static_cast<std::uint8_t>(1u << static_cast<unsigned>(s));
      if (!is_near) continue;
      // Patches placed in space: a particle within the capture distance of the glass attaches in
      // the primary minimum whenever its contact point lies on a favourable cell, at its arrival
      // or at any later step (resting, rolling or translating in the secondary minimum).
      if (spatial && favourablePatchAt(s, p.x, flow)) {
        p.secondary = false;
        return hold(s);
      }
      if ((p.rejected & bit) != 0) continue;
      if (dlvoArrival(p, s, *chemistry(s), model)) return hold(s);
      p.rejected = static_cast<std::uint8_t>(p.rejected | bit);
    }
    // Caught in a secondary minimum the local shear did not let hold it (p.secondary while mobile,
    // p.held_by the surface): it translates along that surface in the well and is held as soon as
    // the shear lets the well hold it (low-velocity regions: Torkzaban, Bradford & Walker 2007);
    // it leaves the well when it leaves that surface's capture distance.
    if (p.secondary) {
      bool in_well = false;
      for (const auto& [s, is_near] : near) in_well = in_well || (s == p.held_by && is_near);
      if (!in_well) {
        p.secondary = false;
        p.held_by = Surface::none;
      } else if (secondaryHolds(p, p.held_by, *chemistry(p.held_by), model)) {
        hold(p.held_by);
      }
    }
    return;
  }
  bool plate = on_bottom || on_top;
  // Torque balance (optional): a particle the shear would roll off the plate stays mobile.
  if (plate && at.torque_balance) plate = model.plateAdhesionHolds(p.x, on_bottom);
  // Attachment efficiency: one draw per arrival on a plate; a rejected particle rolls on until it
  // leaves the capture distance (then a later arrival draws again).
  if (at.plate_efficiency < 1) {
    if (!on_bottom && !on_top) p.plate_rejected = false;
    if (plate && p.plate_rejected) plate = false;
    else if (plate && arrivalDraw(p.id, ++p.plate_arrivals) >= at.plate_efficiency) {
      p.plate_rejected = true;
      plate = false;
    }
  }
  // Torque balance on grain walls and deposits (optional): held only where the contact adhesion
  // withstands the local shear; otherwise the particle moves on and is checked again next step.
  bool deposit = on_deposit, grain = on_grain;
  if (at.surface_torque_balance) {
    if (deposit) deposit = model.surfaceAdhesionHolds(p.x, model.contactAdhesion(true));
    if (grain) grain = model.surfaceAdhesionHolds(p.x, model.contactAdhesion(false));
  }
  if (deposit) hold(Surface::deposit);
  else if (plate) hold(on_bottom ? Surface::bottom : Surface::top);
  else if (grain) hold(Surface::grain);
}

double OverdampedEngine::releaseDistance() const {
  const double r = m_cfg.attachment.release_distance;
  return r < 0 ? m_radius : r;
}

bool OverdampedEngine::beyondRelease(const ParticleState& p, Surface s, double release, const FlowField& flow) const {
  const double a = m_radius;
  switch (s) {
    case Surface::bottom: return p.x.z() - a > release;
    case Surface::top: return flow.depth(p.x.x(), p.x.y()) - p.x.z() - a > release;
    case Surface::grain: return !flow.isSolid(p.x.x(), p.x.y()) && flow.wallDistance(p.x.x(), p.x.y()) - a > release;
    case Surface::deposit: {
      // No deposited centre within 2 a + release.
      const double d = 2 * a + release;
      return !anyDepositNear(p.x, d, [&](int j) { return (m_particles[j].x - p.x).norm() <= d; });
    }
    default: return true;
  }
}

bool OverdampedEngine::dlvoArrival(ParticleState& p, Surface s, const SurfaceChemistry& sc, const HydroModel& model) {
  double u = arrivalDraw(p.id, ++p.arrivals);
  // Patchwise heterogeneity of the glass (Song, Johnson & Elimelech 1994; deposits are latex): the
  // arrival lands on a favourable patch with probability lambda and attaches in the primary
  // minimum; otherwise the same draw, rescaled to [0, 1) on the rest, decides by the unfavourable
  // rule below (lambda = 0: the draw is left as it is).
  // With patches placed in space (m_patches) the favourable cells were checked before the arrival
  // (decideAttachment): an arrival that reaches here is on an unfavourable cell, and its draw goes
  // to the unfavourable rule unscaled.
  const double lambda = s == Surface::deposit || m_patches.size > 0 ? 0.0 : m_cfg.attachment.favourable_fraction;
  if (lambda > 0) {
    if (u < lambda) {
      p.secondary = false;
      return true;
    }
    u = (u - lambda) / (1 - lambda);
  }
  if (u < sc.alpha) {  // over the barrier into the primary minimum
    p.secondary = false;
    return true;
  }
  // Not over the barrier: captured in the secondary minimum with the Maxwell probability
  // (the same draw, rescaled to [0, 1) on the rest of the interval); a particle that is not
  // stays in whatever well it was in.
  if (sc.alpha >= 1 || (u - sc.alpha) / (1 - sc.alpha) >= sc.secondary_capture) return false;
  // In the well of s: held there only if the well withstands the local shear, else it
  // translates in it (decideAttachment checks again every step).
  p.secondary = true;
  p.held_by = s;
  return secondaryHolds(p, s, sc, model);
}

bool OverdampedEngine::secondaryHolds(const ParticleState& p, Surface s, const SurfaceChemistry& sc, const HydroModel& model) const {
  // Held at a distance by the well's attraction alone: only while that pull-off force holds
  // against the local shear's torque, on plates, grain walls and deposits alike.
  const bool plate = s == Surface::bottom || s == Surface::top;
  return plate ? model.plateAdhesionHolds(p.x, s == Surface::bottom, nullptr, sc.secondary_force)
               : model.surfaceAdhesionHolds(p.x, sc.secondary_force);
}

bool OverdampedEngine::overlapsDeposit(const ParticleState& p, const std::vector<int>& fresh) const {
  // Tolerance: the contact sweeps stop at 4 passes; 1e-3 radii is far below any length that matters.
  const double dmin = 2 * m_radius * (1 - 1e-3);
  const auto hit = [&](int j) { return &m_particles[j] != &p && (m_particles[j].x - p.x).norm() < dmin; };
  for (const int j : fresh)
    if (hit(j)) return true;
  return anyDepositNear(p.x, 2 * m_radius, hit);
}

double OverdampedEngine::arrivalDraw(std::int64_t id, std::uint32_t arrival) const {
  // splitmix64 of (seed, particle, arrival): independent of the step size and of the order in
  // which particles are visited, so runs and resumed runs draw the same.
  const std::uint64_t z = splitmix64(m_cfg.seed * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint64_t>(id) * 0xBF58476D1CE4E5B9ULL ^
                                     (static_cast<std::uint64_t>(arrival) << 40));
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

void OverdampedEngine::resolveContacts() {
  const double a = m_radius, d = 2 * a;

  m_start.resize(m_mobile.size());
  for (std::size_t k = 0; k < m_mobile.size(); ++k) m_start[k] = m_particles[m_mobile[k]].x;
  // A few Heyes-Melrose sweeps: each removes every overlap found; new ones made
  // by a push are caught by the next sweep. Dilute scenes need one. Mobile
  // particles are indexed per sweep, as (cell key, index) pairs sorted by key
  // then index in one buffer for all sweeps; deposited ones sit in a persistent
  // hash (they never move), so the cost scales with the mobile count only.
  m_deposit_contacts.clear();
  std::vector<std::pair<std::int64_t, int>> cells;
  cells.reserve(m_mobile.size());
  for (int sweep = 0; sweep < 4; ++sweep) {
    cells.clear();
    for (const int i : m_mobile)
      if (m_particles[i].status == ParticleStatus::mobile) cells.emplace_back(cellKey(m_particles[i].x), i);
    std::sort(cells.begin(), cells.end());
    // The keys in `cells`: a column the filter says is empty skips the search.
    KeyFilter<4096> occupied;
    for (const auto& c : cells) occupied.add(c.first);
    bool any = false;
    const auto visit = [&](ParticleState& p, int i, int j) {
      if (j == i) return;
      auto& q = m_particles[j];
      if (q.status == ParticleStatus::left) return;
      if (q.status == ParticleStatus::mobile && j < i) return;  // each mobile pair once
      Vec3 r = p.x - q.x;
      const double dist = r.norm();
      if (dist >= d || (std::abs(r.x()) >= d)) return;
      if (dist < 1e-12 * d) r = Vec3(0, 0, 1); else r /= dist;
      const double overlap = d - std::max(dist, 0.0);
      any = true;
      if (q.status == ParticleStatus::deposited) {
        p.x += r * overlap;
        m_clamp[i] = 1;
        m_touch[i] |= kDeposit;  // an arrival on a deposit, decided after the sweeps
        if (m_cfg.straining.enabled) m_deposit_contacts.emplace_back(i, j);
      } else {
        p.x += 0.5 * overlap * r;
        q.x -= 0.5 * overlap * r;
        m_clamp[i] = m_clamp[j] = 1;
      }
    };
    for (const int i : m_mobile) {
      auto& p = m_particles[i];
      if (p.status != ParticleStatus::mobile) continue;
      const double cs4 = 4 * a;
      const auto x0 = static_cast<std::int64_t>(std::floor((p.x.x() - d) / cs4)), x1 = static_cast<std::int64_t>(std::floor((p.x.x() + d) / cs4));
      const auto y0 = static_cast<std::int64_t>(std::floor((p.x.y() - d) / cs4)), y1 = static_cast<std::int64_t>(std::floor((p.x.y() + d) / cs4));
      for (auto ix = x0; ix <= x1; ++ix)
        for (auto iy = y0; iy <= y1; ++iy) {
          const std::int64_t key = columnKey(ix, iy);
          if (occupied.mayHold(key)) {
            const auto first = std::lower_bound(cells.begin(), cells.end(), std::pair<std::int64_t, int>(key, std::numeric_limits<int>::min()));
            for (auto it = first; it != cells.end() && it->first == key; ++it) visit(p, i, it->second);
          }
          if (!m_dep_filter.mayHold(key)) continue;
          if (const auto it = m_dep_cells.find(key); it != m_dep_cells.end())
            for (int j : it->second) visit(p, i, j);
        }
    }
    // Pushes may have moved particles into the plates: clamp again (no capture here
    // beyond the plate rule, which the next step's wall check applies). Only the particles pushed
    // in this sweep, and in the first those the wall step left where the clamp moves them
    // (m_clamp): the clamp of any other leaves its z as it is (z already in [a, h - a] at the same
    // (x, y); std::clamp returns it unchanged), or as the previous sweep's clamp left it.
    for (const int i : m_mobile) {
      if (!m_clamp[i]) continue;
      m_clamp[i] = 0;
      auto& p = m_particles[i];
      if (p.status == ParticleStatus::left) continue;
      const double h = m_flow->depth(p.x.x(), p.x.y());
      p.x.z() = std::clamp(p.x.z(), a, std::max(a, h - a));
    }
    if (!any) break;
  }
}

void OverdampedEngine::afterContacts(std::size_t k, Worker& w) {
  auto& p = m_particles[m_mobile[k]];
  if (p.status != ParticleStatus::left) {
    // A push must not carry a particle into a grain or through a throat narrower
    // than itself (particles jammed at a throat push each other): such a push is
    // undone in the plane, leaving the overlap to later steps.
    const FlowField& flow = *w.flow;
    const double a = m_radius;
    const auto fits = [&](const Vec3& x) { return !flow.isSolid(x.x(), x.y()) && flow.wallDistance(x.x(), x.y()) >= 0.9 * a; };
    const Vec3& start = m_start[k];
    if (p.x != start && !fits(p.x) && fits(start)) {
      p.x.x() = start.x();
      p.x.y() = start.y();
    }
    if (m_cfg.straining.enabled && p.status == ParticleStatus::mobile) backOutOfDeposits(p, w);
  }
  reflectAtMirrors(p);  // the contact pushes can carry one across a plane
}

void OverdampedEngine::backOutOfDeposits(ParticleState& p, Worker& w) const {
  // Overlaps the sweeps leave with deposits: a particle stacked over or under a deposit at a
  // throat (in-plane offset ~0) is pushed along z, where the plate (or a deposit on its other
  // side) stops it, and in the plane the walls undo the push. It is moved back against its
  // in-plane drift, the way it came, by the least distance at its height that clears every
  // deposit: for a deposit at in-plane offset w and height difference dz the particle must be
  // s >= 0 along e with |w + s e|^2 >= (2a)^2 - dz^2. Kept only where the particle fits by the
  // contact pushes' rule (0.9 a from the walls, resolveContacts), at the end and halfway.
  const double a = m_radius, d = 2 * a;
  const Vec2 u(p.v.x(), p.v.y());
  if (u.norm() * a < m_model.diffusivity()) return;  // no drift to say where it came from
  if (!overlapsDeposit(p, {})) return;
  const Vec2 e = -u / u.norm();
  const double reach = 2 * d;  // the farthest a back-out goes: past one deposit and a second behind it
  std::vector<int>& near = w.near;
  near.clear();
  const double r = d + reach;
  anyDepositNear(p.x, r, [&](int j) {
    const Vec3 w = p.x - m_particles[j].x;
    if (std::abs(w.z()) < d && w.head<2>().norm() < r) near.push_back(j);
    return false;
  });
  double s = 0;
  bool clear = false;
  for (int pass = 0; pass < 8 && !clear; ++pass) {
    double next = s;
    for (const int j : near) {
      const Vec3 w3 = p.x - m_particles[j].x;
      const Vec2 w = w3.head<2>();
      const double c2 = d * d - w3.z() * w3.z(), b = w.dot(e);
      const double disc = b * b - (w.squaredNorm() - c2);
      if (disc <= 0) continue;  // the line at this height passes clear of it
      const double lo = -b - std::sqrt(disc), hi = -b + std::sqrt(disc);  // inside for lo < s < hi
      if (next > lo && next < hi - 1e-9 * a) next = hi;
    }
    clear = next == s;
    s = next;
  }
  if (!clear || s <= 0 || s > reach) return;
  const Vec2 from(p.x.x(), p.x.y()), to = from + s * e, mid = from + 0.5 * s * e;
  for (const Vec2& q : {to, mid})
    if (w.flow->isSolid(q.x(), q.y()) || w.flow->wallDistance(q.x(), q.y()) < 0.9 * a) return;
  p.x.x() = to.x();
  p.x.y() = to.y();
}

void OverdampedEngine::saveState(CheckpointWriter& w) const {
  w.putString("overdamped-v4");
  w.put(m_t);
  w.put(m_stats);
  w.put<std::uint64_t>(m_particles.size());
  for (const auto& p : m_particles) {
    w.put(p.id);
    w.put(p.x.x()); w.put(p.x.y()); w.put(p.x.z());
    w.put(p.v.x()); w.put(p.v.y()); w.put(p.v.z());
    w.put(static_cast<std::uint8_t>(p.status));
    w.put(p.t_event);
    w.put(p.plate_arrivals);
    w.put(static_cast<std::uint8_t>(p.plate_rejected));
    w.put(p.arrivals);
    w.put(p.rejected);
    w.put(static_cast<std::uint8_t>(p.held_by));
    w.put(static_cast<std::uint8_t>(p.secondary));
    w.put(p.pinned_since);
    w.put(p.pin_anchor.x()); w.put(p.pin_anchor.y()); w.put(p.pin_anchor.z());
  }
  w.putVector(m_dep_order);
  w.putString(gsl_rng_name(m_rng->r));
  w.putBytes(gsl_rng_state(m_rng->r), gsl_rng_size(m_rng->r));
}

void OverdampedEngine::loadState(CheckpointReader& r) {
  // v3: written before straining (no pinned clock; every particle starts unpinned).
  const std::string format = r.getString();
  if (format != "overdamped-v4" && format != "overdamped-v3") throw std::runtime_error("checkpoint " + r.name() + ": not an overdamped-engine state");
  const bool with_pins = format == "overdamped-v4";
  m_t = r.get<double>();
  m_stats = r.get<EngineStats>();
  const auto n = r.get<std::uint64_t>();
  std::vector<ParticleState> ps(n);
  for (auto& p : ps) {
    p.id = r.get<std::int64_t>();
    const double x = r.get<double>(), y = r.get<double>(), z = r.get<double>();
    const double vx = r.get<double>(), vy = r.get<double>(), vz = r.get<double>();
    p.x = Vec3(x, y, z);
    p.v = Vec3(vx, vy, vz);
    const auto st = r.get<std::uint8_t>();
    if (st > 2) throw std::runtime_error("checkpoint " + r.name() + ": bad particle status");
    p.status = static_cast<ParticleStatus>(st);
    p.t_event = r.get<double>();
    p.plate_arrivals = r.get<std::uint32_t>();
    p.plate_rejected = r.get<std::uint8_t>() != 0;
    p.arrivals = r.get<std::uint32_t>();
    p.rejected = r.get<std::uint8_t>();
    const auto held = r.get<std::uint8_t>();
    if (held > static_cast<std::uint8_t>(Surface::strained)) throw std::runtime_error("checkpoint " + r.name() + ": bad surface of a deposit");
    p.held_by = static_cast<Surface>(held);
    p.secondary = r.get<std::uint8_t>() != 0;
    if (with_pins) {
      p.pinned_since = r.get<double>();
      const double ax = r.get<double>(), ay = r.get<double>(), az = r.get<double>();
      p.pin_anchor = Vec3(ax, ay, az);
    }
  }
  const auto order = r.getVector<int>();
  if (r.getString() != gsl_rng_name(m_rng->r)) throw std::runtime_error("checkpoint " + r.name() + ": other random generator");
  const std::string state = r.getString();
  if (state.size() != gsl_rng_size(m_rng->r)) throw std::runtime_error("checkpoint " + r.name() + ": random generator state has the wrong size");
  std::memcpy(gsl_rng_state(m_rng->r), state.data(), state.size());
  m_particles = std::move(ps);
  m_mobile.clear();
  m_dep_cells.clear();
  m_dep_filter = {};
  m_dep_order.clear();
  for (int i = 0; i < static_cast<int>(m_particles.size()); ++i)
    if (m_particles[i].status == ParticleStatus::mobile) m_mobile.push_back(i);
  for (const int i : order) {
    if (i < 0 || i >= static_cast<int>(m_particles.size()) || m_particles[i].status != ParticleStatus::deposited)
      throw std::runtime_error("checkpoint " + r.name() + ": deposit order does not match the particles");
    indexDeposited(i);
  }
}

nlohmann::json OverdampedEngine::describe() const {
  const auto& c = m_cfg;
  nlohmann::json by_surface = nlohmann::json::object();
  std::int64_t secondary = 0;
  for (const auto& p : m_particles)
    if (p.status == ParticleStatus::deposited) {
      by_surface[surfaceName(p.held_by)] = by_surface.value(surfaceName(p.held_by), 0) + 1;
      secondary += p.secondary ? 1 : 0;
    }
  nlohmann::json j = {{"engine", "overdamped"},
          {"diameter_um", c.particle.diameter * 1e6},
          {"density_kg_m3", c.particle.density},
          {"tau_p_s", relaxationTime(c.fluid, c.particle)},
          {"diffusivity_m2_s", m_model.diffusivity()},
          {"settling_speed_m_s", settlingSpeed(c.fluid, c.particle, c.gravity)},
          {"brownian", c.brownian},
          {"wall_hindrance", c.wall_hindrance},
          {"faxen_curvature", c.faxen_curvature},
          {"parallel_drag", !c.wall_hindrance             ? "none (Stokes)"
                            : m_model.nearContactDrag() ? "Goldman-Cox-Brenner lubrication joined to Faxen (free to rotate)"
                                                        : "Faxen series"},
          {"near_wall_shear_lag", m_model.nearWallShear()},
          {"capture_distance_um", c.attachment.capture_distance * 1e6},
          {"hamaker_J", c.attachment.hamaker},
          {"surface_force", c.attachment.rule == AttachmentModel::Rule::dlvo
                                ? "DLVO sphere-plate force of the chemistry (the attachment's profile) towards sticky plates and grains"
                                : "van der Waals A a / (6 gap^2) towards sticky plates and grains"},
          {"plate_attachment", c.attachment.torque_balance ? "torque balance (GCB shear vs DMT adhesion)" : "capture distance"},
          {"surface_attachment", c.attachment.surface_torque_balance ? "torque balance (GCB shear at the centre's speed vs DMT adhesion)"
                                                                     : "capture distance"},
          {"plate_attachment_efficiency", c.attachment.plate_efficiency},
          {"adhesion_separation_nm", c.attachment.adhesion_separation * 1e9},
          {"contact_modulus_GPa", c.attachment.contact_modulus * 1e-9},
          {"max_step_fraction", c.max_step_fraction},
          {"drift_integrator", c.heun_drift ? "heun" : "euler"},
          {"threads", m_threads},
          {"threads_note", fmt::format("per-particle loops (drift, move and wall step; after the contact sweeps, which stay on one "
                                       "thread: undo, back-out, attachment, straining) on {} thread(s) when {} or more particles are "
                                       "mobile; results bit for bit one thread's", m_threads, kMinParallelMobile)},
          {"seed", c.seed},
          {"contacts", "hard spheres, Heyes-Melrose overlap removal"},
          {"ito_drift", c.ito_drift},
          {"attachment_rule", c.attachment.rule == AttachmentModel::Rule::dlvo ? "dlvo" : "capture"},
          {"straining", c.straining.enabled ? nlohmann::json{{"time_s", c.straining.time}, {"anchor_radii", std::max(c.straining.anchor_fraction, c.max_step_fraction)}}
                                            : nlohmann::json("off")},
          {"wall_tolerance_radii", kWallTolerance},
          {"deposited_by_surface", by_surface}};
  if (c.mirror_sides)
    j["sides"] = fmt::format("mirror planes at y = {:.6g} and {:.6g} um: particles reflected there, never deposited there; no images of "
                             "other particles", m_flow->bounds().y0 * 1e6, m_flow->bounds().y1 * 1e6);
  if (m_plate_chem) {
    j["dlvo"] = {{"assumed_chemistry",
                  "the experiment gives no solution chemistry: ionic strength, valence, zeta potentials and Hamaker constant are "
                  "assumptions (case inputs), not measurements"},
                 {"plates_and_grains", m_plate_chem->describe()},
                 {"arrival",
                  {{"rule", "one draw per arrival; after a rejection the next arrival at that surface counts only once the particle's gap "
                            "has exceeded the release distance (an encounter from the bulk, not a crossing of the capture distance)"},
                   {"release_distance_um", releaseDistance() * 1e6}}},
                 {"charge_heterogeneity",
                  {{"model", m_patches.size > 0
                                 ? "patchwise (Song, Johnson & Elimelech 1994): plates and grains only; patches placed in space: cells of "
                                   "side patch_size on the plates' (x, y) and in (x, y, z) at the grain walls, each favourable with "
                                   "probability favourable_fraction (a hash of the seed, surface and cell); a particle within the capture "
                                   "distance attaches in the primary minimum as soon as its contact point is on a favourable cell, "
                                   "checked every step; an arrival on an unfavourable cell goes to the unfavourable rule"
                                 : "patchwise (Song, Johnson & Elimelech 1994): plates and grains only; per arrival, a favourable patch "
                                   "(primary-minimum attachment) with probability favourable_fraction, else the unfavourable rule"},
                   {"placement", m_patches.size > 0 ? "spatial" : "per arrival"},
                   {"patch_size_um", c.attachment.patch_size * 1e6},
                   {"favourable_fraction", c.attachment.favourable_fraction},
                   {"primary_attachment_efficiency", patchwiseEfficiency(c.attachment.favourable_fraction, m_plate_chem->alpha)},
                   {"assumption", "the experiment does not constrain the favourable fraction: a case input, not a measurement"}}},
                 {"deposits", m_deposit_chem->describe()},
                 {"deposited_in_secondary_minimum", secondary}};
  }
  return j;
}

}  // namespace mmval::particles
