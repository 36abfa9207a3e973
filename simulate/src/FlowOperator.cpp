#include "FlowOperator.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mmval::simulate {

namespace {
constexpr double kMinTheta = 1e-2;  // cut fraction floor: keeps the stencil bounded when a node sits on the surface
}

FlowOperator::FlowOperator(FlowProblem problem) : m_p(std::move(problem)) {
  m_N = {m_p.x.cells(), m_p.y.cells()};
  if (m_N[0] < 1 || m_N[1] < 1) throw std::invalid_argument("the flow grid has no cells");
  for (int a = 0; a < 2; ++a) {
    const bool lo = side(a, false).type == BoundaryType::periodic, hi = side(a, true).type == BoundaryType::periodic;
    if (lo != hi) throw std::invalid_argument("periodic boundaries must come in pairs (west-east, south-north)");
    m_per[a] = lo;
    if (m_per[a] && m_N[a] < 2) throw std::invalid_argument("a periodic axis needs at least 2 cells");
  }
  for (const auto& b : m_p.boundary)
    if (b.type == BoundaryType::velocity && !b.velocity) throw std::invalid_argument("a velocity boundary needs a velocity profile");
  if (!(m_p.viscosity > 0) || !(m_p.density > 0)) throw std::invalid_argument("viscosity and density must be positive");
  if (m_p.method == ImmersedMethod::penalized && !(m_p.penalty > 0)) throw std::invalid_argument("the penalty must be positive");
  m_nn = {m_per[0] ? m_N[0] : m_N[0] + 1, m_per[1] ? m_N[1] : m_N[1] + 1};
  m_off = {0, m_nn[0] * m_N[1], m_nn[0] * m_N[1] + m_nn[1] * m_N[0]};
  if (m_p.depth_field.size() > 0) {
    const Eigen::ArrayXXd& hc = m_p.depth_field;
    if (hc.rows() != m_N[1] || hc.cols() != m_N[0])
      throw std::invalid_argument("the depth field must have one value per cell (ny x nx rows x columns)");
    if (!(m_p.depth > 0)) throw std::invalid_argument("a depth field needs the reference depth (FlowProblem::depth > 0)");
    if (!hc.isFinite().all() || !(hc.minCoeff() > 0)) throw std::invalid_argument("the depth field must be finite and > 0 in every cell");
    // Face depth: equal neighbours give their depth exactly (so a constant field
    // reproduces the scalar depth bit for bit); otherwise the harmonic mean of
    // h^3, the exact face conductance of a depth step at the face in the
    // friction-dominated (Reynolds) limit: (dx/2)(1/h1^3 + 1/h2^3) = dx / h_f^3.
    // Boundary faces take their one cell's depth.
    for (int d = 0; d < 2; ++d) {
      const int b = 1 - d;
      m_hface[d].assign(static_cast<std::size_t>(m_nn[d] * m_N[b]), m_p.depth);
      for (int t = 0; t < m_N[b]; ++t)
        for (int n = 0; n < m_nn[d]; ++n) {
          const int lo = m_per[d] ? wrapIndex(d, n - 1) : std::max(n - 1, 0), hi = m_per[d] ? wrapIndex(d, n) : std::min(n, m_N[d] - 1);
          const double h1 = d == 0 ? hc(t, lo) : hc(lo, t), h2 = d == 0 ? hc(t, hi) : hc(hi, t);
          m_hface[d][static_cast<std::size_t>(local(d, n, t))] =
              h1 == h2 ? h1 : std::cbrt(2.0 / (1.0 / (h1 * h1 * h1) + 1.0 / (h2 * h2 * h2)));
        }
    }
  }
  const Shape* shape = m_p.shape.get();
  const bool sharp = shape != nullptr && m_p.method == ImmersedMethod::sharp;
  const bool pen = shape != nullptr && m_p.method == ImmersedMethod::penalized;
  const int ss = std::max(1, m_p.supersample);

  for (int d = 0; d < 2; ++d) {
    const int b = 1 - d, count = m_nn[d] * m_N[b];
    m_kind[d].assign(static_cast<std::size_t>(count), kFluid);
    m_base[d].assign(static_cast<std::size_t>(count), kFluid);
    m_value[d].assign(static_cast<std::size_t>(count), 0.0);
    m_chi[d].assign(static_cast<std::size_t>(count), 0.0);
    m_body[d].assign(static_cast<std::size_t>(count), -1);
    m_cut[d].assign(static_cast<std::size_t>(count), {0, 0, 0, 0});
    m_open[d].assign(static_cast<std::size_t>(count), 1.0);
    for (int t = 0; t < m_N[b]; ++t)
      for (int n = 0; n < m_nn[d]; ++n) {
        const std::size_t q = static_cast<std::size_t>(local(d, n, t));
        const Eigen::Vector2d P = position(d, n, t);
        const int body = shape != nullptr ? shape->bodyAt(P.x(), P.y()) : -1;
        const bool blo = !m_per[d] && n == 0, bhi = !m_per[d] && n == m_N[d];
        char base = kFluid;
        if (blo || bhi) {
          const Boundary& B = side(d, bhi);
          switch (B.type) {
            case BoundaryType::no_slip:
            case BoundaryType::slip: base = kDirichlet; break;
            case BoundaryType::velocity:
              base = kDirichlet;
              m_value[d][q] = body >= 0 ? 0.0 : B.velocity(C(b, t));
              break;
            case BoundaryType::pressure: base = bhi ? kPressureHi : kPressureLo; break;
            case BoundaryType::periodic: break;
          }
        }
        m_base[d][q] = base;
        m_kind[d][q] = (sharp && body >= 0 && base != kDirichlet) ? static_cast<char>(kSolid) : base;
        if (sharp && body >= 0) m_body[d][q] = body;
        if (pen && base != kDirichlet) {
          // Supersample the node's control volume.
          const double lo_n = base == kPressureLo ? F(d, n) : C(d, n - 1), hi_n = base == kPressureHi ? F(d, n) : C(d, n);
          const double lo_t = F(b, t), hi_t = F(b, t + 1);
          int hits = 0, first = -1;
          for (int a1 = 0; a1 < ss; ++a1)
            for (int a2 = 0; a2 < ss; ++a2) {
              const double sn = lo_n + (hi_n - lo_n) * (a1 + 0.5) / ss, st = lo_t + (hi_t - lo_t) * (a2 + 0.5) / ss;
              const int bb = d == 0 ? shape->bodyAt(sn, st) : shape->bodyAt(st, sn);
              if (bb >= 0) {
                ++hits;
                if (first < 0) first = bb;
              }
            }
          m_chi[d][q] = static_cast<double>(hits) / (ss * ss);
          m_body[d][q] = first;
        }
      }
  }
  if (sharp) {
    for (int d = 0; d < 2; ++d) {
      const int b = 1 - d;
      for (int t = 0; t < m_N[b]; ++t)
        for (int n = 0; n < m_nn[d]; ++n) {
          const std::size_t q = static_cast<std::size_t>(local(d, n, t));
          const char k = m_kind[d][q];
          if (k == kSolid || k == kDirichlet) continue;
          const Eigen::Vector2d P = position(d, n, t);
          for (int s = 0; s < 4; ++s) {
            if ((s == 0 && k == kPressureLo) || (s == 1 && k == kPressureHi)) continue;
            const int qn = slotNeighbour(d, n, t, s);
            if (qn < 0) continue;
            const std::size_t ql = static_cast<std::size_t>(qn - m_off[d]);
            if (m_kind[d][ql] != kSolid) continue;
            const int axis = s < 2 ? d : b, sign = (s % 2 == 0) ? -1 : 1;
            const double dist = slotLength(d, n, t, s);
            const double hit = shape->distanceAlong(P.x(), P.y(), axis, sign, dist);
            const double theta = std::clamp(hit / dist, kMinTheta, 1.0);
            m_cut[d][q][static_cast<std::size_t>(s)] = theta;
            if (m_body[d][q] < 0) m_body[d][q] = m_body[d][ql];
            m_open[d][q] += openExcess(d, n, t, s);
          }
        }
    }
  }
  if (!m_p.body_motion.empty() && (shape == nullptr || static_cast<int>(m_p.body_motion.size()) != shape->bodies()))
    throw std::invalid_argument("body_motion needs one rigid motion per body of the shape");
  applyMotion();
  // Cells whose faces are all prescribed carry no pressure information: pin them.
  m_pinned.assign(static_cast<std::size_t>(m_N[0] * m_N[1]), 0);
  bool has_pressure = false;
  for (const auto& B : m_p.boundary) has_pressure = has_pressure || B.type == BoundaryType::pressure;
  int ref = -1;
  auto fixed = [&](int d, int n, int t) {
    const int qn = unknown(d, n, t);
    const char k = m_kind[d][static_cast<std::size_t>(qn - m_off[d])];
    return k == kDirichlet || k == kSolid;
  };
  for (int j = 0; j < m_N[1]; ++j)
    for (int i = 0; i < m_N[0]; ++i) {
      const bool all = fixed(0, i, j) && fixed(0, i + 1, j) && fixed(1, j, i) && fixed(1, j + 1, i);
      if (all) m_pinned[static_cast<std::size_t>(j * m_N[0] + i)] = 1;
      else if (ref < 0) ref = j * m_N[0] + i;
    }
  if (!has_pressure && ref >= 0) m_pinned[static_cast<std::size_t>(ref)] = 2;
  // Cell solid fractions (output, pressure probes, which cells merge).
  m_cellChi = Eigen::ArrayXXd::Zero(m_N[1], m_N[0]);
  if (shape != nullptr)
    for (int j = 0; j < m_N[1]; ++j)
      for (int i = 0; i < m_N[0]; ++i) {
        if (sharp) {
          m_cellChi(j, i) = shape->solid(C(0, i), C(1, j)) ? 1.0 : 0.0;
          continue;
        }
        int hits = 0;
        for (int a1 = 0; a1 < ss; ++a1)
          for (int a2 = 0; a2 < ss; ++a2)
            hits += shape->solid(F(0, i) + W(0, i) * (a1 + 0.5) / ss, F(1, j) + W(1, j) * (a2 + 0.5) / ss) ? 1 : 0;
        m_cellChi(j, i) = static_cast<double>(hits) / (ss * ss);
      }
  if (sharp && m_p.merge_cut_cells) mergeCutCells();
  pinClosedComponents();
}

