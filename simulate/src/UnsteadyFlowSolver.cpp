#include "mmval/simulate/UnsteadyFlowSolver.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "CoupledSystem.hpp"
#include "FlowOperator.hpp"
#include "ProjectionStep.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::simulate {

struct UnsteadyFlowSolver::Impl {
  std::unique_ptr<FlowOperator> op;
  SolverOptions opt;
  UnsteadyOptions uopt;
  MPI_Comm comm;
  FlowStats stats;
  StepStats steps;
  std::unique_ptr<CoupledSystem> sys;   ///< coupled method
  std::unique_ptr<ProjectionStep> proj;  ///< projection method
  std::vector<double> un, unm1, old;  ///< u^n, u^{n-1}, history term of the last step
  double t = 0, coef = 0;
  bool warned = false;
  /// Where the lagged LU came from, for an exact restart: the transient coefficient and the
  /// linearisation state of the first factorisation (it fixed the ordering) and of the last (the
  /// LU in use). factor_count 0: none yet.
  long long factor_count = 0;
  double first_factor_coef = 0, last_factor_coef = 0;
  std::vector<double> first_factor_state, last_factor_state;

  Impl(FlowProblem prob, SolverOptions o, UnsteadyOptions u, MPI_Comm c) : opt(std::move(o)), uopt(u), comm(c) {
    if (!(uopt.max_courant > 0 && uopt.max_courant <= 4))
      throw std::invalid_argument(fmt::format("max_courant must be in (0, 4], got {}", uopt.max_courant));
    if (!(uopt.max_growth > 1 && uopt.max_growth <= 2.4))
      throw std::invalid_argument(fmt::format("max_growth must be in (1, 2.4] (BDF2 zero-stability), got {}", uopt.max_growth));
    if (!(uopt.blowup_factor > 1)) throw std::invalid_argument("blowup_factor must be > 1");
    prob.inertia = true;
    op = std::make_unique<FlowOperator>(std::move(prob));
    stats.unknowns = op->unknowns();
    stats.cells = static_cast<long long>(op->nx()) * op->ny();
    un.assign(static_cast<std::size_t>(op->unknowns()), 0.0);
    unm1 = un;
    old = un;
    if (uopt.projection_sweeps < 1 || uopt.projection_sweeps > 50)
      throw std::invalid_argument(fmt::format("projection_sweeps must be in [1, 50], got {}", uopt.projection_sweeps));
    if (!(uopt.projection_rtol > 0 && uopt.projection_rtol < 1e-2))
      throw std::invalid_argument(fmt::format("projection_rtol must be in (0, 1e-2), got {}", uopt.projection_rtol));
    makeSolver();
  }

  /// The linear solver of the steps for the current operator (after construction and setShape).
  void makeSolver() {
    if (uopt.method == UnsteadyMethod::projection) {
      proj = std::make_unique<ProjectionStep>(*op, comm, uopt.projection_rtol, uopt.projection_rtol, uopt.projection_rotational);
      op->setTransient(coef, coef > 0 ? &old : nullptr);  // ProjectionStep read the rows' mass with its own
      return;
    }
    if (sys) {
      sys->invalidate();
      return;
    }
    sys = std::make_unique<CoupledSystem>(*op, opt, comm);
    // The step matrix changes by O(dt): reuse its LU factorisation across steps (GMRES, tolerance 1e-10).
    sys->setLaggedFactorisation(8, 1e-10);
  }

  int nvel() const { return op->pressureOffset(); }

  double velocityScale() const { return uopt.velocity_scale > 0 ? uopt.velocity_scale : op->maxPrescribedVelocity(); }

  double maxVelocity(const std::vector<double>& s) const {
    double m = 0;
    for (int k = 0; k < nvel(); ++k) m = std::max(m, std::abs(s[static_cast<std::size_t>(k)]));
    return m;
  }

  /// max over cells of |u|/dx + |v|/dy (face maxima), 1/s.
  double courantRate(const std::vector<double>& s) const {
    const Axis& X = op->problem().x;
    const Axis& Y = op->problem().y;
    double r = 0;
    for (int j = 0; j < op->ny(); ++j)
      for (int i = 0; i < op->nx(); ++i) {
        const double uu = std::max(std::abs(s[static_cast<std::size_t>(op->unknown(0, i, j))]), std::abs(s[static_cast<std::size_t>(op->unknown(0, i + 1, j))]));
        const double vv = std::max(std::abs(s[static_cast<std::size_t>(op->unknown(1, j, i))]), std::abs(s[static_cast<std::size_t>(op->unknown(1, j + 1, i))]));
        r = std::max(r, uu / X.width(i) + vv / Y.width(j));
      }
    return r;
  }

