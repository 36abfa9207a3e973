// Rigid bodies moving through creeping flow, resolved on the fluid grid.
//
// The coupling mode for particles that span many cells (a resolved immersed
// boundary once a particle spans enough cells). Each body's no-slip
// condition is its rigid motion, imposed by the sharp immersed boundary of
// FlowOperator (nodes inside the body take U + spin x r, cut viscous fluxes
// take it at the surface point), and the force and torque on it are the
// momentum residual of the unmodified balance at the nodes it touches: the
// force the immersed boundary has to apply to hold the rigid motion, as in
// Shirgaonkar, MacIver & Patankar (2009), taken from the discrete balance.
//
// Stokes flow has no memory and is linear, so a free body needs no time
// history of the fluid: the loads are L = L0 + R X, with L0 the loads of the
// bodies held at rest in the driven flow and R the resistance matrix (one
// solve per unit translation and rotation of each body, drive off). The
// motion of force- and torque-free bodies (or bodies under external loads:
// gravity, contact) is X = -R^-1 (L0 + F_ext). All 3 m + 1 solves share one
// matrix: the geometry is the same, only right-hand sides change, so the
// direct solver factorises once per geometry (then GMRES on the factors,
// tolerance 1e-12, converges in one iteration per right-hand side).
#pragma once
#include <memory>
#include <vector>

#include <Eigen/Core>
#include <mpi.h>

#include "mmval/simulate/FlowSolver.hpp"

namespace mmval::simulate {

/// Several shapes as one: bodies are numbered through the parts in order
/// (part 0's bodies first). Where parts overlap the first part wins.
class ShapeUnion final : public Shape {
 public:
  explicit ShapeUnion(std::vector<std::shared_ptr<const Shape>> parts);
  int bodyAt(double x, double y) const override;
  double distanceAlong(double x, double y, int axis, int sign, double max_distance) const override;
  int bodies() const override { return m_total; }
  Eigen::Vector2d centre(int body) const override;

 private:
  std::vector<std::shared_ptr<const Shape>> m_parts;
  std::vector<int> m_first;  ///< first body index of each part
  int m_total = 0;
};

/// Faxen's series (as given by Happel & Brenner, Low Reynolds Number Hydrodynamics, 1965) for a
/// cylinder of radius a moving midway between two plane walls 2 l apart through fluid at rest:
/// drag per unit length = -R U with R = 4 pi mu / (ln(l/a) - 0.9157 + 1.7244 k^2 - 1.7302 k^4
/// + 2.4056 k^6 - 4.5913 k^8), k = a / l, in N s / m2. Truncated at k^8: a reference for k <~ 0.25-0.4.
double faxenCylinderResistance(double a, double l, double mu);

struct MobilityResult {
  std::vector<RigidMotion> motion;  ///< per body (held bodies: at rest)
  std::vector<BodyLoad> rest_loads; ///< hydrodynamic loads with every body held at rest in the driven flow (L0)
  Eigen::MatrixXd resistance;       ///< 3 m x 3 m over the free bodies, rows/columns (Fx, Fy, T) per body; loads per unit motion
  int solves = 0;                   ///< Stokes solves of this call
  int factorisations = 0;           ///< of the direct solver so far
};

class ResolvedStokes {
 public:
  /// problem: grid, boundaries, fluid (inertia must be off: creeping flow); its shape may be null
  /// until setShape. Throws std::invalid_argument for inertia or a non-direct linear solver.
  explicit ResolvedStokes(FlowProblem problem, SolverOptions options = {}, MPI_Comm comm = MPI_COMM_WORLD);
  ~ResolvedStokes();
  ResolvedStokes(const ResolvedStokes&) = delete;
  ResolvedStokes& operator=(const ResolvedStokes&) = delete;

  /// New body positions (same grid): the next solve refactorises.
  void setShape(std::shared_ptr<const Shape> shape);

  /// Loads on every body for prescribed rigid motions, with the outside drive scaled by `drive`
  /// (1: as in the problem; 0: the bodies' motion alone). The flow of this solve is kept for output.
  std::vector<BodyLoad> loads(const std::vector<RigidMotion>& motion, double drive = 1.0);

  /// Rigid motion of the bodies marked free such that hydrodynamic plus external loads vanish on each;
  /// the others are held at rest. external: per body (N/m and N per unit depth). Leaves the flow of
  /// the resulting motion as the current state (one more solve).
  MobilityResult freeMotion(const std::vector<BodyLoad>& external, const std::vector<bool>& free);

  const FlowProblem& problem() const;
  const FlowStats& stats() const;
  /// Face velocities and cell pressures of the last solve (layout as SteadyFlowSolver).
  void fields(Eigen::ArrayXXd& u, Eigen::ArrayXXd& v, Eigen::ArrayXXd& p) const;
  Eigen::ArrayXXd cellSolidFraction() const;
  /// Cell-centred velocity component of the last solve, ny x nx.
  Eigen::ArrayXXd cellVelocity(int component) const;
  int factorisations() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> m;
};

}  // namespace mmval::simulate
