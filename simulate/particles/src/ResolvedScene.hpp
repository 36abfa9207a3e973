// Internal: the scene model of the particles-resolved kind (Resolved.cpp) -
// rigid disks among grains and obstacles, their Stokes mobility, contacts and
// attachment. Separate from the runner so that the physics reads on its own.
#pragma once
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/ResolvedStokes.hpp"

namespace mmval::particles::resolved {

enum class State { mobile, deposited, left };

struct Disk {
  Eigen::Vector2d x{0, 0};  ///< centre, m
  double a = 0;             ///< radius, m
  State state = State::mobile;
  double attached_at = -1;  ///< time of attachment, s
};

struct Scene {
  double L = 0, W = 0, U = 0, h = 0;  ///< channel length, width, mean inflow speed (0: closed box), Hele-Shaw depth (0: plane); SI
  std::shared_ptr<const simulate::MaskShape> grains;  ///< from geometry.mask (body 0), or null
  std::vector<simulate::Circle> obstacles;
  std::vector<Disk> disks;
  double contact_gap = 0, capture = 0;  ///< m
  Eigen::Vector2d weight{0, 0};  ///< net gravity force per unit depth on one disk, N/m
};

/// Nearest surface to a disk: gap (m), unit normal from the surface towards the disk, and what it is.
struct Nearest {
  double gap = 1e300;
  Eigen::Vector2d normal{0, 1};
  int other = -1;  ///< another disk's index, or -1 for walls, grains and obstacles
};

/// Fixed bodies: the grain image (one body) and the circular obstacles.
int fixedBodies(const Scene& sc);
/// The shape the fluid sees: grains, obstacles, then every particle still inside (body_of_disk: -1 for departed ones).
std::shared_ptr<const simulate::Shape> shapeOf(const Scene& sc, std::vector<int>& body_of_disk);
Nearest nearestSurface(const Scene& sc, std::size_t k);
/// Velocities of the disks (zero for deposited and departed ones) at the current positions: the
/// mobility problem with each mobile disk free under its weight; the flow of that motion stays in
/// `fluid`. A failure names every moving particle's position and gap.
std::vector<Eigen::Vector2d> velocities(simulate::ResolvedStokes& fluid, const Scene& sc, int& solves);
/// Attachment, hard-core contacts and the outlet after a step at time t. Returns the contacts resolved.
int settleContacts(Scene& sc, double t, int& attached);
/// Mean fluid pressure of the first cell column (inlet) minus that of the last (outlet), Pa.
double pressureDrop(const simulate::ResolvedStokes& fluid);

}  // namespace mmval::particles::resolved