  double stableTimeStep() const {
    double rate = courantRate(un);
    if (steps.steps == 0) {
      // Before the flow starts the boundary velocity sets the scale.
      const double h = std::min(op->problem().x.minWidth(), op->problem().y.minWidth());
      rate = std::max(rate, velocityScale() / h);
    }
    return rate > 0 ? uopt.max_courant / rate : std::numeric_limits<double>::infinity();
  }

  double step(double dt_max) {
    if (!(dt_max > 0) || !std::isfinite(dt_max)) throw std::invalid_argument(fmt::format("time step must be positive and finite, got {}", dt_max));
    const double stable = stableTimeStep();  // the Courant limit of the current velocity
    double dt = std::min(dt_max, stable);
    if (steps.steps > 0) dt = std::min(dt, uopt.max_growth * steps.last_dt);
    const double w = steps.steps == 0 ? 0.0 : dt / steps.last_dt;
    const double a0 = (1 + 2 * w) / (1 + w), a1 = 1 + w, a2 = w * w / (1 + w);
    const double rho = op->problem().density;
    std::vector<double> next(un.size()), hist(un.size(), 0.0);
    for (int k = 0; k < nvel(); ++k) {
      const std::size_t q = static_cast<std::size_t>(k);
      hist[q] = rho / dt * (a1 * un[q] - a2 * unm1[q]);
      next[q] = (1 + w) * un[q] - w * unm1[q];  // advecting velocity u*
    }
    for (std::size_t q = static_cast<std::size_t>(nvel()); q < un.size(); ++q) next[q] = un[q];
    const double prev_coef = coef;
    coef = rho * a0 / dt;
    op->setTransient(coef, &hist);
    const double rate_before = std::isfinite(stable) ? uopt.max_courant / stable : 0.0;
    const int factorisations_before = sys ? sys->factorisations() : 0;
    std::vector<double> basis;  // the state this step's matrix is linearised at (the coupled method's lagged LU)
    if (sys) basis = next;
    try {
      if (proj) {
        // The first step sweeps until its pressure has settled to 1e-8 (at most 30 sweeps).
        const bool first = steps.steps == 0;
        proj->step(*op, coef, hist, next, stats, first ? 30 : uopt.projection_sweeps, first ? 1e-8 : 0.0);
        const ProjectionTimings& pt = proj->timings();
        steps.velocity_seconds = pt.velocity_seconds;
        steps.pressure_seconds = pt.pressure_seconds;
        steps.velocity_iterations = pt.velocity_iterations;
        steps.pressure_iterations = pt.pressure_iterations;
      } else {
        sys->solve(*op, Linearisation::picard, next, stats);
      }
      if (sys && sys->factorisations() > factorisations_before) {
        if (factor_count == 0) {
          first_factor_coef = coef;
          first_factor_state = basis;
        }
        ++factor_count;
        last_factor_coef = coef;
        last_factor_state = std::move(basis);
      }
    } catch (const std::runtime_error& e) {
      coef = prev_coef;  // the last good state stays in place
      op->setTransient(coef, &old);
      const auto* failure = dynamic_cast<const FlowFailure*>(&e);
      if (failure == nullptr) throw;  // a PETSc error: not the flow's fault
      throw FlowFailure(fmt::format("unsteady flow failed at t = {:.6g} s (step {}, dt = {:.3g} s): {}; the grid cannot carry this flow", t, steps.steps + 1,
                                    dt, failure->cause()),
                        "refine the grid or lower the Courant limit");
    }
    const double vmax = maxVelocity(next), scale = velocityScale();
    if (scale > 0 && vmax > uopt.blowup_factor * scale) {
      coef = prev_coef;
      op->setTransient(coef, &old);
      throw FlowFailure(fmt::format("unsteady flow diverged at t = {:.6g} s (step {}, dt = {:.3g} s): max |u| = {:.3g} m/s is more than {} x "
                                    "the velocity scale {:.3g} m/s; the grid cannot carry this Reynolds number",
                                    t + dt, steps.steps + 1, dt, vmax, uopt.blowup_factor, scale),
                        "refine the grid or lower the Courant limit");
    }
    old.swap(hist);
    op->setTransient(coef, &old);
    unm1.swap(un);
    un.swap(next);
    t += dt;
    ++steps.steps;
    steps.last_dt = dt;
    steps.last_courant = dt * rate_before;
    steps.max_courant = std::max(steps.max_courant, steps.last_courant);
    return dt;
  }

