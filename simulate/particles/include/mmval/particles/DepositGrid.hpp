// Where deposited particles sit, in the fluid's terms (four-way coupling of the
// micromodel scene). The chip is depth-averaged, so a deposit is a
// volume booked on the image's pixels, in one of two ways:
//  - a column deposit (particles caught at a grain wall) fills the pixel's
//    column (pixel area x chip depth); the column closes (becomes solid for the
//    fluid solver and the particles) when deposits fill `fill_fraction` of it;
//  - a layer deposit (particles resting on a plate, away from grains) thins the
//    local aperture: a layer of solid volume fraction `packing` and thickness
//    volume / (packing x pixel area) grows on the plate, and the pixel closes
//    only when its aperture falls below `min_aperture`. A deposit adds at most
//    `max_layer` (one particle diameter: a monolayer patch) to any one pixel and
//    spreads over the nearest pixels for the rest, so a parcel of many real
//    particles lands as the monolayer patch those particles would cover.
// Volume that does not fit spills into the nearest open pore pixels (nearest
// first, ties by index), so deposited volume is conserved exactly. This is the
// constant-volume idea of the paper's dilation of sub-cell particles
// (Elrahmani et al. 2022, Powder Technol. 398:117130, the coupling) on the pixel grid. A deposit may stand for
// `weight` real particles (a parcel, when the scene simulates a sample).
//
// Packing of a plate layer: colloids attaching to a plate at random form a
// random-sequential-adsorption monolayer that jams at a projected coverage of
// 0.547 (Feder 1980, J. Colloid Interface Sci. 75:68; Hinrichsen, Feder & Jossang
// 1986, J. Stat. Phys. 44:793). Spheres of diameter d at coverage 0.547 hold
// 0.547 x (2/3) d of solid per unit area, so a layer of thickness d has solid
// fraction 0.365: the default, which makes a full monolayer exactly one
// diameter thick (its top is where the flow above it meets the spheres).
#pragma once
#include <cstdint>
#include <vector>

#include "mmval/core/Checkpoint.hpp"
#include "mmval/particles/MicromodelFlow.hpp"

namespace mmval::particles {

struct DepositLayerModel {
  double packing = 0.547 * 2.0 / 3.0;  ///< solid volume fraction of a plate layer (random monolayer at jamming)
  double min_aperture = 0.0;           ///< m; a pixel whose aperture falls below this closes (0: only when filled)
};

class DepositGrid {
 public:
  /// `grains`: rows x cols solid mask; capacity of a pore pixel's column = fill_fraction * pixel^2 * depth.
  /// Throws std::invalid_argument on non-positive sizes, fill_fraction outside (0, 1], packing outside
  /// (0, 1] or min_aperture outside [0, depth).
  DepositGrid(const PixelMask& grains, double pixel, double depth, double fill_fraction, DepositLayerModel layer = {});

  /// Column deposit: adds `volume` (m3) at the point (x, y) (m, y up). Returns how many pixels closed.
  int add(double x, double y, double volume);
  /// Layer deposit of `volume` (m3) at (x, y), at most `max_layer` (m) thicker on any one pixel. Returns how many pixels closed.
  int addLayer(double x, double y, double volume, double max_layer);

  /// Pixels closed by deposits (rows x cols).
  const PixelMask& closed() const { return m_closed; }
  std::int64_t closedCount() const { return m_closed_count; }
  /// Local aperture per pixel (row-major, row 0 at the top), m: depth minus the layer thickness;
  /// the full depth on grains, 0 on closed pixels.
  std::vector<double> aperture() const;
  /// Lost aperture summed over the pore pixels in units of a whole column: a closed pixel counts 1,
  /// an open one its layer thickness / depth. Column deposits alone make this closedCount().
  double lostColumns() const { return m_lost; }
  double depositedVolume() const { return m_total; }  ///< m3, everything ever added
  double capacity() const { return m_capacity; }      ///< m3 per pixel column
  const DepositLayerModel& layerModel() const { return m_layer_model; }

  void save(CheckpointWriter& w) const;
  void load(CheckpointReader& r);

 private:
  /// Visits open pore pixels nearest first from (x, y); `take(k)` returns the volume pixel k accepts.
  template <class Take>
  int spread(double x, double y, double volume, Take take);
  void close(std::size_t k);

  PixelMask m_grains, m_closed;
  double m_pixel, m_depth, m_capacity, m_total = 0.0, m_lost = 0.0;
  DepositLayerModel m_layer_model;
  std::vector<double> m_volume;  ///< column volume per pixel, row-major (row * cols + col)
  std::vector<double> m_layer;   ///< layer solid volume per pixel
  std::int64_t m_closed_count = 0;
};

}  // namespace mmval::particles
