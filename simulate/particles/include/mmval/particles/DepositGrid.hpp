// Where deposited particles sit, as solid in the fluid grid (four-way coupling
// of the micromodel scene, issue 6). The chip is depth-averaged, so a deposit
// is a volume in a pixel's column (pixel area x chip depth). A column closes
// (becomes solid for the fluid solver and for the particles) when deposits fill
// `fill_fraction` of it; a deposit that does not fit spills into the nearest
// open pore pixels (volume is conserved exactly). This is the constant-volume
// idea of the paper's dilation of sub-cell particles (paper-notes.md, coupling)
// on the pixel grid. A deposit may stand for `weight` real particles (a parcel,
// when the scene simulates a sample of the suspension).
#pragma once
#include <cstdint>
#include <vector>

#include "mmval/particles/Checkpoint.hpp"
#include "mmval/particles/MicromodelFlow.hpp"

namespace mmval::particles {

class DepositGrid {
 public:
  /// `grains`: rows x cols solid mask; capacity of a pore pixel = fill_fraction * pixel^2 * depth.
  DepositGrid(const PixelMask& grains, double pixel, double depth, double fill_fraction);

  /// Adds `volume` (m3) at the point (x, y) (m, y up). Returns how many pixels closed.
  int add(double x, double y, double volume);
  /// Pixels closed by deposits (rows x cols).
  const PixelMask& closed() const { return m_closed; }
  std::int64_t closedCount() const { return m_closed_count; }
  double depositedVolume() const { return m_total; }  ///< m3, everything ever added
  double capacity() const { return m_capacity; }      ///< m3 per pixel

  void save(CheckpointWriter& w) const;
  void load(CheckpointReader& r);

 private:
  PixelMask m_grains, m_closed;
  double m_pixel, m_capacity, m_total = 0.0;
  std::vector<double> m_volume;  ///< per pixel, row-major (row * cols + col)
  std::int64_t m_closed_count = 0;
};

}  // namespace mmval::particles
