#include "mmval/particles/LiggghtsEngine.hpp"

#include <atom.h>
#include <fix_external.h>
#include <lammps.h>
#include <library.h>
#include <modify.h>
#include <universe.h>
#include <update.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace mmval::particles {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

void fluidCallback(void* self, LAMMPS_NS::bigint ntimestep, int nlocal, int* tag, double** x, double** fext) {
  static_cast<LiggghtsEngine*>(self)->applyFluidForces(static_cast<long long>(ntimestep), nlocal, tag, x, fext);
}

void ensureMpi() {
  int initialised = 0;
  MPI_Initialized(&initialised);
  if (initialised) return;
  MPI_Init(nullptr, nullptr);
  std::atexit([] {
    int finalised = 0;
    MPI_Finalized(&finalised);
    if (!finalised) MPI_Finalize();
  });
}

}  // namespace

LiggghtsEngine::LiggghtsEngine(std::shared_ptr<const FlowField> flow, SceneConfig config, MPI_Comm comm)
    : m_flow(std::move(flow)), m_cfg(std::move(config)), m_model(m_flow, m_cfg), m_comm(comm) {
  if (m_cfg.attachment.torque_balance)
    throw InputError(keyLocation("deposition.plate_rule"), "the torque balance on the plates is implemented in the overdamped engine only",
                     "torque-balance", "plate_rule = \"capture\" with LIGGGHTS, or the overdamped engine");
  if (m_cfg.attachment.surface_torque_balance)
    throw InputError(keyLocation("deposition.surface_rule"), "the torque balance on grains and deposits is implemented in the overdamped engine only",
                     "torque-balance", "surface_rule = \"capture\" with LIGGGHTS (its sjkr cohesion decides), or the overdamped engine");
  m_outlet = std::isnan(m_cfg.outlet_x) ? m_flow->bounds().x1 : m_cfg.outlet_x;
  m_setup = liggghtsSetupFor(*m_flow, m_cfg, m_outlet);
  const std::vector<std::string> commands = liggghtsSetupCommands(m_setup);  // validates; throws before LIGGGHTS starts
  ensureMpi();
  // LIGGGHTS 3.8 with -screen none segfaults once fix mesh/surface reads an STL
  // (it writes to the null screen unchecked): always use files.
  std::string log = m_setup.log_file.string(), screen = m_setup.screen_file.string();
  std::string a0 = "mmval", a1 = "-log", a3 = "-screen", a5 = "-echo", a6 = "none";
  char* argv[] = {a0.data(), a1.data(), log.data(), a3.data(), screen.data(), a5.data(), a6.data()};
  lammps_open(7, argv, m_comm, &m_lmp);
  if (!m_lmp) throw std::runtime_error("lammps_open failed");
  auto* lmp = static_cast<LAMMPS_NS::LAMMPS*>(m_lmp);
  // The string the log header prints between "LIGGGHTS (" and ")"; kept as is if its form is new.
  const std::string printed = lmp->universe->version != nullptr ? lmp->universe->version : "";
  m_version = liggghtsVersionFromHeader(printed).value_or(printed);
  for (const auto& c : commands) command(c);
  command("fix mmval_nve all nve/sphere");
  // After the wall fixes: the callback sees pair and wall forces already summed in f.
  command("fix mmval_fluid all external pf/callback 1 1");
  const int ifix = lmp->modify->find_fix("mmval_fluid");
  if (ifix < 0) throw std::logic_error("fix mmval_fluid not found after creation");
  static_cast<LAMMPS_NS::FixExternal*>(lmp->modify->fix[ifix])->set_callback(fluidCallback, this);
  m_step_base = static_cast<long long>(lmp->update->ntimestep);
  m_dt0 = m_setup.dt;
}

LiggghtsEngine::~LiggghtsEngine() {
  if (m_lmp) lammps_close(m_lmp);
}

void LiggghtsEngine::command(const std::string& c) { lammps_command(m_lmp, const_cast<char*>(c.c_str())); }

void LiggghtsEngine::insert(const std::vector<Vec3>& positions) {
  if (positions.empty()) return;
  std::vector<ParticleState> trial = m_particles;
  for (std::size_t k = 0; k < positions.size(); ++k) {
    const std::string why = insertionProblem(*m_flow, m_model.radius(), positions[k], trial);
    if (!why.empty()) throw InputError(keyLocation("particles.insert"), fmt::format("particle {} of this insertion cannot be placed: {}", k, why));
    ParticleState s;
    s.id = static_cast<std::int64_t>(trial.size()) + 1;
    s.x = positions[k];
    trial.push_back(s);
  }
  const auto cmds = liggghtsInsertCommands(m_setup, positions, static_cast<long>(m_particles.size()) + 1);  // validates
  for (const auto& c : cmds) command(c);
  m_particles = std::move(trial);
  m_status.resize(m_particles.size(), static_cast<std::uint8_t>(ParticleStatus::mobile));
  m_event.resize(m_particles.size(), kInf);
  m_need_setup = true;
  const int natoms = lammps_get_natoms(m_lmp);
  if (natoms != static_cast<int>(m_particles.size()))
    throw std::logic_error(fmt::format("LIGGGHTS holds {} atoms, mmval inserted {}", natoms, m_particles.size()));
}