double FlowOperator::W(int a, int k) const {
  const int N = m_N[a];
  if (k >= 0 && k < N) return ax(a).width(k);
  if (m_per[a]) return ax(a).width(wrapIndex(a, k));
  return ax(a).width(k < 0 ? 0 : N - 1);
}

double FlowOperator::C(int a, int k) const {
  const int N = m_N[a];
  if (k >= 0 && k < N) return ax(a).centre(k);
  if (m_per[a]) {
    const int kk = wrapIndex(a, k);
    const int periods = (k - kk) / N;
    return ax(a).centre(kk) + periods * ax(a).length();
  }
  // Mirror ghosts beyond a non-periodic side.
  return k < 0 ? ax(a).lo() - (0.5 - k - 1) * W(a, 0) : ax(a).hi() + (0.5 + k - N) * W(a, N - 1);
}

double FlowOperator::F(int a, int n) const {
  const int N = m_N[a];
  if (n >= 0 && n <= N) return ax(a).face(n);
  if (m_per[a]) {
    const int kk = ((n % N) + N) % N;
    const int periods = (n - kk) / N;
    return ax(a).face(kk) + periods * ax(a).length();
  }
  return n < 0 ? ax(a).lo() : ax(a).hi();
}

Eigen::Vector2d FlowOperator::position(int d, int n, int t) const {
  return d == 0 ? Eigen::Vector2d(F(0, n), C(1, t)) : Eigen::Vector2d(C(0, t), F(1, n));
}