  int advance(double dt) {
    if (!(dt > 0) || !std::isfinite(dt)) throw std::invalid_argument(fmt::format("advance: dt must be positive and finite, got {} s", dt));
    const double t_end = t + dt;
    int n = 0;
    bool reduced = false;
    while (t_end - t > 1e-12 * dt) {
      const double remaining = t_end - t;
      double limit = stableTimeStep();
      if (steps.steps > 0) limit = std::min(limit, uopt.max_growth * steps.last_dt);
      const double sub = std::ceil(remaining / limit * (1 - 1e-12));
      if (sub > 1) reduced = true;
      const double h = remaining / std::max(1.0, sub);
      // The Courant limit is re-evaluated inside step(); a velocity jump may shorten this step.
      const double taken = step(h);
      if (taken < h * (1 - 1e-12)) reduced = true;
      ++n;
    }
    if (reduced && n > 1) {
      ++steps.reduced_steps;
      steps.warning = fmt::format("requested dt = {:.3g} s exceeds the Courant limit {} (dt_max ~ {:.3g} s): taken in {} steps", dt, uopt.max_courant,
                                  dt / n, n);
      if (!warned && PetscSession::rank() == 0) spdlog::warn("fluid: {}", steps.warning);
      warned = true;
    }
    return n;
  }
};

namespace {
// 2: with the lagged LU's origin (state 1 restarted to the GMRES tolerance only).
// 3: with the projection method's last pressure increment (empty for the coupled method).
constexpr const char* kStateFormat = "mmval-unsteady-state-3";
}

void UnsteadyFlowSolver::saveState(CheckpointWriter& w) const {
  const Impl& s = *m;
  w.putString(kStateFormat);
  w.put<std::int64_t>(s.op->unknowns());
  w.put(s.t);
  w.put(s.coef);
  w.put(s.warned);
  w.put<std::int64_t>(s.steps.steps);
  w.put<std::int64_t>(s.steps.reduced_steps);
  w.put(s.steps.last_dt);
  w.put(s.steps.last_courant);
  w.put(s.steps.max_courant);
  w.putString(s.steps.warning);
  w.put<std::int64_t>(s.stats.linear_iterations);
  w.put(s.stats.assemble_seconds);
  w.put(s.stats.solve_seconds);
  w.putVector(s.un);
  w.putVector(s.unm1);
  w.putVector(s.old);
  w.put<std::int64_t>(s.factor_count);
  w.put(s.sys ? s.sys->refactorPending() : false);
  w.put(s.first_factor_coef);
  w.put(s.last_factor_coef);
  w.putVector(s.first_factor_state);
  w.putVector(s.last_factor_state);
  w.putVector(s.proj ? s.proj->lastIncrement() : std::vector<double>{});
}

void UnsteadyFlowSolver::loadState(CheckpointReader& r) {
  Impl& s = *m;
  if (r.getString() != kStateFormat) throw std::runtime_error(fmt::format("checkpoint {}: not an unsteady-flow state of this mmval", r.name()));
  const auto n = r.get<std::int64_t>();
  if (n != s.op->unknowns())
    throw std::runtime_error(fmt::format("checkpoint {}: a state of {} unknowns, but this grid has {}", r.name(), n, s.op->unknowns()));
  // Everything is read before anything is set, so a truncated checkpoint leaves the solver as it was.
  const double t = r.get<double>(), coef = r.get<double>();
  const bool warned = r.get<bool>();
  StepStats steps;
  steps.steps = r.get<std::int64_t>();
  steps.reduced_steps = r.get<std::int64_t>();
  steps.last_dt = r.get<double>();
  steps.last_courant = r.get<double>();
  steps.max_courant = r.get<double>();
  steps.warning = r.getString();
  const auto iterations = r.get<std::int64_t>();
  const double assemble = r.get<double>(), solve = r.get<double>();
  const auto vectorOf = [&](std::size_t expected) {
    auto x = r.getVector<double>();
    if (x.size() != expected) throw std::runtime_error(fmt::format("checkpoint {}: a vector of {} values where {} belong", r.name(), x.size(), expected));
    return x;
  };
  std::array<std::vector<double>, 3> v;
  for (auto& x : v) x = vectorOf(s.un.size());
  const auto factor_count = r.get<std::int64_t>();
  const bool refactor_pending = r.get<bool>();
  const double first_coef = r.get<double>(), last_coef = r.get<double>();
  const std::size_t basis_size = factor_count > 0 ? s.un.size() : 0;
  auto first_state = vectorOf(basis_size), last_state = vectorOf(basis_size);
  auto increment = r.getVector<double>();
  if (!increment.empty() && (!s.proj || increment.size() != s.un.size() - static_cast<std::size_t>(s.nvel())))
    throw std::runtime_error(fmt::format("checkpoint {}: a pressure increment of {} values that this solver cannot use", r.name(), increment.size()));
  s.t = t;
  s.coef = coef;
  s.warned = warned;
  s.steps = steps;
  s.stats.linear_iterations = static_cast<int>(iterations);
  s.stats.assemble_seconds = assemble;
  s.stats.solve_seconds = solve;
  s.un = std::move(v[0]);
  s.unm1 = std::move(v[1]);
  s.old = std::move(v[2]);
  s.factor_count = factor_count;
  s.first_factor_coef = first_coef;
  s.last_factor_coef = last_coef;
  s.first_factor_state = std::move(first_state);
  s.last_factor_state = std::move(last_state);
  if (s.proj) s.proj->setLastIncrement(std::move(increment));
  // Rebuild the lagged LU exactly: the first factorisation fixed the ordering, the last is in use.
  // (The projection method keeps only the state and the last pressure change, set above.)
  if (s.sys && s.factor_count > 0) {
    s.op->setTransient(s.first_factor_coef, &s.old);
    s.sys->factorise(*s.op, Linearisation::picard, s.first_factor_state);
    if (s.factor_count > 1) {
      s.op->setTransient(s.last_factor_coef, &s.old);
      s.sys->factorise(*s.op, Linearisation::picard, s.last_factor_state);
    }
  }
  if (s.sys) s.sys->setRefactorPending(s.factor_count == 0 || refactor_pending);
  s.op->setTransient(s.coef, &s.old);  // the residual body force of the restored step
}

