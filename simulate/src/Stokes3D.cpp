#include "mmval/simulate/Stokes3D.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>
#include <petscksp.h>

#include "SolverUtil.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/simulate/Petsc.hpp"

namespace mmval::simulate {

using detail::check;
using detail::secondsSince;

namespace {

using Index3 = std::array<int, 3>;

}  // namespace

struct Stokes3DSolver::Impl {
  Stokes3DProblem pr;
  Stokes3DOptions opt;
  MPI_Comm comm = MPI_COMM_WORLD;
  Stokes3DStats st;
  Index3 N{};
  std::array<double, 3> h{};
  BoolArray solid;                      ///< ny x nx after removing isolated pores
  std::array<std::vector<int>, 3> vid;  ///< unknown of each velocity node, -1: fixed (zero)
  std::vector<int> pid;                 ///< unknown of each cell, -1: solid
  int n_vel = 0, n_all = 0;
  std::vector<double> x;  ///< solution of the free unknowns (every rank)

  // Node counts per component d: N_a + (a == d ? 1 : 0) along each axis a.
  int nodeCount(int d, int a) const { return N[static_cast<std::size_t>(a)] + (a == d ? 1 : 0); }
  int nodeLocal(int d, const Index3& a) const { return a[0] + nodeCount(d, 0) * (a[1] + nodeCount(d, 1) * a[2]); }
  int cellLocal(const Index3& c) const { return c[0] + N[0] * (c[1] + N[1] * c[2]); }
  bool solidCell(int i, int j) const { return solid(j, i); }

  /// Adjacent cells of node (d, a) along d that exist, all solid?  (*any: at least one solid)
  void adjacentSolid(int d, const Index3& a, bool& any, bool& all) const {
    any = false;
    all = true;
    for (int s = -1; s <= 0; ++s) {
      Index3 c = a;
      c[static_cast<std::size_t>(d)] += s;
      if (c[static_cast<std::size_t>(d)] < 0 || c[static_cast<std::size_t>(d)] >= N[static_cast<std::size_t>(d)]) continue;
      const bool sc = solidCell(c[0], c[1]);
      any = any || sc;
      all = all && sc;
    }
  }

  bool fixedNode(int d, const Index3& a) const {
    const int ad = a[static_cast<std::size_t>(d)], Nd = N[static_cast<std::size_t>(d)];
    if (d != 0 && (ad == 0 || ad == Nd)) return true;  // side walls (either kind) and plates: zero normal velocity
    bool any = false, all = false;
    adjacentSolid(d, a, any, all);
    return any;
  }

