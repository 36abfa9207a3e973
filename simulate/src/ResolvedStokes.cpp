#include "mmval/simulate/ResolvedStokes.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Dense>
#include <fmt/format.h>

#include "CoupledSystem.hpp"
#include "FlowOperator.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::simulate {

ShapeUnion::ShapeUnion(std::vector<std::shared_ptr<const Shape>> parts) : m_parts(std::move(parts)) {
  for (const auto& p : m_parts) {
    if (!p) throw std::invalid_argument("ShapeUnion: a part is null");
    m_first.push_back(m_total);
    m_total += p->bodies();
  }
}

int ShapeUnion::bodyAt(double x, double y) const {
  for (std::size_t k = 0; k < m_parts.size(); ++k) {
    const int b = m_parts[k]->bodyAt(x, y);
    if (b >= 0) return m_first[k] + b;
  }
  return -1;
}

double ShapeUnion::distanceAlong(double x, double y, int axis, int sign, double max_distance) const {
  double best = max_distance;
  // A part's own search may assume its end point is inside it: ask only parts that cover some point
  // of the segment's end, else bisect the union (the base class) for the parts that do not.
  for (const auto& p : m_parts) {
    const double ex = axis == 0 ? x + sign * max_distance : x, ey = axis == 0 ? y : y + sign * max_distance;
    if (p->bodyAt(ex, ey) >= 0) best = std::min(best, p->distanceAlong(x, y, axis, sign, max_distance));
  }
  if (best < max_distance) return best;
  return Shape::distanceAlong(x, y, axis, sign, max_distance);
}

Eigen::Vector2d ShapeUnion::centre(int body) const {
  for (std::size_t k = m_parts.size(); k-- > 0;)
    if (body >= m_first[k]) return m_parts[k]->centre(body - m_first[k]);
  throw std::out_of_range("ShapeUnion: no such body");
}

double faxenCylinderResistance(double a, double l, double mu) {
  constexpr double kPi = 3.14159265358979323846;
  const double k = a / l;
  return 4 * kPi * mu / (std::log(l / a) - 0.9157 + 1.7244 * k * k - 1.7302 * std::pow(k, 4) + 2.4056 * std::pow(k, 6) - 4.5913 * std::pow(k, 8));
}

struct ResolvedStokes::Impl {
  FlowProblem base;
  SolverOptions opt;
  MPI_Comm comm;
  std::unique_ptr<FlowOperator> op;
  std::unique_ptr<CoupledSystem> sys;
  FlowStats stats;
  std::vector<double> state;
  int solves = 0;

  void build() {
    op = std::make_unique<FlowOperator>(base);
    if (!sys) {
      sys = std::make_unique<CoupledSystem>(*op, opt, comm);
      // One matrix, many right-hand sides: the factors of the first solve serve the rest.
      sys->setLaggedFactorisation(12, 1e-12);
    }
    // A moved body changes which nodes are solid: the old factors are then a poor preconditioner
    // (measured: GMRES ran out of its 96 iterations at every move of half a cell), so refactorise.
    sys->invalidate();
    state.assign(static_cast<std::size_t>(op->unknowns()), 0.0);
  }

  std::vector<BodyLoad> solveLoads(const std::vector<RigidMotion>& motion, double drive) {
    op->setBodyMotion(motion);
    op->setDriveScale(drive);
    std::fill(state.begin(), state.end(), 0.0);
    sys->solve(*op, Linearisation::stokes, state, stats);
    ++solves;
    return op->bodyLoads(state);
  }
};

ResolvedStokes::ResolvedStokes(FlowProblem problem, SolverOptions options, MPI_Comm comm) {
  if (problem.inertia) throw std::invalid_argument("ResolvedStokes solves creeping flow: the problem must have inertia off");
  if (options.linear != "direct") throw std::invalid_argument("ResolvedStokes reuses one factorisation for many right-hand sides: it needs the direct linear solver");
  PetscSession::ensure();
  m = std::make_unique<Impl>();
  m->base = std::move(problem);
  m->opt = std::move(options);
  m->comm = comm;
  m->build();
  m->stats.unknowns = m->op->unknowns();
  m->stats.cells = static_cast<long long>(m->op->nx()) * m->op->ny();
}

ResolvedStokes::~ResolvedStokes() = default;

void ResolvedStokes::setShape(std::shared_ptr<const Shape> shape) {
  m->base.shape = std::move(shape);
  m->base.body_motion.clear();
  m->build();
}

std::vector<BodyLoad> ResolvedStokes::loads(const std::vector<RigidMotion>& motion, double drive) { return m->solveLoads(motion, drive); }

