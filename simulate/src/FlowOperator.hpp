// Internal: the discrete MAC operator behind SteadyFlowSolver (no PETSc here).
// Unknowns: all u faces, then all v faces, then all cell pressures. Every
// equation row is built as linear terms plus bilinear (convective) terms so
// that the same code yields the Stokes matrix, the Picard and Newton
// linearisations, and the residual of the unmodified balance used for forces.
#pragma once
#include <array>
#include <cstddef>
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "mmval/simulate/FlowSolver.hpp"

namespace mmval::simulate {

enum class Linearisation { stokes, picard, newton };

/// A matrix's nonzero pattern, row by row (compressed rows, columns sorted within each row).
struct RowPattern {
  std::vector<int> start{0};  ///< row r's columns are cols[start[r] .. start[r + 1])
  std::vector<int> cols;
  int rows() const { return static_cast<int>(start.size()) - 1; }
};

/// Affine expression sum c_k x[idx_k] + k of at most two unknowns.
struct Lin {
  std::array<int, 2> idx{};
  std::array<double, 2> c{};
  int n = 0;
  double k = 0;
  void add(int i, double coef) {
    idx[static_cast<std::size_t>(n)] = i;
    c[static_cast<std::size_t>(n)] = coef;
    ++n;
  }
  double eval(const std::vector<double>& s) const {
    double v = k;
    for (int q = 0; q < n; ++q) v += c[static_cast<std::size_t>(q)] * s[static_cast<std::size_t>(idx[static_cast<std::size_t>(q)])];
    return v;
  }
};

struct RowTerms {
  struct Bilinear {
    double c;
    Lin a, b;
  };
  std::vector<std::pair<int, double>> lin;
  std::vector<Bilinear> bil;
  double rhs = 0;
  void clear() {
    lin.clear();
    bil.clear();
    rhs = 0;
  }
};

class FlowOperator {
 public:
  explicit FlowOperator(FlowProblem problem);

  const FlowProblem& problem() const { return m_p; }
  int nx() const { return m_N[0]; }
  int ny() const { return m_N[1]; }
  int unknowns() const { return m_off[2] + m_N[0] * m_N[1]; }
  int pressureOffset() const { return m_off[2]; }

  /// Row r of the system linearised at `state`: merged (column, value) entries, returns the right-hand side.
  double linearRow(int r, Linearisation mode, const std::vector<double>& state, RowTerms& scratch,
                   std::vector<std::pair<int, double>>& entries) const;

  /// Fixed pattern (SolverOptions::fixed_pattern), Stokes rows. The pattern this operator keeps for
  /// later geometries on the same grid: its own entries; the pressure of every cell in its
  /// continuity row (a cell whose faces all close is pinned, p = 0); and for every merged cell the
  /// entries a neighbour as its new master needs when its master closes (its continuity row: the
  /// neighbours' pressures; the neighbours' rows: its faces; its faces' rows: the neighbours' pressures).
  RowPattern keptPattern() const;
  /// Rows are returned in `pattern` (explicit zeros where this operator has no entry, so that the
  /// assembled matrix keeps that pattern); null: the operator's own entries (the default). Whether
  /// the rows fit is found while they are built: a row of linearRow that fits has exactly the
  /// pattern's entries (its own are a subset), one that does not has more (see rowFitsPattern).
  void setPattern(std::shared_ptr<const RowPattern> pattern) { m_pattern = std::move(pattern); }
  const RowPattern* pattern() const { return m_pattern.get(); }
  /// With a pattern set: whether row r as linearRow returned it (`entries`, `count` of them) lies within the pattern.
  bool rowFitsPattern(int r, std::size_t count) const {
    return m_pattern == nullptr ||
           count == static_cast<std::size_t>(m_pattern->start[static_cast<std::size_t>(r) + 1] - m_pattern->start[static_cast<std::size_t>(r)]);
  }

  /// Unsteady hook: adds coef * vol * u (coef = rho a0 / dt) to every momentum
  /// row and vol * old[r] to its right-hand side (old: rho times the history terms / dt per unknown).
  void setTransient(double coef, const std::vector<double>* old) {
    m_tcoef = coef;
    m_told = old;
  }