  void setup() {
    N = {pr.nx, pr.ny, pr.nz};
    if (pr.nx < 1 || pr.ny < 1 || pr.nz < 1) throw std::invalid_argument("the 3D grid needs at least one cell per axis");
    if (!(pr.length > 0) || !(pr.width > 0) || !(pr.depth > 0)) throw std::invalid_argument("the 3D domain needs positive length, width and depth");
    if (!(pr.viscosity > 0)) throw std::invalid_argument("the viscosity must be positive");
    if (opt.schur != "lsc" && opt.schur != "selfp" && opt.schur != "mass")
      throw std::invalid_argument("3D Schur preconditioner must be 'lsc', 'selfp' or 'mass', got '" + opt.schur + "'");
    h = {pr.length / pr.nx, pr.width / pr.ny, pr.depth / pr.nz};
    BoolArray raw = pr.solid.size() == 0 ? BoolArray::Constant(pr.ny, pr.nx, false) : pr.solid;
    if (raw.rows() != pr.ny || raw.cols() != pr.nx)
      throw std::invalid_argument(fmt::format("the 3D solid mask is {} x {}, the grid needs {} x {} (rows x columns)", raw.rows(), raw.cols(), pr.ny, pr.nx));
    const PoreSpaceReport rep = analysePoreSpace(raw);  // throws NoFlowPath
    solid = rep.solid_connected;
    st.porosity_total = rep.porosity_total;
    st.porosity_connected = rep.porosity_connected;
    st.cells = static_cast<long long>(pr.nx) * pr.ny * pr.nz;
    int next = 0;
    for (int d = 0; d < 3; ++d) {
      const Index3 cnt{nodeCount(d, 0), nodeCount(d, 1), nodeCount(d, 2)};
      vid[static_cast<std::size_t>(d)].assign(static_cast<std::size_t>(cnt[0]) * cnt[1] * cnt[2], -1);
      for (int k = 0; k < cnt[2]; ++k)
        for (int j = 0; j < cnt[1]; ++j)
          for (int i = 0; i < cnt[0]; ++i) {
            const Index3 a{i, j, k};
            if (!fixedNode(d, a)) vid[static_cast<std::size_t>(d)][static_cast<std::size_t>(nodeLocal(d, a))] = next++;
          }
    }
    n_vel = next;
    pid.assign(static_cast<std::size_t>(st.cells), -1);
    for (int k = 0; k < N[2]; ++k)
      for (int j = 0; j < N[1]; ++j)
        for (int i = 0; i < N[0]; ++i) {
          if (solidCell(i, j)) continue;
          // A fluid cell with every face fixed would leave its pressure undetermined (cannot
          // happen after the connectivity pass, which keeps only inlet-to-outlet pores).
          bool free_face = false;
          for (int d = 0; d < 3; ++d)
            for (int s = 0; s <= 1; ++s) {
              Index3 a{i, j, k};
              a[static_cast<std::size_t>(d)] += s;
              free_face = free_face || vid[static_cast<std::size_t>(d)][static_cast<std::size_t>(nodeLocal(d, a))] >= 0;
            }
          if (free_face) pid[static_cast<std::size_t>(cellLocal({i, j, k}))] = next++;
        }
    n_all = next;
    st.fluid_cells = n_all - n_vel;
    st.unknowns = n_all;
    x.assign(static_cast<std::size_t>(n_all), 0.0);
  }

  /// Options prefix: one per Schur preconditioner, so each can be tuned from the command line.
  const char* prefix() const { return opt.schur == "mass" ? "stokes3dm_" : opt.schur == "selfp" ? "stokes3ds_" : "stokes3d_"; }

  int velocityUnknown(int d, const Index3& a) const { return vid[static_cast<std::size_t>(d)][static_cast<std::size_t>(nodeLocal(d, a))]; }

  /// Momentum row of the free node (d, a): entries and right-hand side.
  double momentumRow(int d, const Index3& a, std::vector<std::pair<PetscInt, PetscScalar>>& e) const {
    const std::size_t du = static_cast<std::size_t>(d);
    const double mu = pr.viscosity;
    const int ad = a[du];
    const bool lo_open = d == 0 && ad == 0, hi_open = d == 0 && ad == N[0];
    const double len_d = (lo_open || hi_open) ? 0.5 * h[du] : h[du];
    double area_d = 1;
    for (int b = 0; b < 3; ++b)
      if (b != d) area_d *= h[static_cast<std::size_t>(b)];
    double rhs = 0, diag = 0;
    // Pressure force: p of the cell above the face minus p of the cell below, times the face area.
    Index3 c_hi = a, c_lo = a;
    c_lo[du] -= 1;
    if (hi_open) rhs -= pr.outlet_pressure * area_d;
    else e.emplace_back(pid[static_cast<std::size_t>(cellLocal(c_hi))], area_d);
    if (lo_open) rhs += pr.inlet_pressure * area_d;
    else e.emplace_back(pid[static_cast<std::size_t>(cellLocal(c_lo))], -area_d);
    // Viscous fluxes along d (normal direction): neighbours always exist unless the side is open.
    for (int s : {-1, 1}) {
      if ((s < 0 && lo_open) || (s > 0 && hi_open)) continue;  // zero normal gradient at the open boundary
      Index3 nb = a;
      nb[du] += s;
      const double c = mu * area_d / h[du];
      diag += c;
      const int q = velocityUnknown(d, nb);
      if (q >= 0) e.emplace_back(q, -c);  // else: a zero node on a surface one spacing away
    }
    // Transverse directions.
    for (int b = 0; b < 3; ++b) {
      if (b == d) continue;
      const std::size_t bu = static_cast<std::size_t>(b);
      const int o = 3 - d - b;
      const double area = len_d * h[static_cast<std::size_t>(o)], c = mu * area / h[bu];
      for (int s : {-1, 1}) {
        Index3 nb = a;
        nb[bu] += s;
        if (nb[bu] < 0 || nb[bu] >= N[bu]) {
          if (b == 2 || (b == 1 && !pr.slip_sides)) diag += 2 * c;  // no-slip wall half a spacing away
          continue;                                                 // open (x) or slip (y): no flux
        }
        const int q = velocityUnknown(d, nb);
        if (q >= 0) {
          diag += c;
          e.emplace_back(q, -c);
          continue;
        }
        bool any = false, all = false;
        adjacentSolid(d, nb, any, all);
        diag += all ? 2 * c : c;  // inside the solid: wall at the cell face, half a spacing; on its surface: one spacing
      }
    }
    e.emplace_back(velocityUnknown(d, a), diag);
    return rhs;
  }