void LiggghtsEngine::setVelocity(std::int64_t id, const Vec3& v) {
  if (id < 1 || id > static_cast<std::int64_t>(m_particles.size()) || !v.allFinite())
    throw std::invalid_argument(fmt::format("setVelocity: no particle {} or velocity not finite", id));
  if (m_need_setup) {
    command("run 0");  // atoms get their arrays and map entries
    m_need_setup = false;
  }
  auto* atom = static_cast<LAMMPS_NS::LAMMPS*>(m_lmp)->atom;
  const int i = atom->map(static_cast<int>(id));
  if (i >= 0 && i < atom->nlocal)
    for (int c = 0; c < 3; ++c) atom->v[i][c] = v[c];
  m_particles[static_cast<std::size_t>(id) - 1].v = v;
}

void LiggghtsEngine::applyFluidForces(long long ntimestep, int nlocal, int* tag, double** x, double** fext) {
  auto* lmp = static_cast<LAMMPS_NS::LAMMPS*>(m_lmp);
  LAMMPS_NS::Atom* atom = lmp->atom;
  double** v = atom->v;
  double** f = atom->f;
  double** omega = atom->omega;
  double** torque = atom->torque;
  const double* radius = atom->radius;
  const double* rmass = atom->rmass;
  const double dt = lmp->update->dt;
  const double t = m_t_base + static_cast<double>(ntimestep - m_step_base) * dt;
  const double mu = m_cfg.fluid.viscosity;
  const auto& flow = *m_flow;
  for (int i = 0; i < nlocal; ++i) {
    const std::size_t k = static_cast<std::size_t>(tag[i]) - 1;
    const double m = rmass[i], a = radius[i], inertia = 0.4 * m * a * a;
    const Vec3 xi(x[i][0], x[i][1], x[i][2]);
    if (k < m_status.size() && m_status[k] == static_cast<std::uint8_t>(ParticleStatus::mobile)) {
      if (xi.x() > m_outlet) {
        m_status[k] = static_cast<std::uint8_t>(ParticleStatus::left);
        m_event[k] = t;
      } else if (m_model.captured(xi)) {
        m_status[k] = static_cast<std::uint8_t>(ParticleStatus::deposited);
        m_event[k] = t;
      }
    }
    if (k >= m_status.size() || m_status[k] != static_cast<std::uint8_t>(ParticleStatus::mobile)) {
      // Frozen: cancel every force and stop the particle within this step.
      for (int c = 0; c < 3; ++c) {
        fext[i][c] = -f[i][c] - m * v[i][c] / dt;
        torque[i][c] = -inertia * omega[i][c] / dt;
      }
      continue;
    }
    const Vec3 u = m_model.fluidVelocity(xi) + m_model.shearLag(xi);  // the free sphere's velocity near a plate (Goldman, Cox & Brenner)
    const Vec3 fb = m_model.force(xi);
    const double h = flow.depth(xi.x(), xi.y());
    const auto [par, perp] = m_model.hindrance(xi.z(), h);
    const double k0 = 6.0 * kPi * mu * a;
    for (int c = 0; c < 3; ++c) {
      const double K = k0 * (c < 2 ? par : perp);
      const double target = u[c] + (fb[c] + f[i][c]) / K;
      const double total = m / dt * (1.0 - std::exp(-K * dt / m)) * (target - v[i][c]);
      fext[i][c] = total - f[i][c];
    }
    // Spin relaxes to half the vorticity of the depth profile: omega_f = (-du_y/dz, du_x/dz, 0) / 2.
    const Vec2 um = flow.meanVelocity(xi.x(), xi.y());
    const double dprof = h > 0 ? 6.0 * (h - 2.0 * xi.z()) / (h * h) : 0.0;
    const double wf[3] = {-0.5 * um.y() * dprof, 0.5 * um.x() * dprof, 0.0};
    const double kr = 8.0 * kPi * mu * a * a * a;
    const double er = 1.0 - std::exp(-kr * dt / inertia);
    for (int c = 0; c < 3; ++c) {
      const double target = wf[c] + torque[i][c] / kr;
      torque[i][c] = inertia / dt * er * (target - omega[i][c]);
    }
  }
}

void LiggghtsEngine::retime() {
  double vmax = 0;
  for (const auto& p : m_particles)
    if (p.status == ParticleStatus::mobile && p.v.allFinite()) vmax = std::max(vmax, p.v.norm());
  const double dt = std::min(m_dt0, liggghtsTimeStep(m_cfg.particle, m_cfg.rayleigh_fraction, 2 * vmax));
  if (!(std::isfinite(dt) && dt > 0) || std::abs(dt - m_setup.dt) <= 1e-9 * m_setup.dt) return;
  auto* lmp = static_cast<LAMMPS_NS::LAMMPS*>(m_lmp);
  m_t_base = m_t;
  m_step_base = static_cast<long long>(lmp->update->ntimestep);
  m_setup.dt = dt;
  command(fmt::format("timestep {:.17g}", dt));
}