  /// Replaces the uniform body force (N/m3), e.g. a time-dependent drive.
  void setBodyForce(const Eigen::Vector2d& f) { m_p.body_force = f; }
  /// Replaces the bodies' rigid motions (FlowProblem::body_motion) without rebuilding the geometry:
  /// only right-hand sides change, so one factorisation serves many motions.
  void setBodyMotion(std::vector<RigidMotion> motion);
  /// Scales everything that drives the flow from outside the bodies (boundary velocities and
  /// pressures, the body force): 1 as given, 0 for the bodies' own motion alone.
  void setDriveScale(double scale) { m_drive = scale; }
  /// Largest |prescribed velocity| on the domain boundary (velocity sides), m/s.
  double maxPrescribedVelocity() const;
  /// True for velocity nodes the solver fixes (walls, inflow, sharp-solid nodes).
  bool isFixedNode(int r) const;

  std::vector<BodyLoad> bodyLoads(const std::vector<double>& s) const;
  double pressureAt(const std::vector<double>& s, double x, double y) const;
  double flowRate(const std::vector<double>& s, Side side) const;
  double superficialVelocity(const std::vector<double>& s) const;
  double maxRelativeDivergence(const std::vector<double>& s) const;
  Eigen::ArrayXXd cellVelocity(const std::vector<double>& s, int component) const;
  Eigen::ArrayXXd cellSolidFraction() const { return m_cellChi; }
  void unpack(const std::vector<double>& s, Eigen::ArrayXXd& u, Eigen::ArrayXXd& v, Eigen::ArrayXXd& p) const;
  /// Position of the velocity node of component d (0: u, 1: v) with normal index n and transverse index t.
  Eigen::Vector2d position(int d, int n, int t) const;
  /// Unknown index of a velocity node (indices wrap on periodic axes; -1 outside the domain).
  int unknown(int d, int n, int t) const;
  int cellUnknown(int i, int j) const { return m_off[2] + wrapIndex(1, j) * m_N[0] + wrapIndex(0, i); }
  /// Volume of the momentum control volume of a node (m2, per unit depth).
  double controlVolume(int d, int n, int t) const;
  /// Normal-index count of component d (faces along axis d: N or N + 1).
  int normalCount(int d) const { return m_nn[d]; }
  bool isMomentumRow(int r) const;