int FlowOperator::unknown(int d, int n, int t) const {
  const int b = 1 - d;
  if (m_per[d]) n = wrapIndex(d, n);
  else if (n < 0 || n > m_N[d]) return -1;
  if (m_per[b]) t = wrapIndex(b, t);
  else if (t < 0 || t >= m_N[b]) return -1;
  return m_off[d] + local(d, n, t);
}

bool FlowOperator::isMomentumRow(int r) const { return r < m_off[2]; }

double FlowOperator::maxPrescribedVelocity() const {
  double m = 0;
  for (int d = 0; d < 2; ++d) {
    for (double v : m_value[d]) m = std::max(m, std::abs(m_drive * v));
    for (double v : m_rigid[d]) m = std::max(m, std::abs(v));
  }
  return m;
}

bool FlowOperator::isFixedNode(int r) const {
  if (r < 0 || r >= m_off[2]) return false;
  const int d = r < m_off[1] ? 0 : 1;
  const char k = m_kind[d][static_cast<std::size_t>(r - m_off[d])];
  return k == kDirichlet || k == kSolid;
}

double FlowOperator::controlVolume(int d, int n, int t) const {
  const std::size_t q = static_cast<std::size_t>(local(d, n, t));
  const char base = m_base[d][q];
  const double lo_n = base == kPressureLo ? F(d, n) : C(d, n - 1), hi_n = base == kPressureHi ? F(d, n) : C(d, n);
  return (hi_n - lo_n) * W(1 - d, t);
}

int FlowOperator::slotNeighbour(int d, int n, int t, int s) const {
  return unknown(d, s == 0 ? n - 1 : s == 1 ? n + 1 : n, s == 2 ? t - 1 : s == 3 ? t + 1 : t);
}

double FlowOperator::slotLength(int d, int n, int t, int s) const {
  if (s < 2) return W(d, s == 0 ? n - 1 : n);
  const int b = 1 - d;
  return std::abs(C(b, s == 2 ? t - 1 : t + 1) - C(b, t));
}

Lin FlowOperator::alongLink(int d, int n, int t, int s, double w) const {
  const int P = unknown(d, n, t), Q = slotNeighbour(d, n, t, s);
  const std::size_t qp = static_cast<std::size_t>(P - m_off[d]), qq = static_cast<std::size_t>(Q - m_off[d]);
  const bool solid_p = m_kind[d][qp] == kSolid, solid_q = m_kind[d][qq] == kSolid;
  Lin L;
  if (solid_p && solid_q) return L;
  // Between a fluid node and a solid one the velocity falls linearly to zero at
  // the surface (theta of the link, as in the viscous flux), not at the solid
  // node, and a point beyond the surface is at rest: interpolating towards the
  // solid node's zero moved the wall up to a cell beyond the surface in the
  // convective fluxes (an O(h) error in the face values next to the body). The
  // value belongs to the link, the same in both rows that share a face, so the
  // convective fluxes stay conservative (the residual body force needs that).
  const double theta_p = solid_q ? m_cut[d][qp][static_cast<std::size_t>(s)] : 0.0;
  const double theta_q = solid_p ? m_cut[d][qq][static_cast<std::size_t>(s ^ 1)] : 0.0;
  if (theta_p > 0) {
    if (w < theta_p) L.add(P, 1.0 - w / theta_p);
  } else if (theta_q > 0) {
    if (1.0 - w < theta_q) L.add(Q, 1.0 - (1.0 - w) / theta_q);
  } else {
    L.add(P, 1.0 - w);
    L.add(Q, w);
  }
  return L;
}

Lin FlowOperator::advecting(int d, int n, int face_t, Kind base) const {
  // Component b = 1 - d at (axis-d coordinate F(d, n), axis-b face face_t):
  // interpolate the b-nodes (normal index face_t, transverse cells n - 1 and n).
  const int b = 1 - d;
  Lin L;
  if (base == kPressureLo) {
    L.add(unknown(b, face_t, n), 1.0);
  } else if (base == kPressureHi) {
    L.add(unknown(b, face_t, n - 1), 1.0);
  } else {
    L = alongLink(b, face_t, n - 1, 3, (F(d, n) - C(d, n - 1)) / (C(d, n) - C(d, n - 1)));
  }
  return L;
}

Lin FlowOperator::advected(int d, int n, int t, int t2) const {
  // Component d between transverse indices t and t2 = t +- 1, at the face between them.
  const int b = 1 - d;
  const int P = unknown(d, n, t);
  Lin L;
  const int Q = unknown(d, n, t2);
  if (Q < 0) {
    const BoundaryType bt = side(b, t2 > t).type;
    if (bt == BoundaryType::slip || bt == BoundaryType::pressure) L.add(P, 1.0);  // zero gradient; no-slip: zero
    return L;
  }
  const double face = t2 > t ? F(b, t + 1) : F(b, t);
  return alongLink(d, n, t, t2 > t ? 3 : 2, (face - C(b, t)) / (C(b, t2) - C(b, t)));
}

