#include "mmval/stokes/Stokes.hpp"

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <vector>

#include <Eigen/Sparse>
#include <Eigen/SparseLU>

namespace mmval::stokes {

void setSolidFromIndicator(Problem& p, const std::function<bool(double, double)>& solid, int s) {
  p.solid_u = Eigen::ArrayXXd::Zero(p.ny, p.nx);
  p.solid_v = Eigen::ArrayXXd::Zero(p.ny, p.nx);
  for (int j = 0; j < p.ny; ++j)
    for (int i = 0; i < p.nx; ++i) {
      int cu = 0, cv = 0;
      for (int a = 0; a < s; ++a)
        for (int b = 0; b < s; ++b) {
          const double fx = (a + 0.5) / s - 0.5, fy = (b + 0.5) / s - 0.5;
          // u face at (i h, (j + 1/2) h); v face at ((i + 1/2) h, j h).
          cu += solid((i + fx) * p.h, (j + 0.5 + fy) * p.h) ? 1 : 0;
          cv += solid((i + 0.5 + fx) * p.h, (j + fy) * p.h) ? 1 : 0;
        }
      p.solid_u(j, i) = static_cast<double>(cu) / (s * s);
      p.solid_v(j, i) = static_cast<double>(cv) / (s * s);
    }
}

Solution solve(const Problem& p) {
  if (p.nx < 2 || p.ny < 2 || !(p.h > 0) || !(p.viscosity > 0)) throw std::invalid_argument("stokes: bad grid or viscosity");
  const auto t0 = std::chrono::steady_clock::now();
  const int nx = p.nx, ny = p.ny;
  const bool walls = p.walls_y;
  const double h = p.h, mu = p.viscosity, h2 = h * h;
  const double friction = p.depth > 0 ? 12.0 * mu / (p.depth * p.depth) : 0.0;
  const double penalty = mu / (p.penalty * h2);
  auto su = [&](int j, int i) { return p.solid_u.size() ? p.solid_u(j, i) : 0.0; };
  auto sv = [&](int j, int i) { return p.solid_v.size() ? p.solid_v(j, i) : 0.0; };
  const int nu = nx * ny, nv = nx * ny, np = nx * ny;
  auto U = [&](int j, int i) { return ((j + ny) % ny) * nx + (i + nx) % nx; };
  auto V = [&](int j, int i) { return nu + ((j + ny) % ny) * nx + (i + nx) % nx; };
  auto P = [&](int j, int i) { return nu + nv + ((j + ny) % ny) * nx + (i + nx) % nx; };
  const int n = nu + nv + np;
  std::vector<Eigen::Triplet<double>> t;
  t.reserve(static_cast<std::size_t>(n) * 7);
  Eigen::VectorXd b = Eigen::VectorXd::Zero(n);
  // x-momentum at u(j, i): -mu lap u + dp/dx + (friction + penalty chi) u = G.
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int r = U(j, i);
      double diag = 4 * mu / h2 + friction + penalty * su(j, i);
      t.emplace_back(r, U(j, i - 1), -mu / h2);
      t.emplace_back(r, U(j, i + 1), -mu / h2);
      if (walls && j == 0) diag += mu / h2;  // ghost u = -u across the bottom wall
      else t.emplace_back(r, U(j - 1, i), -mu / h2);
      if (walls && j == ny - 1) diag += mu / h2;
      else t.emplace_back(r, U(j + 1, i), -mu / h2);
      t.emplace_back(r, r, diag);
      t.emplace_back(r, P(j, i), 1 / h);
      t.emplace_back(r, P(j, i - 1), -1 / h);
      b(r) = p.pressure_gradient * (1 - su(j, i));
    }
  // y-momentum at v(j, i) (bottom face of cell j). With walls, v = 0 on j = 0.
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int r = V(j, i);
      if (walls && j == 0) {
        t.emplace_back(r, r, 1.0);
        continue;
      }
      t.emplace_back(r, r, 4 * mu / h2 + friction + penalty * sv(j, i));
      t.emplace_back(r, V(j, i - 1), -mu / h2);
      t.emplace_back(r, V(j, i + 1), -mu / h2);
      if (!(walls && j == 1)) t.emplace_back(r, V(j - 1, i), -mu / h2);
      if (!(walls && j == ny - 1)) t.emplace_back(r, V(j + 1, i), -mu / h2);
      t.emplace_back(r, P(j, i), 1 / h);
      t.emplace_back(r, P(j - 1, i), -1 / h);
    }
  // Continuity in cell (j, i); the pressure is fixed in cell (0, 0) instead of its
  // continuity row, which is redundant (the sum of all rows vanishes).
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int r = P(j, i);
      if (i == 0 && j == 0) {
        t.emplace_back(r, r, 1.0);
        continue;
      }
      t.emplace_back(r, U(j, i + 1), 1 / h);
      t.emplace_back(r, U(j, i), -1 / h);
      if (!(walls && j == ny - 1)) t.emplace_back(r, V(j + 1, i), 1 / h);
      if (!(walls && j == 0)) t.emplace_back(r, V(j, i), -1 / h);
    }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  A.makeCompressed();
  const auto t1 = std::chrono::steady_clock::now();
  Eigen::SparseLU<Eigen::SparseMatrix<double>, Eigen::COLAMDOrdering<int>> lu;
  lu.compute(A);
  if (lu.info() != Eigen::Success) throw std::runtime_error("stokes: factorisation failed (singular system: is the pore space connected?)");
  const Eigen::VectorXd x = lu.solve(b);
  if (lu.info() != Eigen::Success || !x.allFinite()) throw std::runtime_error("stokes: solve failed or produced non-finite values");
  const auto t2 = std::chrono::steady_clock::now();
  Solution s;
  s.u.resize(ny, nx);
  s.v.resize(ny, nx);
  s.p.resize(ny, nx);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      s.u(j, i) = x(U(j, i));
      s.v(j, i) = x(V(j, i));
      s.p(j, i) = x(P(j, i));
    }
  s.superficial_u = s.u.mean();
  double maxdiv = 0;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const double vn = (walls && j == ny - 1) ? 0.0 : s.v((j + 1) % ny, i);
      const double vs = (walls && j == 0) ? 0.0 : s.v(j, i);
      maxdiv = std::max(maxdiv, std::abs(s.u(j, (i + 1) % nx) - s.u(j, i) + vn - vs));
    }
  const double umax = s.u.abs().maxCoeff();
  s.max_divergence = umax > 0 ? maxdiv / umax : 0;
  s.unknowns = n;
  s.assemble_seconds = std::chrono::duration<double>(t1 - t0).count();
  s.solve_seconds = std::chrono::duration<double>(t2 - t1).count();
  return s;
}

}  // namespace mmval::stokes
