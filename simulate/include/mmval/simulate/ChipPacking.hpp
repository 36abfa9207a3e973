// Sand-pack-like micromodel patterns (docs/chip-generator.md): random polydisperse discs with a minimum
// gap, between two solid walls, with open inlet and outlet columns.
//
// Grain diameters are lognormal (mean, coefficient of variation), as sieved sands are usually
// described (e.g. Pore2Chip draws its grain sizes from a distribution in the same way; the code
// here is our own).
//
// Initial placement (ChipPlacement::uniform, the default): random sequential addition (RSA;
// Widom 1966, J. Chem. Phys. 44, 3888; Feder 1980, J. Theor. Biol. 87, 237), largest disc first,
// each disc kept at the first of a fixed number of random positions that is at least the gap from
// every disc placed so far; a disc that finds none, and every disc after a run of such failures,
// goes one per cell of a jittered grid over the pattern instead (about a fifth of the discs at the
// paper's statistics). Why: a Poisson start (independent uniform positions, the former method,
// still ChipPlacement::poisson) has density fluctuations of Poisson size at every scale, and
// overlap removal only pushes discs apart where they overlap: the dense patches end as jammed
// clusters beside open patches that stay open, and 0.5 mm crops of one 2 x 1 mm chip gave k from
// 2.1 to 5.0 D. RSA cannot exceed its jamming coverage anywhere (0.547 for equal discs, Feder
// 1980; higher for polydisperse discs added largest first), which bounds the local density from
// above, and every region keeps filling until it is near that coverage, which bounds it from
// below: density fluctuations at a few grain diameters are far below Poisson's (windowPorosity
// below: window porosity SD ~0.2 of the binomial SD, against ~0.6-0.9 for the Poisson start). The
// jittered grid is stratified sampling (one disc per equal cell), again far below Poisson. The
// grid's discs overlap their neighbours at the start; the relaxation separates them.
//
// Then the discs are pushed apart (Gauss-Seidel overlap removal, each disc inflated by half the
// minimum gap, radii grown in stages) until no two come closer than the gap, so every throat
// between grains is at least the gap wide and the pore space percolates. The rendering then clears
// the few edge pixels whose squares come closer than the gap to another grain's (or a wall), so
// the mask keeps the gap too (renderChipLabels). Porosity is met on the pixels by scaling all
// radii and relaxing again (on the rendering without clearing, as before the gap was kept), then
// the kept-gap rendering grows every disc by the same fraction of a pixel to give back the area
// the clearing took.
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

/// Initial placement of the discs before overlap removal (see the top of this header).
enum class ChipPlacement {
  uniform,  ///< random sequential addition with the gap rule, largest first; the rest on a jittered grid
  poisson,  ///< independent uniform positions (the former start; kept as the reference it is compared with)
};

/// What to pack. Every length in pixels.
struct ChipPackingSpec {
  int cols = 0, rows = 0;           ///< image size
  /// Solid rows at the top and the bottom (no-flow sides). 0: no walls, the edges are mirror planes
  /// (a strip of a wider chip; the flow solves' sides are slip): discs keep half the minimum gap
  /// from an edge, so the gap to their mirror image is the minimum gap.
  int wall_px = 2;
  double port_px = 0;               ///< grain-free columns at the inlet (left) and outlet (right)
  double mean_diameter_px = 20;     ///< mean grain diameter (lognormal)
  double diameter_cv = 0.3;         ///< coefficient of variation of the diameter
  double min_gap_px = 3;            ///< smallest distance between grain surfaces (and grain to wall)
  double porosity = 0.58;           ///< target porosity of the whole image, walls included
  double porosity_tolerance = 0.005;
  ChipPlacement placement = ChipPlacement::uniform;
  std::uint64_t seed = 1;
};

/// Homogeneity: porosity of non-overlapping square windows tiling the grain region (between the
/// ports and the walls), centred in it.
struct ChipWindowPorosity {
  int side_px = 0;       ///< window side
  int count = 0;         ///< windows
  double mean = 0, sd = 0, min = 0, max = 0;  ///< porosity over the windows (sd: n - 1 in the denominator)
  /// SD expected if the same discs were placed independently (Poisson): each disc's centre lies
  /// in a window with probability p = window / region area, so the grain area of a window has
  /// variance p (1 - p) sum_i (pi r_i^2)^2 and the porosity SD is its root over the window area
  /// (binomial; discs cut by the window edge and overlaps neglected: an overestimate by
  /// O(diameter / side)).
  double poisson_sd = 0;
};

/// Window side of the homogeneity statistic, in mean grain diameters: k is tuned on tiles of
/// tens of grains, so fluctuations at this scale are what make one tile differ from another.
inline constexpr double kHomogeneityWindowDiameters = 10;