void FlowOperator::momentumRow(int d, int n, int t, bool standard, RowTerms& R) const {
  const int b = 1 - d;
  const std::size_t q = static_cast<std::size_t>(local(d, n, t));
  const Kind base = static_cast<Kind>(m_base[d][q]);
  const bool lo_b = base == kPressureLo, hi_b = base == kPressureHi;
  const int P = m_off[d] + static_cast<int>(q);
  const double lo_n = lo_b ? F(d, n) : C(d, n - 1), hi_n = hi_b ? F(d, n) : C(d, n);
  const double wn = hi_n - lo_n, wt = W(b, t), vol = wn * wt;
  const double mu = m_p.viscosity, rho = m_p.density;
  double diag = 0;
  // Pressure force (outward normal times p on the two normal faces).
  if (hi_b) R.rhs -= m_drive * side(d, true).pressure * wt;
  else R.lin.emplace_back(pcell(d, n, t), wt);
  if (lo_b) R.rhs += m_drive * side(d, false).pressure * wt;
  else R.lin.emplace_back(pcell(d, n - 1, t), -wt);
  // Viscous fluxes mu A (u_P - u_Q) / dist.
  const auto& cut = m_cut[d][q];
  for (int s = 0; s < 4; ++s) {
    if ((s == 0 && lo_b) || (s == 1 && hi_b)) continue;  // zero normal gradient at an open boundary
    const double A = s < 2 ? wt : wn;
    const int Q = slotNeighbour(d, n, t, s);
    if (Q < 0) {  // ghost beyond a wall along the transverse axis (mirror)
      const BoundaryType bt = side(b, s == 3).type;
      if (bt == BoundaryType::no_slip || bt == BoundaryType::velocity) diag += 2 * mu * A / W(b, t);
      continue;
    }
    const double dist = slotLength(d, n, t, s);
    const double theta = standard ? 0.0 : cut[static_cast<std::size_t>(s)];
    if (theta > 0) {
      diag += mu * A / (theta * dist);  // wall (moving with the body) at theta * dist
      R.rhs += mu * A / (theta * dist) * m_cutWall[d][q][static_cast<std::size_t>(s)];
    } else {
      diag += mu * A / dist;
      R.lin.emplace_back(Q, -mu * A / dist);
    }
  }
  if (m_p.inertia) {
    // Normal faces.
    if (hi_b) {
      Lin a;
      a.add(P, 1.0);
      R.bil.push_back({rho * wt, a, a});
    } else {
      const Lin a = alongLink(d, n, t, 1, 0.5);  // the cell centre, half-way to the neighbour
      R.bil.push_back({rho * wt, a, a});
    }
    if (lo_b) {
      Lin a;
      a.add(P, 1.0);
      R.bil.push_back({-rho * wt, a, a});
    } else {
      const Lin a = alongLink(d, n, t, 0, 0.5);  // the cell centre, half-way to the neighbour
      R.bil.push_back({-rho * wt, a, a});
    }
    // Transverse faces: advecting b-velocity times advected d-velocity.
    R.bil.push_back({rho * wn, advecting(d, n, t + 1, base), advected(d, n, t, t + 1)});
    R.bil.push_back({-rho * wn, advecting(d, n, t, base), advected(d, n, t, t - 1)});
  }
  if (m_p.depth > 0) {
    const double hf = faceDepth(d, q);
    diag += 12 * mu / (hf * hf) * vol;  // Hele-Shaw friction of the face's depth
  }
  if (!standard && m_chi[d][q] > 0) {
    // Volume-fraction forcing u = M u* + (1 - M) v (M = 1 - chi, v = 0): the row
    // becomes (1 - chi) [momentum] + chi a_P u = 0 with a_P the row's own
    // diagonal, i.e. a penalty a_P chi / (1 - chi) (capped where chi -> 1).
    const double chi = m_chi[d][q];
    const double pen = diag * chi / std::max(1.0 - chi, m_p.penalty);
    diag += pen;
    R.rhs += pen * m_rigid[d][q];
  }
  if (m_tcoef > 0) {
    diag += m_tcoef * vol;
    R.rhs += vol * (*m_told)[static_cast<std::size_t>(P)];
  }
  R.rhs += m_drive * m_p.body_force[d] * vol;
  R.lin.emplace_back(P, diag);
  if (!standard && m_open[d][q] != 1.0) {
    // The continuity weighs this node's flux by m_open; its pressure force is the transpose
    // (m_open A dp), so the whole row is m_open times the momentum balance at the node: div
    // stays minus the transpose of grad, and the residual body force is unchanged in form.
    const double k = m_open[d][q];
    for (auto& e : R.lin) e.second *= k;
    for (auto& bt : R.bil) bt.c *= k;
    R.rhs *= k;
  }
}

void FlowOperator::continuityRow(int i, int j, RowTerms& R) const {
  const std::size_t c = static_cast<std::size_t>(j * m_N[0] + i);
  if (m_pinned[c] != 0) {
    R.lin.emplace_back(cellUnknown(i, j), W(0, i));
    return;
  }
  if (!m_master.empty() && m_master[c] >= 0) {
    // A merged cell: its fluxes count in its master's row; its pressure is the master's.
    R.lin.emplace_back(cellUnknown(i, j), W(0, i));
    R.lin.emplace_back(m_off[2] + m_master[c], -W(0, i));
    return;
  }
  cellFluxes(i, j, R);
  if (!m_merged.empty())
    for (int k : m_merged[c]) cellFluxes(k % m_N[0], k / m_N[0], R);
}

void FlowOperator::cellFluxes(int i, int j, RowTerms& R) const {
  const double dx = W(0, i), dy = W(1, j);
  // Variable depth: the flux h_f u_f A_f is conserved (weights h_f / h_ref keep the row's scale);
  // faces the body surface crosses count their fluid part (m_open).
  // A crossed face of a moving body: the fluid part's profile starts at the surface's velocity and
  // the covered part moves with the body, flux A (m_open u - m_openWall).
  const auto face = [&](int d, int n, int t, double area) {
    const int r = unknown(d, n, t);
    const std::size_t q = static_cast<std::size_t>(r - m_off[d]);
    R.lin.emplace_back(r, area * fluxWeight(d, n, t) * m_open[d][q]);
    if (!m_openWall[d].empty()) R.rhs += area * fluxWeight(d, n, t) * m_openWall[d][q];
  };
  face(0, i, j, dy);
  face(0, i + 1, j, -dy);
  face(1, j, i, dx);
  face(1, j + 1, i, -dx);
}