UnsteadyFlowSolver::UnsteadyFlowSolver(FlowProblem problem, SolverOptions options, UnsteadyOptions unsteady, MPI_Comm comm) {
  PetscSession::ensure();
  m = std::make_unique<Impl>(std::move(problem), std::move(options), unsteady, comm);
}

UnsteadyFlowSolver::~UnsteadyFlowSolver() = default;

int UnsteadyFlowSolver::advance(double dt_s) { return m->advance(dt_s); }
double UnsteadyFlowSolver::step(double dt_max_s) { return m->step(dt_max_s); }
double UnsteadyFlowSolver::stableTimeStep() const { return m->stableTimeStep(); }

void UnsteadyFlowSolver::setVelocity(const std::function<Eigen::Vector2d(double, double)>& velocity) {
  const FlowOperator& op = *m->op;
  for (int d = 0; d < 2; ++d)
    for (int t = 0; t < (d == 0 ? op.ny() : op.nx()); ++t)
      for (int n = 0; n < op.normalCount(d); ++n) {
        const int r = op.unknown(d, n, t);
        if (r < 0) continue;
        const Eigen::Vector2d P = op.position(d, n, t);
        m->un[static_cast<std::size_t>(r)] = op.isFixedNode(r) ? 0.0 : velocity(P.x(), P.y())[d];
      }
  m->unm1 = m->un;
}

void UnsteadyFlowSolver::setShape(std::shared_ptr<const Shape> shape) {
  FlowProblem p = m->op->problem();
  p.shape = std::move(shape);
  m->op = std::make_unique<FlowOperator>(std::move(p));
  m->op->setTransient(m->coef, &m->old);
  m->makeSolver();
  // The matrix pattern may change with the shape: the next factorisation starts a new LU history.
  m->factor_count = 0;
}

void UnsteadyFlowSolver::setBodyForce(const Eigen::Vector2d& force) {
  m->op->setBodyForce(force);
  if (m->proj) {  // its rows keep the body force in their constant part
    m->op->setTransient(0.0, nullptr);
    m->proj->refreshRows(*m->op);
    m->op->setTransient(m->coef, &m->old);
  }
}

double UnsteadyFlowSolver::time() const { return m->t; }
const StepStats& UnsteadyFlowSolver::stepStats() const { return m->steps; }
const FlowStats& UnsteadyFlowSolver::stats() const { return m->stats; }
const FlowProblem& UnsteadyFlowSolver::problem() const { return m->op->problem(); }
int UnsteadyFlowSolver::nx() const { return m->op->nx(); }
int UnsteadyFlowSolver::ny() const { return m->op->ny(); }
std::vector<BodyLoad> UnsteadyFlowSolver::bodyLoads() const { return m->op->bodyLoads(m->un); }
double UnsteadyFlowSolver::pressureAt(double x, double y) const { return m->op->pressureAt(m->un, x, y); }
double UnsteadyFlowSolver::maxRelativeDivergence() const { return m->op->maxRelativeDivergence(m->un); }
double UnsteadyFlowSolver::maxVelocity() const { return m->maxVelocity(m->un); }
Eigen::ArrayXXd UnsteadyFlowSolver::cellVelocity(int component) const { return m->op->cellVelocity(m->un, component); }
Eigen::ArrayXXd UnsteadyFlowSolver::cellSolidFraction() const { return m->op->cellSolidFraction(); }
void UnsteadyFlowSolver::fields(Eigen::ArrayXXd& u, Eigen::ArrayXXd& v, Eigen::ArrayXXd& p) const { m->op->unpack(m->un, u, v, p); }

}  // namespace mmval::simulate