  /// Continuity rows are scaled by mu / min(dx, dy, dz) so that their residual is a force like the
  /// momentum rows' (m3/s -> Pa m2); otherwise the relative FGMRES tolerance barely sees them.
  double rowScale() const { return pr.viscosity / std::min({h[0], h[1], h[2]}); }

  /// Continuity row of fluid cell c: + outflow through its free faces (so B = G^T up to sign and
  /// the Schur complement B A^-1 B^T is positive definite).
  void continuityRow(const Index3& c, std::vector<std::pair<PetscInt, PetscScalar>>& e) const {
    const double s = rowScale();
    for (int d = 0; d < 3; ++d) {
      double area = s;
      for (int b = 0; b < 3; ++b)
        if (b != d) area *= h[static_cast<std::size_t>(b)];
      Index3 a = c;
      const int lo = velocityUnknown(d, a);
      a[static_cast<std::size_t>(d)] += 1;
      const int hi = velocityUnknown(d, a);
      if (lo >= 0) e.emplace_back(lo, -area);
      if (hi >= 0) e.emplace_back(hi, area);
    }
    e.emplace_back(pid[static_cast<std::size_t>(cellLocal(c))], 0.0);  // explicit zero diagonal
  }

  /// Grid location of every unknown (row -> generator).
  struct Loc {
    int kind;  ///< 0..2 velocity component, 3 pressure
    Index3 a;
  };
  std::vector<Loc> locations() const {
    std::vector<Loc> loc(static_cast<std::size_t>(n_all));
    for (int d = 0; d < 3; ++d) {
      const Index3 cnt{nodeCount(d, 0), nodeCount(d, 1), nodeCount(d, 2)};
      for (int k = 0; k < cnt[2]; ++k)
        for (int j = 0; j < cnt[1]; ++j)
          for (int i = 0; i < cnt[0]; ++i) {
            const int q = velocityUnknown(d, {i, j, k});
            if (q >= 0) loc[static_cast<std::size_t>(q)] = {d, {i, j, k}};
          }
    }
    for (int k = 0; k < N[2]; ++k)
      for (int j = 0; j < N[1]; ++j)
        for (int i = 0; i < N[0]; ++i) {
          const int q = pid[static_cast<std::size_t>(cellLocal({i, j, k}))];
          if (q >= 0) loc[static_cast<std::size_t>(q)] = {3, {i, j, k}};
        }
    return loc;
  }

