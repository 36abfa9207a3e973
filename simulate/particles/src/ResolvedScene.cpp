#include "ResolvedScene.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include <fmt/format.h>

namespace mmval::particles::resolved {

namespace sim = mmval::simulate;

int fixedBodies(const Scene& sc) { return (sc.grains ? 1 : 0) + static_cast<int>(sc.obstacles.size()); }

std::shared_ptr<const sim::Shape> shapeOf(const Scene& sc, std::vector<int>& body_of_disk) {
  std::vector<sim::Circle> parts;
  body_of_disk.assign(sc.disks.size(), -1);
  int next = fixedBodies(sc);
  for (std::size_t k = 0; k < sc.disks.size(); ++k) {
    if (sc.disks[k].state == State::left) continue;
    parts.push_back({sc.disks[k].x.x(), sc.disks[k].x.y(), sc.disks[k].a});
    body_of_disk[k] = next++;
  }
  std::vector<std::shared_ptr<const sim::Shape>> all;
  if (sc.grains) all.push_back(sc.grains);
  if (!sc.obstacles.empty()) all.push_back(std::make_shared<sim::Circles>(sc.obstacles));
  if (!parts.empty()) all.push_back(std::make_shared<sim::Circles>(parts));
  if (all.empty()) return nullptr;
  return std::make_shared<sim::ShapeUnion>(std::move(all));
}

Nearest nearestSurface(const Scene& sc, std::size_t k) {
  const Disk& D = sc.disks[k];
  Nearest n;
  auto consider = [&](double gap, Eigen::Vector2d normal, int other) {
    if (gap < n.gap) n = {gap, normal, other};
  };
  consider(D.x.y() - D.a, {0, 1}, -1);
  consider(sc.W - D.x.y() - D.a, {0, -1}, -1);
  if (sc.U == 0) {  // closed box: end walls too
    consider(D.x.x() - D.a, {1, 0}, -1);
    consider(sc.L - D.x.x() - D.a, {-1, 0}, -1);
  }
  if (sc.grains) {
    // Grain pixels near the disk: the gap to the closest point of each pixel square.
    const auto& m = sc.grains->mask();
    const double px = sc.grains->pixel(), reach = D.a + 2 * std::max(sc.contact_gap, sc.capture) + px;  // farther grains decide nothing
    const int rows = static_cast<int>(m.rows()), cols = static_cast<int>(m.cols());
    const int c0 = std::max(0, static_cast<int>(std::floor((D.x.x() - reach) / px))), c1 = std::min(cols - 1, static_cast<int>(std::floor((D.x.x() + reach) / px)));
    // Row 0 is the image's top: y = (rows - r) px at its upper edge.
    const int r0 = std::max(0, static_cast<int>(std::floor(rows - (D.x.y() + reach) / px))), r1 = std::min(rows - 1, static_cast<int>(std::floor(rows - (D.x.y() - reach) / px)));
    for (int r = r0; r <= r1; ++r)
      for (int col = c0; col <= c1; ++col) {
        if (!m(r, col)) continue;
        const Eigen::Vector2d lo(col * px, (rows - r - 1) * px);
        const Eigen::Vector2d q(std::clamp(D.x.x(), lo.x(), lo.x() + px), std::clamp(D.x.y(), lo.y(), lo.y() + px));
        const Eigen::Vector2d rr = D.x - q;
        const double dist = rr.norm();
        consider(dist - D.a, dist > 0 ? Eigen::Vector2d(rr / dist) : Eigen::Vector2d(0, 1), -1);
      }
  }
  for (const auto& o : sc.obstacles) {
    const Eigen::Vector2d r = D.x - Eigen::Vector2d(o.x, o.y);
    const double dist = r.norm();
    consider(dist - o.radius - D.a, dist > 0 ? Eigen::Vector2d(r / dist) : Eigen::Vector2d(0, 1), -1);
  }
  for (std::size_t j = 0; j < sc.disks.size(); ++j) {
    if (j == k || sc.disks[j].state == State::left) continue;
    const Eigen::Vector2d r = D.x - sc.disks[j].x;
    const double dist = r.norm();
    consider(dist - sc.disks[j].a - D.a, dist > 0 ? Eigen::Vector2d(r / dist) : Eigen::Vector2d(0, 1), static_cast<int>(j));
  }
  return n;
}

std::vector<Eigen::Vector2d> velocities(sim::ResolvedStokes& fluid, const Scene& sc, int& solves) {
  std::vector<int> body;
  fluid.setShape(shapeOf(sc, body));
  const int nb = fixedBodies(sc) + static_cast<int>(std::count_if(body.begin(), body.end(), [](int b) { return b >= 0; }));
  std::vector<sim::BodyLoad> ext(static_cast<std::size_t>(nb));
  std::vector<bool> free(static_cast<std::size_t>(nb), false);
  for (std::size_t k = 0; k < sc.disks.size(); ++k) {
    if (body[k] < 0 || sc.disks[k].state != State::mobile) continue;
    ext[static_cast<std::size_t>(body[k])].force = sc.weight;
    free[static_cast<std::size_t>(body[k])] = true;
  }
  std::vector<Eigen::Vector2d> v(sc.disks.size(), Eigen::Vector2d::Zero());
  if (std::none_of(free.begin(), free.end(), [](bool f) { return f; })) {
    fluid.loads(std::vector<sim::RigidMotion>(static_cast<std::size_t>(nb)), 1.0);
    ++solves;
    return v;
  }
  sim::MobilityResult r;
  try {
    r = fluid.freeMotion(ext, free);
  } catch (const std::runtime_error& e) {
    std::string where;
    for (std::size_t k = 0; k < sc.disks.size(); ++k)
      if (sc.disks[k].state == State::mobile)
        where += fmt::format("{}particle {} at ({:.4g}, {:.4g}) um, gap {:.3g} um", where.empty() ? "" : "; ", k + 1, sc.disks[k].x.x() * 1e6,
                             sc.disks[k].x.y() * 1e6, nearestSurface(sc, k).gap * 1e6);
    throw std::runtime_error(fmt::format("{} [{}]", e.what(), where));
  }
  solves += r.solves;
  for (std::size_t k = 0; k < sc.disks.size(); ++k)
    if (body[k] >= 0 && sc.disks[k].state == State::mobile) v[k] = r.motion[static_cast<std::size_t>(body[k])].velocity;
  return v;
}

int settleContacts(Scene& sc, double t, int& attached) {
  int contacts = 0;
  for (std::size_t k = 0; k < sc.disks.size(); ++k) {
    Disk& D = sc.disks[k];
    if (D.state != State::mobile) continue;
    if (sc.U > 0 && D.x.x() + D.a >= sc.L) {  // its leading edge reaches the outlet: beyond, the grid cannot hold it
      D.state = State::left;
      continue;
    }
    // A few passes: pushing a disk off one surface may bring it near another.
    for (int pass = 0; pass < 4; ++pass) {
      const Nearest n = nearestSurface(sc, k);
      const bool sticky = n.other < 0 || sc.disks[static_cast<std::size_t>(n.other)].state == State::deposited;
      if (sc.capture > 0 && sticky && n.gap < sc.capture) {
        D.state = State::deposited;
        D.attached_at = t;
        ++attached;
        if (n.gap < sc.contact_gap) D.x += (sc.contact_gap - n.gap) * n.normal;  // rests at the contact gap the grid can resolve
        break;
      }
      if (n.gap >= sc.contact_gap) break;
      ++contacts;
      if (n.other >= 0 && sc.disks[static_cast<std::size_t>(n.other)].state == State::mobile) {
        // Two moving disks: each moves back half the overlap.
        const double push = 0.5 * (sc.contact_gap - n.gap);
        D.x += push * n.normal;
        sc.disks[static_cast<std::size_t>(n.other)].x -= push * n.normal;
      } else {
        D.x += (sc.contact_gap - n.gap) * n.normal;
      }
    }
  }
  return contacts;
}

double pressureDrop(const sim::ResolvedStokes& fluid) {
  Eigen::ArrayXXd u, v, p;
  fluid.fields(u, v, p);
  const Eigen::ArrayXXd chi = fluid.cellSolidFraction();
  double in = 0, out = 0;
  int nin = 0, nout = 0;
  const auto last = p.cols() - 1;
  for (Eigen::Index j = 0; j < p.rows(); ++j) {
    if (chi(j, 0) < 0.5) in += p(j, 0), ++nin;
    if (chi(j, last) < 0.5) out += p(j, last), ++nout;
  }
  return (nin ? in / nin : 0.0) - (nout ? out / nout : 0.0);
}

}  // namespace mmval::particles::resolved