/// A throat: the narrowest point of the pore channel between two neighbouring grains (or a grain
/// and a wall): the gap along the line of centres, counted when its midpoint is nearer to those
/// two than to any other grain (it lies on the pore space's medial axis).
struct ChipThroat {
  double width_px = 0;
  double x = 0, y = 0;  ///< midpoint, px
  /// The two solids: disc indices; b = kThroatTopWall / kThroatBottomWall for a wall. Mirror
  /// sides: b is the disc whose image it is (b == a: the disc's own image), `mirror` says which edge.
  int a = -1, b = -1;
  int mirror = 0;  ///< 0: no image; -1: b's image across the top edge; +1: across the bottom edge
};
inline constexpr int kThroatTopWall = -1, kThroatBottomWall = -2;

/// Disc index of each pixel (rows x cols): -1 pore or wall.
using ChipLabels = Eigen::Array<int, Eigen::Dynamic, Eigen::Dynamic>;

struct ChipPacking {
  std::vector<ChipDisc> discs;
  BoolArray solid;              ///< rows x cols, true = grain or wall
  ChipLabels labels;            ///< rows x cols, the disc each grain pixel belongs to (renderChipLabels)
  int cleared_px = 0;           ///< grain pixels the rendering cleared to keep the minimum gap (renderChipLabels)
  double render_grow_px = 0;    ///< growth of the discs in the final rendering (renderChipLabels), px
  double porosity_total = 0;    ///< pore pixels / all pixels
  int relax_sweeps = 0;         ///< Gauss-Seidel sweeps of the last relaxation
  int porosity_rounds = 0;      ///< radius scalings used to meet the porosity
  int sequentially_added = 0;   ///< uniform placement: discs placed by RSA (the rest on the jittered grid)
  ChipWindowPorosity homogeneity;  ///< windows of kHomogeneityWindowDiameters mean diameters
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

/// Renders discs and walls (pixel centres inside a disc are grain). min_gap_px > 0: then clears
/// the grain pixels that break the minimum gap as rendered (renderChipLabels).
BoolArray renderChip(const std::vector<ChipDisc>& discs, int cols, int rows, int wall_px, double min_gap_px = 0, double grow_px = 0);

/// Distance between the unit squares of pixels (i1, j1) and (i2, j2), px: 0 for neighbours,
/// sqrt(a^2 + b^2) for squares a columns and b rows apart.
double pixelSquareGap(int di, int dj);

/// The grain pixels of a rendering, labelled by disc: a pixel is grain when its centre lies inside
/// a disc grown by grow_px (as renderChip; packChip grows by the fraction of a pixel that gives
/// back the grain area the clearing below takes). A pixel square reaches up to 0.71 px beyond its disc, so two grains
/// whose discs keep the minimum gap can render closer (lattice values 2, sqrt 5, 2 sqrt 2 px for a
/// 3 px gap). min_gap_px > 0: then, while two grain pixels of different discs have squares closer
/// than min_gap_px (pixelSquareGap), the one whose centre lies less deep inside its disc
/// (r - distance to the centre) is cleared (ties: the later in column-major order), and so is a
/// grain pixel closer than min_gap_px to a wall row (wall_px > 0) or, with mirror sides
/// (wall_px 0), closer than min_gap_px / 2 to the top or bottom edge (its gap to its own image is
/// twice that; its gap to another grain's image is then at least min_gap_px too). `cleared`
/// receives the number of pixels cleared.
ChipLabels renderChipLabels(const std::vector<ChipDisc>& discs, int cols, int rows, int wall_px, double min_gap_px, double grow_px = 0,
                            int* cleared = nullptr);

/// Grain pairs (and grain-wall or grain-edge pairs) whose pixel squares are closer than
/// min_gap_px in `labels` (the rule of renderChipLabels): 0 when the rendering keeps the gap.
int renderedGapViolations(const ChipLabels& labels, int wall_px, double min_gap_px);

/// Window porosity of `solid` (windows of side_px, tiling the spec's grain region) with the
/// Poisson reference from `discs`. count = 0 (and zeros) when not one window fits.
ChipWindowPorosity windowPorosity(const BoolArray& solid, const std::vector<ChipDisc>& discs, const ChipPackingSpec& spec, int side_px);

/// The throats of a packing (grain-grain and grain-wall), widths in px. wall_px 0: mirror sides,
/// the throats between the discs and the mirror images of the discs across the top and bottom
/// edges instead of grain-wall ones (a disc's throat to its own image is twice its distance to
/// the edge, its midpoint on the edge).
std::vector<ChipThroat> chipThroats(const std::vector<ChipDisc>& discs, int rows, int wall_px, double max_width_px);

/// Each throat's width as rendered, px, in the order of `throats`: the smallest distance between
/// the pixel squares of its two grains in `labels` (pixelSquareGap), or from its grain's squares
/// to the wall rows, or with mirror sides to the image's squares (to its own image: twice the
/// distance to the edge). NaN when a grain has no pixel.
std::vector<double> renderedThroatWidths(const std::vector<ChipThroat>& throats, const ChipLabels& labels, int wall_px);

}  // namespace mmval::simulate