  void solve() {
    PetscSession::ensure();
    auto t0 = std::chrono::steady_clock::now();
    Mat A = nullptr, Sp = nullptr;
    Vec b = nullptr, xs = nullptr;
    KSP ksp = nullptr;
    IS isu = nullptr, isp = nullptr;
    auto cleanup = [&] {
      if (ksp != nullptr) KSPDestroy(&ksp);
      if (isu != nullptr) ISDestroy(&isu);
      if (isp != nullptr) ISDestroy(&isp);
      if (Sp != nullptr) MatDestroy(&Sp);
      if (A != nullptr) MatDestroy(&A);
      if (b != nullptr) VecDestroy(&b);
      if (xs != nullptr) VecDestroy(&xs);
    };
    try {
      const PetscInt n = n_all;
      check(MatCreate(comm, &A), "MatCreate");
      check(MatSetSizes(A, PETSC_DECIDE, PETSC_DECIDE, n, n), "MatSetSizes");
      check(MatSetType(A, MATAIJ), "MatSetType");
      check(MatSeqAIJSetPreallocation(A, 9, nullptr), "prealloc");
      check(MatMPIAIJSetPreallocation(A, 9, nullptr, 9, nullptr), "prealloc");
      check(MatCreateVecs(A, &xs, &b), "MatCreateVecs");
      PetscInt lo = 0, hi = 0;
      check(MatGetOwnershipRange(A, &lo, &hi), "ownership");
      const std::vector<Loc> loc = locations();
      std::vector<std::pair<PetscInt, PetscScalar>> e;
      std::vector<PetscInt> cols;
      std::vector<PetscScalar> vals;
      for (PetscInt r = lo; r < hi; ++r) {
        e.clear();
        const Loc& L = loc[static_cast<std::size_t>(r)];
        double rhs = 0;
        if (L.kind < 3) rhs = momentumRow(L.kind, L.a, e);
        else continuityRow(L.a, e);
        cols.clear();
        vals.clear();
        for (const auto& [col, val] : e) {
          cols.push_back(col);
          vals.push_back(val);
        }
        check(MatSetValues(A, 1, &r, static_cast<PetscInt>(cols.size()), cols.data(), vals.data(), ADD_VALUES), "MatSetValues");
        if (rhs != 0) check(VecSetValue(b, r, rhs, INSERT_VALUES), "VecSetValue");
      }
      check(MatAssemblyBegin(A, MAT_FINAL_ASSEMBLY), "assembly");
      check(MatAssemblyEnd(A, MAT_FINAL_ASSEMBLY), "assembly");
      check(VecAssemblyBegin(b), "vec assembly");
      check(VecAssemblyEnd(b), "vec assembly");
      st.assemble_seconds = secondsSince(t0);
      t0 = std::chrono::steady_clock::now();

      check(KSPCreate(comm, &ksp), "KSPCreate");
      check(KSPSetOptionsPrefix(ksp, prefix()), "prefix");
      check(KSPSetOperators(ksp, A, A), "KSPSetOperators");
      check(KSPSetType(ksp, KSPFGMRES), "KSPSetType");
      check(KSPGMRESSetRestart(ksp, 100), "restart");  // FGMRES keeps 2 vectors per step: bounds the memory
      check(KSPSetTolerances(ksp, opt.rtol, 1e-300, PETSC_DEFAULT, opt.max_iterations), "tolerances");
      PC pc;
      check(KSPGetPC(ksp, &pc), "KSPGetPC");
      check(PCSetType(pc, PCFIELDSPLIT), "fieldsplit");
      std::vector<PetscInt> iu, ip;
      for (PetscInt r = lo; r < hi; ++r) (r < n_vel ? iu : ip).push_back(r);
      check(ISCreateGeneral(comm, static_cast<PetscInt>(iu.size()), iu.data(), PETSC_COPY_VALUES, &isu), "IS u");
      check(ISCreateGeneral(comm, static_cast<PetscInt>(ip.size()), ip.data(), PETSC_COPY_VALUES, &isp), "IS p");
      check(PCFieldSplitSetIS(pc, "0", isu), "IS u");
      check(PCFieldSplitSetIS(pc, "1", isp), "IS p");
      check(PCFieldSplitSetType(pc, PC_COMPOSITE_SCHUR), "schur");
      check(PCFieldSplitSetSchurFactType(pc, PC_FIELDSPLIT_SCHUR_FACT_UPPER), "schur fact");
      if (opt.schur == "mass") {
        // Diagonal (lumped) pressure mass matrix / mu: every cell has the same volume.
        const PetscInt plo = std::max<PetscInt>(lo, n_vel), phi = std::max<PetscInt>(hi, n_vel);
        check(MatCreateAIJ(comm, phi - plo, phi - plo, PETSC_DETERMINE, PETSC_DETERMINE, 1, nullptr, 0, nullptr, &Sp), "Sp");
        const double m = rowScale() * h[0] * h[1] * h[2] / pr.viscosity;
        for (PetscInt r = plo; r < phi; ++r) check(MatSetValue(Sp, r - n_vel, r - n_vel, m, INSERT_VALUES), "Sp value");
        check(MatAssemblyBegin(Sp, MAT_FINAL_ASSEMBLY), "Sp assembly");
        check(MatAssemblyEnd(Sp, MAT_FINAL_ASSEMBLY), "Sp assembly");
        check(PCFieldSplitSetSchurPre(pc, PC_FIELDSPLIT_SCHUR_PRE_USER, Sp), "schur pre user");
      } else if (opt.schur == "selfp") {
        check(PCFieldSplitSetSchurPre(pc, PC_FIELDSPLIT_SCHUR_PRE_SELFP, nullptr), "selfp");
      } else {
        // LSC works on the Schur complement operator itself (A10 A01 and A10 A00 A01 products).
        check(PCFieldSplitSetSchurPre(pc, PC_FIELDSPLIT_SCHUR_PRE_SELF, nullptr), "self");
      }
      const auto def = detail::defaultOption;
      const std::string pre = std::string("-") + prefix();
      def(pre + "fieldsplit_0_ksp_type", "preonly");
      def(pre + "fieldsplit_0_pc_type", "hypre");
      def(pre + "fieldsplit_1_ksp_type", "preonly");
      def(pre + "fieldsplit_1_pc_type", opt.schur == "mass" ? "jacobi" : opt.schur == "selfp" ? "hypre" : "lsc");
      if (opt.schur == "lsc") def(pre + "fieldsplit_1_lsc_pc_type", "hypre");  // the pressure Poisson solves B B^T
      check(KSPSetFromOptions(ksp), "KSPSetFromOptions");
      check(KSPSolve(ksp, b, xs), "KSPSolve");
      KSPConvergedReason reason;
      check(KSPGetConvergedReason(ksp, &reason), "reason");
      PetscInt its = 0;
      KSPGetIterationNumber(ksp, &its);
      st.iterations = static_cast<int>(its);
      if (reason < 0)
        throw NumericalFailure(fmt::format("the 3D Stokes solve did not converge ({} after {} FGMRES iterations)", KSPConvergedReasons[reason], its),
                               "numerics.schur_3d", "another Schur-complement preconditioner (lsc, selfp, mass), or fewer cells (numerics.cells_per_pixel_3d)");
      gather(xs);
      st.solve_seconds = secondsSince(t0);
    } catch (...) {
      cleanup();
      throw;
    }
    cleanup();
  }