MobilityResult ResolvedStokes::freeMotion(const std::vector<BodyLoad>& external, const std::vector<bool>& free) {
  const Shape* shape = m->base.shape.get();
  if (shape == nullptr) throw std::invalid_argument("freeMotion: there are no bodies");
  const int nb = shape->bodies();
  if (static_cast<int>(external.size()) != nb || static_cast<int>(free.size()) != nb)
    throw std::invalid_argument(fmt::format("freeMotion: {} bodies but {} external loads and {} free flags", nb, external.size(), free.size()));
  std::vector<int> idx;
  for (int k = 0; k < nb; ++k)
    if (free[static_cast<std::size_t>(k)]) idx.push_back(k);
  MobilityResult res;
  const int solves0 = m->solves;
  const std::vector<RigidMotion> rest(static_cast<std::size_t>(nb));
  res.rest_loads = m->solveLoads(rest, 1.0);
  const int n = 3 * static_cast<int>(idx.size());
  res.resistance = Eigen::MatrixXd::Zero(n, n);
  Eigen::VectorXd rhs(n);
  for (std::size_t c = 0; c < idx.size(); ++c) {
    const int k = idx[c];
    const BodyLoad& L0 = res.rest_loads[static_cast<std::size_t>(k)];
    const BodyLoad& E = external[static_cast<std::size_t>(k)];
    rhs.segment<3>(3 * static_cast<int>(c)) << -(L0.force.x() + E.force.x()), -(L0.force.y() + E.force.y()), -(L0.torque + E.torque);
    for (int dof = 0; dof < 3; ++dof) {
      std::vector<RigidMotion> unit = rest;
      if (dof < 2) unit[static_cast<std::size_t>(k)].velocity[dof] = 1.0;
      else unit[static_cast<std::size_t>(k)].spin = 1.0;
      const std::vector<BodyLoad> L = m->solveLoads(unit, 0.0);
      for (std::size_t r = 0; r < idx.size(); ++r) {
        const BodyLoad& Lr = L[static_cast<std::size_t>(idx[r])];
        res.resistance.block<3, 1>(3 * static_cast<int>(r), 3 * static_cast<int>(c) + dof) << Lr.force.x(), Lr.force.y(), Lr.torque;
      }
    }
  }
  Eigen::VectorXd X = Eigen::VectorXd::Zero(n);
  if (n > 0) {
    // Force per m/s and torque per rad/s differ by ~radius^2: equilibrate the diagonal before the solve.
    Eigen::VectorXd D(n);
    for (int i = 0; i < n; ++i) {
      const double a = std::abs(res.resistance(i, i));
      if (!(a > 0) || !std::isfinite(a))
        throw std::runtime_error("freeMotion: a body feels no resistance to its own motion (it covers no grid node: refine the grid or enlarge the body)");
      D(i) = 1.0 / std::sqrt(a);
    }
    const Eigen::MatrixXd S = D.asDiagonal() * res.resistance * D.asDiagonal();
    const auto lu = S.fullPivLu();
    if (!lu.isInvertible()) throw std::runtime_error("freeMotion: the resistance matrix is singular");
    X = D.asDiagonal() * lu.solve(D.asDiagonal() * rhs);
    if (!X.allFinite()) throw std::runtime_error("freeMotion: the body motion is not finite");
  }
  res.motion = rest;
  for (std::size_t c = 0; c < idx.size(); ++c) {
    RigidMotion& M = res.motion[static_cast<std::size_t>(idx[c])];
    M.velocity = {X(3 * static_cast<int>(c)), X(3 * static_cast<int>(c) + 1)};
    M.spin = X(3 * static_cast<int>(c) + 2);
  }
  m->solveLoads(res.motion, 1.0);  // the flow of the free motion, for output
  res.solves = m->solves - solves0;
  res.factorisations = m->sys->factorisations();
  return res;
}

const FlowProblem& ResolvedStokes::problem() const { return m->op->problem(); }
const FlowStats& ResolvedStokes::stats() const { return m->stats; }
void ResolvedStokes::fields(Eigen::ArrayXXd& u, Eigen::ArrayXXd& v, Eigen::ArrayXXd& p) const { m->op->unpack(m->state, u, v, p); }
Eigen::ArrayXXd ResolvedStokes::cellSolidFraction() const { return m->op->cellSolidFraction(); }
Eigen::ArrayXXd ResolvedStokes::cellVelocity(int component) const { return m->op->cellVelocity(m->state, component); }
int ResolvedStokes::factorisations() const { return m->sys->factorisations(); }

}  // namespace mmval::simulate