void FlowOperator::mergeCutCells() {
  const int nc = m_N[0] * m_N[1];
  m_master.assign(static_cast<std::size_t>(nc), -1);
  m_merged.assign(static_cast<std::size_t>(nc), {});
  // m_cellChi is 1 where a cell's centre is inside a body (sharp).
  std::vector<char> inside(static_cast<std::size_t>(nc), 0);
  for (int j = 0; j < m_N[1]; ++j)
    for (int i = 0; i < m_N[0]; ++i) {
      const std::size_t c = static_cast<std::size_t>(j * m_N[0] + i);
      inside[c] = m_pinned[c] == 0 && m_cellChi(j, i) > 0.5 ? 1 : 0;
    }
  // Each cell whose centre is inside a body points at the neighbour across its most open
  // fluid face, preferring a neighbour whose centre is in the fluid.
  std::vector<int> next(static_cast<std::size_t>(nc), -1);
  for (int j = 0; j < m_N[1]; ++j)
    for (int i = 0; i < m_N[0]; ++i) {
      const std::size_t c = static_cast<std::size_t>(j * m_N[0] + i);
      if (inside[c] == 0) continue;
      double best = 0;
      bool best_fluid = false;
      const int faces[4][5] = {{0, i, j, i - 1, j}, {0, i + 1, j, i + 1, j}, {1, j, i, i, j - 1}, {1, j + 1, i, i, j + 1}};
      for (const auto& f : faces) {
        const int d = f[0], r = unknown(d, f[1], f[2]);
        const std::size_t q = static_cast<std::size_t>(r - m_off[d]);
        if (m_kind[d][q] != kFluid) continue;
        int ni = f[3], nj = f[4];
        if (!m_per[0] && (ni < 0 || ni >= m_N[0])) continue;
        if (!m_per[1] && (nj < 0 || nj >= m_N[1])) continue;
        ni = wrapIndex(0, ni);
        nj = wrapIndex(1, nj);
        const std::size_t nb = static_cast<std::size_t>(nj * m_N[0] + ni);
        if (m_pinned[nb] != 0) continue;
        const bool fluid = inside[nb] == 0;
        const double w = (d == 0 ? W(1, j) : W(0, i)) * m_open[d][q];
        if ((fluid && !best_fluid) || (fluid == best_fluid && w > best)) {
          best = w;
          best_fluid = fluid;
          next[c] = static_cast<int>(nb);
        }
      }
    }
  // Follow the chain to a cell whose centre is in the fluid (a chain that closes on itself stays unmerged).
  for (int c = 0; c < nc; ++c) {
    if (next[static_cast<std::size_t>(c)] < 0) continue;
    int m = c, steps = 0;
    while (m >= 0 && inside[static_cast<std::size_t>(m)] != 0 && steps++ <= nc) m = next[static_cast<std::size_t>(m)];
    if (m < 0 || inside[static_cast<std::size_t>(m)] != 0) continue;
    m_master[static_cast<std::size_t>(c)] = m;
    m_merged[static_cast<std::size_t>(m)].push_back(c);
  }
}

void FlowOperator::pinClosedComponents() {
  // Cells exchange pressure through fluid velocity nodes (the node's momentum row holds both
  // cells' pressures, the cells' continuity rows hold the node) and through merges. A component
  // of cells that touches no pressure boundary and holds no pinned cell has no pressure level,
  // and the sum of its continuity rows involves only prescribed (solid or wall) velocities, so
  // the system is singular: its LU gave a non-finite field. The sharp method makes such
  // components of enclosed pockets and of cut cells: at 0.5 cells per pixel a lone pore pixel in
  // a grain can open the face between two cells whose centres are both in the grain, and each
  // merges into the other (a chain that closes on itself, left unmerged). Replacing one
  // continuity row of such a component by p = 0 removes the free level; the dropped row is the
  // negative sum of the others (no net flux through a closed boundary at rest), so nothing else
  // changes. Components with a pressure boundary, or the one pinned by the constructor when the
  // domain has none, are left as they are.
  const int nc = m_N[0] * m_N[1];
  std::vector<int> parent(static_cast<std::size_t>(nc));
  for (int c = 0; c < nc; ++c) parent[static_cast<std::size_t>(c)] = c;
  const auto find = [&](int c) {
    while (parent[static_cast<std::size_t>(c)] != c) c = parent[static_cast<std::size_t>(c)] = parent[static_cast<std::size_t>(parent[static_cast<std::size_t>(c)])];
    return c;
  };
  const auto join = [&](int a, int b) {
    a = find(a);
    b = find(b);
    if (a != b) parent[static_cast<std::size_t>(std::max(a, b))] = std::min(a, b);
  };
  // Cell index (j nx + i) of the cell on side `hi` of node (d, n, t) along axis d; -1 outside the domain.
  const auto cellBeside = [&](int d, int n, int t, bool hi) {
    int k = hi ? n : n - 1;
    if (m_per[d]) k = wrapIndex(d, k);
    else if (k < 0 || k >= m_N[d]) return -1;
    return d == 0 ? t * m_N[0] + k : k * m_N[0] + t;
  };
  std::vector<char> referenced(static_cast<std::size_t>(nc), 0);
  for (int c = 0; c < nc; ++c) {
    if (m_pinned[static_cast<std::size_t>(c)] != 0) referenced[static_cast<std::size_t>(c)] = 1;
    if (!m_master.empty() && m_master[static_cast<std::size_t>(c)] >= 0) join(c, m_master[static_cast<std::size_t>(c)]);
  }
  for (int d = 0; d < 2; ++d) {
    const int b = 1 - d;
    for (int t = 0; t < m_N[b]; ++t)
      for (int n = 0; n < m_nn[d]; ++n) {
        const char k = m_kind[d][static_cast<std::size_t>(local(d, n, t))];
        if (k == kFluid) {
          const int lo = cellBeside(d, n, t, false), hi = cellBeside(d, n, t, true);
          if (lo >= 0 && hi >= 0) join(lo, hi);
        } else if (k == kPressureLo || k == kPressureHi) {
          const int c = cellBeside(d, n, t, k == kPressureLo);
          if (c >= 0) referenced[static_cast<std::size_t>(c)] = 1;
        }
      }
  }
  for (int c = 0; c < nc; ++c)
    if (referenced[static_cast<std::size_t>(c)] != 0) referenced[static_cast<std::size_t>(find(c))] = 1;
  for (int c = 0; c < nc; ++c) {  // the first cell of each closed component that keeps its own pressure
    const int r = find(c);
    if (referenced[static_cast<std::size_t>(r)] != 0) continue;
    if (!m_master.empty() && m_master[static_cast<std::size_t>(c)] >= 0) continue;
    m_pinned[static_cast<std::size_t>(c)] = 2;
    referenced[static_cast<std::size_t>(r)] = 1;
  }
}