void LiggghtsEngine::advance(double t_end) {
  if (m_particles.empty()) {
    // Nothing to integrate, and LIGGGHTS 3.8 ends the process on a run without atoms
    // ("Atom sorting has bin size = 0.0", exit 1): only the clock moves.
    const long long n = std::llround((t_end - m_t) / m_setup.dt);
    if (n > 0) m_t += static_cast<double>(n) * m_setup.dt;
    m_t_base = m_t;
    m_step_base = static_cast<long long>(static_cast<LAMMPS_NS::LAMMPS*>(m_lmp)->update->ntimestep);
    return;
  }
  const auto t0 = std::chrono::steady_clock::now();
  retime();
  const long long n = std::llround((t_end - m_t) / m_setup.dt);
  long long done = 0;
  while (done < n) {
    const long long chunk = std::min<long long>(n - done, 100000000LL);
    command(m_need_setup ? fmt::format("run {}", chunk) : fmt::format("run {} pre no post no", chunk));
    m_need_setup = false;
    done += chunk;
  }
  if (n > 0) {
    m_t += static_cast<double>(n) * m_setup.dt;
    m_stats.steps += n;
    m_stats.particle_steps += n * static_cast<long long>(m_particles.size());
  }
  m_stats.last_dt = m_setup.dt;
  m_stats.min_dt = std::min(m_stats.min_dt, m_setup.dt);
  m_stats.max_dt = std::max(m_stats.max_dt, m_setup.dt);
  gather();
  m_stats.wall_seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void LiggghtsEngine::gather() {
  if (m_particles.empty()) return;
  // Status and event times: each rank updated its own atoms.
  MPI_Allreduce(MPI_IN_PLACE, m_status.data(), static_cast<int>(m_status.size()), MPI_UNSIGNED_CHAR, MPI_MAX, m_comm);
  MPI_Allreduce(MPI_IN_PLACE, m_event.data(), static_cast<int>(m_event.size()), MPI_DOUBLE, MPI_MIN, m_comm);
  auto* lmp = static_cast<LAMMPS_NS::LAMMPS*>(m_lmp);
  const auto* atom = lmp->atom;
  std::vector<double> mine;
  mine.reserve(static_cast<std::size_t>(atom->nlocal) * 7);
  for (int i = 0; i < atom->nlocal; ++i) {
    mine.push_back(static_cast<double>(atom->tag[i]));
    for (int c = 0; c < 3; ++c) mine.push_back(atom->x[i][c]);
    for (int c = 0; c < 3; ++c) mine.push_back(atom->v[i][c]);
  }
  int ranks = 1;
  MPI_Comm_size(m_comm, &ranks);
  std::vector<int> counts(ranks), displs(ranks, 0);
  const int count = static_cast<int>(mine.size());
  MPI_Allgather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, m_comm);
  for (int r = 1; r < ranks; ++r) displs[r] = displs[r - 1] + counts[r - 1];
  std::vector<double> all(static_cast<std::size_t>(displs.back() + counts.back()));
  MPI_Allgatherv(mine.data(), count, MPI_DOUBLE, all.data(), counts.data(), displs.data(), MPI_DOUBLE, m_comm);
  for (std::size_t j = 0; j + 6 < all.size(); j += 7) {
    const auto id = static_cast<std::size_t>(std::llround(all[j]));
    if (id < 1 || id > m_particles.size()) continue;
    auto& p = m_particles[id - 1];
    p.x = Vec3(all[j + 1], all[j + 2], all[j + 3]);
    p.v = Vec3(all[j + 4], all[j + 5], all[j + 6]);
  }
  for (std::size_t k = 0; k < m_particles.size(); ++k) {
    m_particles[k].status = static_cast<ParticleStatus>(m_status[k]);
    m_particles[k].t_event = std::isfinite(m_event[k]) ? m_event[k] : std::numeric_limits<double>::quiet_NaN();
  }
}

nlohmann::json LiggghtsEngine::describe() const {
  const auto& c = m_cfg;
  int ranks = 1;
  MPI_Comm_size(m_comm, &ranks);
  return {{"engine", "liggghts"},
          {"diameter_um", c.particle.diameter * 1e6},
          {"density_kg_m3", c.particle.density},
          {"youngs_modulus_Pa", c.particle.youngs_modulus},
          {"tau_p_s", relaxationTime(c.fluid, c.particle)},
          {"dt_s", m_setup.dt},
          {"rayleigh_time_s", rayleighTime(c.particle)},
          {"cohesion_energy_density_J_m3", c.cohesion_energy_density},
          {"wall_hindrance", c.wall_hindrance},
          {"capture_distance_um", c.attachment.capture_distance * 1e6},
          {"ranks", ranks},
          {"contacts", "Hertz + tangential history (LIGGGHTS 3.8)"},
          {"drag", "exponential integrator in fix external callback, every DEM step"}};
}

}  // namespace mmval::particles
