// Steady Stokes flow on a staggered (MAC) Cartesian grid.
//
// Why MAC: velocities on cell faces and pressure at cell centres give an
// exactly divergence-free discrete velocity and no pressure checkerboarding,
// without the interpolation fixes a collocated grid needs.
//
// Solids are immersed by their volume fraction chi on each velocity face
// (supersampled), the paper's marker-function idea u = M u + (1 - M) v with a
// resting solid (v = 0), imposed as a Brinkman penalty mu chi / eta u with a
// small permeability eta (a fraction of h^2). A quasi-2D chip adds the
// depth-averaged friction 12 mu u / h_depth^2. The flow is driven by a mean
// pressure gradient G (a body force), periodic in x and y or periodic in x
// with no-slip walls at y = 0 and y = H.
//
// The coupled (u, v, p) saddle-point system is assembled once and solved
// with a sparse LU factorisation (Eigen). That is exact to round-off and
// fast up to ~10^5 unknowns; it scales worse than O(N) (the multigrid
// solver the issue asks for is not built yet).
#pragma once
#include <functional>

#include <Eigen/Core>

namespace mmval::stokes {

struct Problem {
  int nx = 32, ny = 32;
  double h = 1.0;                 ///< cell size, m
  bool walls_y = false;           ///< no-slip walls at y = 0 and y = ny h (else periodic in y)
  double viscosity = 1e-3;        ///< Pa s
  double pressure_gradient = 1.0; ///< G = -dp/dx driving the flow along x, Pa/m
  double depth = 0;               ///< chip depth for the Hele-Shaw friction; 0: plain 2D
  double penalty = 1e-4;          ///< eta / h^2 of the Brinkman penalty in solids
  Eigen::ArrayXXd solid_u;        ///< solid fraction at u faces, ny x nx (face i is the left face of cell i); empty: all fluid
  Eigen::ArrayXXd solid_v;        ///< solid fraction at v faces, ny x nx (face j is the bottom face of cell j)
};

struct Solution {
  Eigen::ArrayXXd u, v, p;        ///< ny x nx each
  double superficial_u = 0;       ///< mean of u over the whole domain (Darcy velocity), m/s
  double max_divergence = 0;      ///< max |div u| h / max |u|
  long long unknowns = 0;
  double assemble_seconds = 0, solve_seconds = 0;
};

/// Solid fraction of every u and v face of `p` from an indicator solid(x, y)
/// sampled s x s times over each face's control volume.
void setSolidFromIndicator(Problem& p, const std::function<bool(double, double)>& solid, int s = 8);

Solution solve(const Problem& p);

}  // namespace mmval::stokes
