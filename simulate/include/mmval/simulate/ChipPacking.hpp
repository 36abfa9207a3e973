// Sand-pack-like micromodel patterns (docs/chip-generator.md): random polydisperse discs with a minimum
// gap, between two solid walls, with open inlet and outlet columns.
//
// Grain diameters are lognormal (mean, coefficient of variation), as sieved sands are usually
// described (e.g. Pore2Chip draws its grain sizes from a distribution in the same way; the code
// here is our own). The discs start at random positions and are pushed apart (Gauss-Seidel
// overlap removal, each disc inflated by half the minimum gap) until no two come closer than the
// gap, so every throat between grains is at least the gap wide and the pore space percolates.
// Porosity is then met on the rendered pixels by scaling all radii and relaxing again.
//
// Units: lengths in pixels inside this header's types (the pixel is the pattern's only scale);
// the caller converts with the pixel size.
#pragma once
#include <cstdint>
#include <vector>

#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::simulate {

struct ChipDisc {
  double x = 0, y = 0;  ///< centre, px (x along the flow from the left edge, y from the top row)
  double r = 0;         ///< radius, px
};

/// What to pack. Every length in pixels.
struct ChipPackingSpec {
  int cols = 0, rows = 0;           ///< image size
  int wall_px = 2;                  ///< solid rows at the top and the bottom (no-flow sides)
  double port_px = 0;               ///< grain-free columns at the inlet (left) and outlet (right)
  double mean_diameter_px = 20;     ///< mean grain diameter (lognormal)
  double diameter_cv = 0.3;         ///< coefficient of variation of the diameter
  double min_gap_px = 3;            ///< smallest distance between grain surfaces (and grain to wall)
  double porosity = 0.58;           ///< target porosity of the whole image, walls included
  double porosity_tolerance = 0.005;
  std::uint64_t seed = 1;
};

/// A throat: the narrowest point of the pore channel between two neighbouring grains (or a grain
/// and a wall): the gap along the line of centres, counted when its midpoint is nearer to those
/// two than to any other grain (it lies on the pore space's medial axis).
struct ChipThroat {
  double width_px = 0;
  double x = 0, y = 0;  ///< midpoint, px
};

struct ChipPacking {
  std::vector<ChipDisc> discs;
  BoolArray solid;              ///< rows x cols, true = grain or wall
  double porosity_total = 0;    ///< pore pixels / all pixels
  int relax_sweeps = 0;         ///< Gauss-Seidel sweeps of the last relaxation
  int porosity_rounds = 0;      ///< radius scalings used to meet the porosity
};

/// Lognormal diameter parameters with the given mean and CV: sigma^2 = ln(1 + cv^2),
/// mu = ln(mean) - sigma^2 / 2. Diameters are clipped to [kMinDiameterFactor, kMaxDiameterFactor]
/// x mean (a chip cannot etch grains far below its feature size; the clip changes the mean by
/// < 1 % for cv <= 0.5).
inline constexpr double kMinDiameterFactor = 0.3, kMaxDiameterFactor = 3.0;

/// Packs and renders. Throws std::invalid_argument when the discs cannot be separated by the gap
/// (the inflated discs would cover more than kMaxInflatedFraction of the area: lower porosity
/// than the gap allows) or the porosity cannot be met within the tolerance.
ChipPacking packChip(const ChipPackingSpec& spec);

/// Inflated area fraction above which relaxation is refused: random close packing of
/// polydisperse discs is ~0.84 (Desmond & Weeks 2009, PRE 80, 051305); 0.80 keeps a margin so the
/// overlap removal converges in a few hundred sweeps.
inline constexpr double kMaxInflatedFraction = 0.80;

/// Renders discs and walls (pixel centres inside a disc are grain).
BoolArray renderChip(const std::vector<ChipDisc>& discs, int cols, int rows, int wall_px);

/// The throats of a packing (grain-grain and grain-wall), widths in px.
std::vector<ChipThroat> chipThroats(const std::vector<ChipDisc>& discs, int rows, int wall_px, double max_width_px);

}  // namespace mmval::simulate