  void gather(Vec xs) { detail::gatherToAll(xs, n_all, x, "the 3D Stokes solution"); }

  double nodeValue(int d, const Index3& a) const {
    for (int b = 0; b < 3; ++b)
      if (a[static_cast<std::size_t>(b)] < 0 || a[static_cast<std::size_t>(b)] >= nodeCount(d, b)) throw std::out_of_range("3D velocity index outside the grid");
    const int q = velocityUnknown(d, a);
    return q >= 0 ? x[static_cast<std::size_t>(q)] : 0.0;
  }
};

Stokes3DSolver::Stokes3DSolver(Stokes3DProblem problem, Stokes3DOptions options, MPI_Comm comm) : m(std::make_unique<Impl>()) {
  m->pr = std::move(problem);
  m->opt = std::move(options);
  m->comm = comm;
  m->setup();
}

Stokes3DSolver::~Stokes3DSolver() = default;

void Stokes3DSolver::solve() { m->solve(); }

const Stokes3DProblem& Stokes3DSolver::problem() const { return m->pr; }
const Stokes3DStats& Stokes3DSolver::stats() const { return m->st; }

double Stokes3DSolver::u(int i, int j, int k) const { return m->nodeValue(0, {i, j, k}); }
double Stokes3DSolver::v(int i, int j, int k) const { return m->nodeValue(1, {i, j, k}); }
double Stokes3DSolver::w(int i, int j, int k) const { return m->nodeValue(2, {i, j, k}); }

double Stokes3DSolver::p(int i, int j, int k) const {
  if (i < 0 || j < 0 || k < 0 || i >= m->N[0] || j >= m->N[1] || k >= m->N[2]) throw std::out_of_range("3D cell index outside the grid");
  const int q = m->pid[static_cast<std::size_t>(m->cellLocal({i, j, k}))];
  return q >= 0 ? m->x[static_cast<std::size_t>(q)] : 0.0;
}

double Stokes3DSolver::flowRate(int n) const {
  double q = 0;
  for (int k = 0; k < m->N[2]; ++k)
    for (int j = 0; j < m->N[1]; ++j) q += u(n, j, k);
  return q * m->h[1] * m->h[2];
}

double Stokes3DSolver::permeability() const {
  const auto& P = m->pr;
  return P.viscosity * flowRate(P.nx) * P.length / (P.width * P.depth * (P.inlet_pressure - P.outlet_pressure));
}

double Stokes3DSolver::maxRelativeDivergence() const {
  double umax = 0, dmax = 0;
  for (int q = 0; q < m->n_vel; ++q) umax = std::max(umax, std::abs(m->x[static_cast<std::size_t>(q)]));
  const auto& h = m->h;
  for (int k = 0; k < m->N[2]; ++k)
    for (int j = 0; j < m->N[1]; ++j)
      for (int i = 0; i < m->N[0]; ++i) {
        if (m->pid[static_cast<std::size_t>(m->cellLocal({i, j, k}))] < 0) continue;
        const double div = (u(i + 1, j, k) - u(i, j, k)) / h[0] + (v(i, j + 1, k) - v(i, j, k)) / h[1] + (w(i, j, k + 1) - w(i, j, k)) / h[2];
        dmax = std::max(dmax, std::abs(div));
      }
  const double hmin = std::min({h[0], h[1], h[2]});
  return umax > 0 ? dmax * hmin / umax : dmax * hmin;
}

BoolArray coarsenMask(const BoolArray& fine, int nx, int ny) {
  const int rows = static_cast<int>(fine.rows()), cols = static_cast<int>(fine.cols());
  if (rows < 1 || cols < 1 || nx < 1 || ny < 1) throw std::invalid_argument("coarsenMask: empty mask or grid");
  Eigen::ArrayXXi solid_count = Eigen::ArrayXXi::Zero(ny, nx), count = Eigen::ArrayXXi::Zero(ny, nx);
  for (int r = 0; r < rows; ++r) {
    const int j = std::min(ny - 1, static_cast<int>((r + 0.5) * ny / rows));
    for (int c = 0; c < cols; ++c) {
      const int i = std::min(nx - 1, static_cast<int>((c + 0.5) * nx / cols));
      ++count(j, i);
      if (fine(r, c)) ++solid_count(j, i);
    }
  }
  BoolArray out(ny, nx);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      if (count(j, i) > 0) {
        out(j, i) = 2 * solid_count(j, i) > count(j, i);
      } else {
        const int r = std::min(rows - 1, static_cast<int>((j + 0.5) * rows / ny)), c = std::min(cols - 1, static_cast<int>((i + 0.5) * cols / nx));
        out(j, i) = fine(r, c);
      }
    }
  return out;
}