 private:
  enum Kind : char { kFluid, kDirichlet, kPressureLo, kPressureHi, kSolid };
  const Axis& ax(int a) const { return a == 0 ? m_p.x : m_p.y; }
  const Boundary& side(int a, bool hi) const { return m_p.boundary[static_cast<std::size_t>(a == 0 ? (hi ? 1 : 0) : (hi ? 3 : 2))]; }
  int wrapIndex(int a, int k) const { return m_per[a] ? ((k % m_N[a]) + m_N[a]) % m_N[a] : k; }
  double W(int a, int k) const;
  double C(int a, int k) const;
  double F(int a, int n) const;
  int local(int d, int n, int t) const { return t * m_nn[d] + n; }
  /// Pressure unknown of cell (k, t) along axis d, through the merge: a merged cell's faces see its master's pressure.
  int pcell(int d, int k, int t) const {
    const int u = d == 0 ? cellUnknown(k, t) : cellUnknown(t, k);
    const int m = m_master.empty() ? -1 : m_master[static_cast<std::size_t>(u - m_off[2])];
    return m < 0 ? u : m_off[2] + m;
  }
  /// Adds the four face fluxes of cell (i, j) to a continuity row.
  void cellFluxes(int i, int j, RowTerms& R) const;
  /// linearRow without the kept pattern: the row's own merged entries.
  double ownRow(int r, Linearisation mode, const std::vector<double>& state, RowTerms& R, std::vector<std::pair<int, double>>& entries) const;
  /// Sharp: merges each cell whose centre is inside a body (and which is not pinned) into a neighbour.
  void mergeCutCells();
  /// Pins one cell (its pressure to 0) in every pressure component without a pressure boundary.
  void pinClosedComponents();
  void momentumRow(int d, int n, int t, bool standard, RowTerms& R) const;
  void continuityRow(int i, int j, RowTerms& R) const;
  /// Component d at the fraction w of the link from node (n, t) to its neighbour in slot s
  /// (0: n - 1, 1: n + 1, 2: t - 1, 3: t + 1); zero beyond the surface on a fluid-solid link.
  Lin alongLink(int d, int n, int t, int s, double w) const;
  Lin advecting(int d, int n, int face_t, Kind base) const;
  Lin advected(int d, int n, int t, int t2) const;
  bool bilinearPressure(const std::vector<double>& s, double x, double y, double& out) const;
  /// Neighbour slots of a velocity node: s = 0, 1, 2, 3 for normal index n - 1, n + 1 and transverse
  /// index t - 1, t + 1. The neighbour's unknown (-1 outside a non-periodic domain) and the distance to it, m.
  int slotNeighbour(int d, int n, int t, int s) const;
  double slotLength(int d, int n, int t, int s) const;
  /// Sharp, no Hele-Shaw friction: the excess (factor - 1) of the flux of node (d, n, t)'s face when
  /// the surface of cut slot s (2, 3: the transverse neighbours) crosses that face; 0 otherwise.
  double openExcess(int d, int n, int t, int s) const;
  /// Component d of body's rigid velocity at point X (zero at rest or without motions).
  double rigidVelocity(int body, int d, const Eigen::Vector2d& X) const;
  /// Fills m_rigid and m_cutWall from m_p.body_motion.
  void applyMotion();

  FlowProblem m_p;
  std::array<int, 2> m_N{}, m_nn{};
  std::array<bool, 2> m_per{};
  std::array<int, 3> m_off{};
  std::array<std::vector<char>, 2> m_kind, m_base;
  std::array<std::vector<double>, 2> m_value, m_chi;
  std::array<std::vector<int>, 2> m_body;
  std::array<std::vector<std::array<double, 4>>, 2> m_cut;  ///< theta per neighbour slot (n-1, n+1, t-1, t+1); 0: no cut
  std::array<std::vector<double>, 2> m_rigid;                 ///< body velocity at solid (sharp) / forced (penalized) nodes
  std::array<std::vector<std::array<double, 4>>, 2> m_cutWall;  ///< body velocity at the surface point of each cut slot
  double m_drive = 1.0;                                       ///< see setDriveScale
  /// Sharp: flux of the node's face over (node value x face area), > 1 where the surface crosses the face
  /// (its fluid part with the velocity linear from the surface); 1 elsewhere.
  std::array<std::vector<double>, 2> m_open;
  /// Moving bodies only (empty at rest): sum over the crossed faces' slots of (open excess) x (surface velocity), m/s; the
  /// face flux is then A (m_open u - m_openWall): the fluid part's linear profile starts at the
  /// surface's velocity, and the covered part moves with the body.
  std::array<std::vector<double>, 2> m_openWall;
  std::array<std::vector<double>, 2> m_hface;  ///< depth field only: face depth h_f per velocity node, m
  /// Face depth of node (d, q): the face's own with a depth field, else the scalar depth.
  double faceDepth(int d, std::size_t q) const { return m_hface[d].empty() ? m_p.depth : m_hface[d][q]; }
  /// Continuity / flux weight h_f / h_ref of the face of node (d, n, t) (1 without a depth field).
  double fluxWeight(int d, int n, int t) const;
  std::vector<char> m_pinned;
  /// Sharp: master cell of a merged cell (-1: not merged), and each master's merged cells.
  std::vector<int> m_master;
  std::vector<std::vector<int>> m_merged;
  Eigen::ArrayXXd m_cellChi;  ///< ny x nx
  double m_tcoef = 0;
  const std::vector<double>* m_told = nullptr;
  std::shared_ptr<const RowPattern> m_pattern;  ///< see setPattern
};

}  // namespace mmval::simulate