double FlowOperator::fluxWeight(int d, int n, int t) const {
  if (m_hface[d].empty()) return 1.0;
  const int r = unknown(d, n, t);
  return m_hface[d][static_cast<std::size_t>(r - m_off[d])] / m_p.depth;
}

double FlowOperator::linearRow(int r, Linearisation mode, const std::vector<double>& state, RowTerms& R,
                               std::vector<std::pair<int, double>>& entries) const {
  const double rhs = ownRow(r, mode, state, R, entries);
  if (!m_pattern) return rhs;
  // The kept pattern's columns this row lacks, as explicit zeros (merged in column order).
  const RowPattern& P = *m_pattern;
  const auto first = P.cols.begin() + P.start[static_cast<std::size_t>(r)], last = P.cols.begin() + P.start[static_cast<std::size_t>(r) + 1];
  const std::size_t own = entries.size();
  std::size_t k = 0;
  for (auto it = first; it != last; ++it) {
    while (k < own && entries[k].first < *it) ++k;
    if (k < own && entries[k].first == *it) continue;
    entries.emplace_back(*it, 0.0);
  }
  if (entries.size() != own)
    std::inplace_merge(entries.begin(), entries.begin() + static_cast<std::ptrdiff_t>(own), entries.end(),
                       [](const auto& a, const auto& b) { return a.first < b.first; });
  return rhs;
}

RowPattern FlowOperator::keptPattern() const {
  // Extra (row, column) pairs beyond the rows' own entries.
  std::vector<std::pair<int, int>> extra;
  const int nc = m_N[0] * m_N[1];
  for (int c = 0; c < nc; ++c) extra.emplace_back(m_off[2] + c, m_off[2] + c);
  if (!m_master.empty()) {
    for (int c = 0; c < nc; ++c) {
      if (m_master[static_cast<std::size_t>(c)] < 0) continue;
      const int i = c % m_N[0], j = c / m_N[0];
      const int faces[4] = {unknown(0, i, j), unknown(0, i + 1, j), unknown(1, j, i), unknown(1, j + 1, i)};
      const int ni[4] = {i - 1, i + 1, i, i}, nj[4] = {j, j, j - 1, j + 1};
      for (int s = 0; s < 4; ++s) {
        if ((!m_per[0] && (ni[s] < 0 || ni[s] >= m_N[0])) || (!m_per[1] && (nj[s] < 0 || nj[s] >= m_N[1]))) continue;
        const int nb = cellUnknown(ni[s], nj[s]);
        extra.emplace_back(cellUnknown(i, j), nb);
        for (int f : faces) {
          extra.emplace_back(nb, f);
          extra.emplace_back(f, nb);
        }
      }
    }
  }
  std::sort(extra.begin(), extra.end());
  RowPattern P;
  const std::vector<double> zero(static_cast<std::size_t>(unknowns()), 0.0);
  RowTerms R;
  std::vector<std::pair<int, double>> entries;
  std::vector<int> row;
  std::size_t e = 0;
  for (int r = 0; r < unknowns(); ++r) {
    ownRow(r, Linearisation::stokes, zero, R, entries);
    row.clear();
    for (const auto& en : entries) row.push_back(en.first);
    for (; e < extra.size() && extra[e].first == r; ++e) row.push_back(extra[e].second);
    std::sort(row.begin(), row.end());
    row.erase(std::unique(row.begin(), row.end()), row.end());
    P.cols.insert(P.cols.end(), row.begin(), row.end());
    P.start.push_back(static_cast<int>(P.cols.size()));
  }
  return P;
}