Stokes3DProblem maskStokes3DProblem(const BoolArray& solid, double pixel, double depth, double viscosity, double pressure_drop, double cells_per_pixel) {
  Stokes3DProblem p;
  p.length = static_cast<double>(solid.cols()) * pixel;
  p.width = static_cast<double>(solid.rows()) * pixel;
  p.depth = depth;
  p.nx = std::max(4, static_cast<int>(std::lround(solid.cols() * cells_per_pixel)));
  p.ny = std::max(4, static_cast<int>(std::lround(solid.rows() * cells_per_pixel)));
  p.solid = coarsenMask(solid, p.nx, p.ny);  // row j = y cell j (the image mirrored in y: k along x is unchanged)
  p.slip_sides = true;
  p.viscosity = viscosity;
  p.inlet_pressure = pressure_drop;
  p.outlet_pressure = 0;
  return p;
}

std::optional<double> extrapolateInDepthCells(const std::vector<int>& cells_z, const std::vector<double>& k) {
  const std::size_t n = std::min(cells_z.size(), k.size());
  if (n < 2 || cells_z[n - 1] == cells_z[n - 2]) return std::nullopt;
  const double r = static_cast<double>(cells_z[n - 1]) / cells_z[n - 2];
  return k[n - 1] + (k[n - 1] - k[n - 2]) / (r * r - 1);
}

}  // namespace mmval::simulate