double FlowOperator::ownRow(int r, Linearisation mode, const std::vector<double>& state, RowTerms& R,
                            std::vector<std::pair<int, double>>& entries) const {
  R.clear();
  entries.clear();
  if (r >= m_off[2]) {
    const int cell = r - m_off[2];
    continuityRow(cell % m_N[0], cell / m_N[0], R);
  } else {
    const int d = r < m_off[1] ? 0 : 1;
    const int loc = r - m_off[d];
    const int n = loc % m_nn[d], t = loc / m_nn[d];
    const char k = m_kind[d][static_cast<std::size_t>(loc)];
    if (k == kDirichlet || k == kSolid) {
      const double mu = m_p.viscosity;
      entries.emplace_back(r, mu);
      return mu * (k == kDirichlet ? m_drive * m_value[d][static_cast<std::size_t>(loc)] : m_rigid[d][static_cast<std::size_t>(loc)]);
    }
    momentumRow(d, n, t, false, R);
  }
  entries = R.lin;
  double rhs = R.rhs;
  for (const auto& bt : R.bil) {
    const double A0 = mode == Linearisation::stokes ? 0.0 : bt.a.eval(state);
    const double B0 = mode == Linearisation::newton ? bt.b.eval(state) : 0.0;
    // Newton: c (A0 b + B0 a) x = rhs - c (-A0 B0 + A0 kb + B0 ka); Picard: c A0 b x = rhs - c A0 kb.
    for (int q = 0; q < bt.b.n; ++q) entries.emplace_back(bt.b.idx[static_cast<std::size_t>(q)], bt.c * A0 * bt.b.c[static_cast<std::size_t>(q)]);
    for (int q = 0; q < bt.a.n; ++q) entries.emplace_back(bt.a.idx[static_cast<std::size_t>(q)], bt.c * B0 * bt.a.c[static_cast<std::size_t>(q)]);
    if (mode == Linearisation::newton) rhs -= bt.c * (-A0 * B0 + A0 * bt.b.k + B0 * bt.a.k);
    else if (mode == Linearisation::picard) rhs -= bt.c * A0 * bt.b.k;
  }
  std::sort(entries.begin(), entries.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  std::size_t w = 0;
  for (std::size_t i = 0; i < entries.size(); ++i) {
    if (w > 0 && entries[w - 1].first == entries[i].first) entries[w - 1].second += entries[i].second;
    else entries[w++] = entries[i];
  }
  entries.resize(w);
  return rhs;
}

double FlowOperator::openExcess(int d, int n, int t, int s) const {
  if (s < 2 || m_p.depth > 0) return 0.0;
  const double theta = m_cut[d][static_cast<std::size_t>(local(d, n, t))][static_cast<std::size_t>(s)];
  if (!(theta > 0)) return 0.0;
  const double gap = theta * slotLength(d, n, t, s), wf = W(1 - d, t);
  if (!(gap < 0.5 * wf)) return 0.0;
  // The surface crosses this node's face, gap from the node: the flux through the
  // face's fluid part, with the velocity linear from zero at the surface through the
  // node, is u_P (2 gap + wf)^2 / (8 gap), not u_P wf (exact for the linear near-wall
  // profile; the node value times the whole face is not, an O(h) velocity error next
  // to walls inclined to the grid, Channel.InclinedImmersedWallsConverge). Not with
  // Hele-Shaw friction: its wall layer (depth / sqrt 12) is thinner than a cell, so the
  // profile is not linear across it (Pore2Chip at 2 pixels per cell moved 1.2 % away
  // from its 1-pixel value with it).
  return (2 * gap + wf) * (2 * gap + wf) / (8 * gap * wf) - 1.0;
}

double FlowOperator::rigidVelocity(int body, int d, const Eigen::Vector2d& X) const {
  if (body < 0 || m_p.body_motion.empty()) return 0.0;
  const RigidMotion& M = m_p.body_motion[static_cast<std::size_t>(body)];
  Eigen::Vector2d r = X - m_p.shape->centre(body);
  for (int a = 0; a < 2; ++a)
    if (m_per[a]) r[a] -= ax(a).length() * std::round(r[a] / ax(a).length());
  return d == 0 ? M.velocity.x() - M.spin * r.y() : M.velocity.y() + M.spin * r.x();
}

void FlowOperator::setBodyMotion(std::vector<RigidMotion> motion) {
  if (!motion.empty() && (m_p.shape == nullptr || static_cast<int>(motion.size()) != m_p.shape->bodies()))
    throw std::invalid_argument("setBodyMotion needs one rigid motion per body of the shape");
  m_p.body_motion = std::move(motion);
  applyMotion();
}

void FlowOperator::applyMotion() {
  for (int d = 0; d < 2; ++d) {
    const int b = 1 - d;
    m_rigid[d].assign(m_kind[d].size(), 0.0);
    m_cutWall[d].assign(m_kind[d].size(), {0, 0, 0, 0});
    m_openWall[d].clear();  // bodies at rest: no surface velocity in the crossed faces' flux
    if (m_p.body_motion.empty()) continue;
    m_openWall[d].assign(m_kind[d].size(), 0.0);
    for (int t = 0; t < m_N[b]; ++t)
      for (int n = 0; n < m_nn[d]; ++n) {
        const std::size_t q = static_cast<std::size_t>(local(d, n, t));
        const int body = m_body[d][q];
        if (body < 0 || m_base[d][q] == kDirichlet) continue;
        const Eigen::Vector2d P = position(d, n, t);
        m_rigid[d][q] = rigidVelocity(body, d, P);
        for (int s = 0; s < 4; ++s) {
          const double theta = m_cut[d][q][static_cast<std::size_t>(s)];
          if (theta <= 0) continue;
          // The surface point of the slot: theta of the way to the solid neighbour.
          const int axis = s < 2 ? d : b, sign = (s % 2 == 0) ? -1 : 1;
          Eigen::Vector2d X = P;
          X[axis] += sign * theta * slotLength(d, n, t, s);
          // The solid neighbour's body (a node between two bodies sees each on its own side).
          const int qn = slotNeighbour(d, n, t, s);
          const int nb = qn >= 0 ? m_body[d][static_cast<std::size_t>(qn - m_off[d])] : body;
          m_cutWall[d][q][static_cast<std::size_t>(s)] = rigidVelocity(nb >= 0 ? nb : body, d, X);
          m_openWall[d][q] += openExcess(d, n, t, s) * m_cutWall[d][q][static_cast<std::size_t>(s)];
        }
      }
  }
}

std::vector<BodyLoad> FlowOperator::bodyLoads(const std::vector<double>& s) const {
  std::vector<BodyLoad> loads;
  const Shape* shape = m_p.shape.get();
  if (shape == nullptr) return loads;
  loads.resize(static_cast<std::size_t>(shape->bodies()));
  RowTerms R;
  for (int d = 0; d < 2; ++d) {
    const int b = 1 - d;
    for (int t = 0; t < m_N[b]; ++t)
      for (int n = 0; n < m_nn[d]; ++n) {
        const std::size_t q = static_cast<std::size_t>(local(d, n, t));
        const int body = m_body[d][q];
        if (body < 0 || m_base[d][q] == kDirichlet) continue;
        const bool touched = m_kind[d][q] == kSolid || m_chi[d][q] > 0 ||
                             std::any_of(m_cut[d][q].begin(), m_cut[d][q].end(), [](double th) { return th > 0; });
        if (!touched) continue;
        R.clear();
        momentumRow(d, n, t, true, R);
        double res = -R.rhs;
        for (const auto& [idx, c] : R.lin) res += c * s[static_cast<std::size_t>(idx)];
        for (const auto& bt : R.bil) res += bt.c * bt.a.eval(s) * bt.b.eval(s);
        const double f = -res;  // the body's reaction on the fluid is R; the fluid pushes the body with -R
        auto& L = loads[static_cast<std::size_t>(body)];
        L.force[d] += f;
        Eigen::Vector2d r = position(d, n, t) - shape->centre(body);
        for (int a = 0; a < 2; ++a)
          if (m_per[a]) r[a] -= ax(a).length() * std::round(r[a] / ax(a).length());
        L.torque += d == 0 ? -r.y() * f : r.x() * f;
      }
  }
  return loads;
}

bool FlowOperator::bilinearPressure(const std::vector<double>& s, double x, double y, double& out) const {
  int i0 = ax(0).cellOf(x), j0 = ax(1).cellOf(y);
  if (x < C(0, i0)) --i0;
  if (y < C(1, j0)) --j0;
  i0 = std::clamp(i0, 0, std::max(0, m_N[0] - 2));
  j0 = std::clamp(j0, 0, std::max(0, m_N[1] - 2));
  const int i1 = std::min(i0 + 1, m_N[0] - 1), j1 = std::min(j0 + 1, m_N[1] - 1);
  const double wx = i1 == i0 ? 0.0 : std::clamp((x - C(0, i0)) / (C(0, i1) - C(0, i0)), 0.0, 1.0);
  const double wy = j1 == j0 ? 0.0 : std::clamp((y - C(1, j0)) / (C(1, j1) - C(1, j0)), 0.0, 1.0);
  const int is[2] = {i0, i1}, js[2] = {j0, j1};
  double v = 0;
  for (int a = 0; a < 2; ++a)
    for (int c = 0; c < 2; ++c) {
      if (m_cellChi(js[c], is[a]) >= 0.5) return false;
      v += (a ? wx : 1 - wx) * (c ? wy : 1 - wy) * s[static_cast<std::size_t>(cellUnknown(is[a], js[c]))];
    }
  out = v;
  return true;
}

double FlowOperator::pressureAt(const std::vector<double>& s, double x, double y) const {
  double v = 0;
  if (bilinearPressure(s, x, y, v)) return v;
  const int i = ax(0).cellOf(x), j = ax(1).cellOf(y);
  for (int axis = 0; axis < 2; ++axis) {
    const double h = axis == 0 ? W(0, i) : W(1, j);
    for (int sign : {-1, 1}) {
      double p[3];
      bool ok = true;
      for (int k = 0; k < 3 && ok; ++k) {
        const double dd = sign * h * (k + 1.5);
        ok = bilinearPressure(s, axis == 0 ? x + dd : x, axis == 0 ? y : y + dd, p[k]);
      }
      // Quadratic through three equally spaced points, extrapolated 1.5 h back to the surface point.
      if (ok) return p[0] + (p[0] - p[1]) * 1.5 + 0.5 * 1.5 * 2.5 * (p[0] - 2 * p[1] + p[2]);
    }
  }
  return s[static_cast<std::size_t>(cellUnknown(i, j))];
}

double FlowOperator::flowRate(const std::vector<double>& s, Side sd) const {
  const int d = (sd == Side::west || sd == Side::east) ? 0 : 1, b = 1 - d;
  const int n = (sd == Side::east || sd == Side::north) ? (m_per[d] ? 0 : m_N[d]) : 0;
  double q = 0;
  for (int t = 0; t < m_N[b]; ++t) q += s[static_cast<std::size_t>(unknown(d, n, t))] * W(b, t) * fluxWeight(d, n, t);
  return q;
}

double FlowOperator::superficialVelocity(const std::vector<double>& s) const {
  double sum = 0;
  for (int j = 0; j < m_N[1]; ++j)
    for (int i = 0; i < m_N[0]; ++i)
      sum += 0.5 * (s[static_cast<std::size_t>(unknown(0, i, j))] * fluxWeight(0, i, j) + s[static_cast<std::size_t>(unknown(0, i + 1, j))] * fluxWeight(0, i + 1, j)) *
             W(0, i) * W(1, j);
  return sum / (ax(0).length() * ax(1).length());
}

double FlowOperator::maxRelativeDivergence(const std::vector<double>& s) const {
  double umax = 0, dmax = 0;
  for (int r = 0; r < m_off[2]; ++r) umax = std::max(umax, std::abs(s[static_cast<std::size_t>(r)]));
  RowTerms R;
  for (int j = 0; j < m_N[1]; ++j)
    for (int i = 0; i < m_N[0]; ++i) {
      if (m_pinned[static_cast<std::size_t>(j * m_N[0] + i)] != 0) continue;
      if (!m_master.empty() && m_master[static_cast<std::size_t>(j * m_N[0] + i)] >= 0) continue;  // counted in its master's row
      // The continuity row itself (net inflow, m2/s per unit depth): the divergence the solver enforces.
      R.clear();
      continuityRow(i, j, R);
      double net = -R.rhs;
      for (const auto& [idx, c] : R.lin) net += c * s[static_cast<std::size_t>(idx)];
      const double dx = W(0, i), dy = W(1, j);
      dmax = std::max(dmax, std::abs(net) / (dx * dy) * std::min(dx, dy));
    }
  return umax > 0 ? dmax / umax : dmax;
}

Eigen::ArrayXXd FlowOperator::cellVelocity(const std::vector<double>& s, int c) const {
  Eigen::ArrayXXd out(m_N[1], m_N[0]);
  for (int j = 0; j < m_N[1]; ++j)
    for (int i = 0; i < m_N[0]; ++i)
      out(j, i) = c == 0 ? 0.5 * (s[static_cast<std::size_t>(unknown(0, i, j))] + s[static_cast<std::size_t>(unknown(0, i + 1, j))])
                         : 0.5 * (s[static_cast<std::size_t>(unknown(1, j, i))] + s[static_cast<std::size_t>(unknown(1, j + 1, i))]);
  return out;
}

void FlowOperator::unpack(const std::vector<double>& s, Eigen::ArrayXXd& u, Eigen::ArrayXXd& v, Eigen::ArrayXXd& p) const {
  u.resize(m_N[1], m_N[0] + 1);
  v.resize(m_N[1] + 1, m_N[0]);
  p.resize(m_N[1], m_N[0]);
  for (int j = 0; j < m_N[1]; ++j)
    for (int i = 0; i <= m_N[0]; ++i) u(j, i) = s[static_cast<std::size_t>(unknown(0, i, j))];
  for (int j = 0; j <= m_N[1]; ++j)
    for (int i = 0; i < m_N[0]; ++i) v(j, i) = s[static_cast<std::size_t>(unknown(1, j, i))];
  for (int j = 0; j < m_N[1]; ++j)
    for (int i = 0; i < m_N[0]; ++i) p(j, i) = s[static_cast<std::size_t>(cellUnknown(i, j))];
}

}  // namespace mmval::simulate
