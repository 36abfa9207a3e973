// Connectivity of the pore space of a binary mask: a geometry is checked before any solve.
//
// Pores are 4-connected fluid pixels (an edge shared, not just a corner: a
// diagonal contact carries no flow on a Cartesian grid). Only components that
// touch both the inlet side and the outlet side carry flow; the others are
// isolated pores, excluded from the flow solve (turned solid) and from the
// connected porosity. Periodic directions wrap.
//
// Throats: a flow path is only as resolved as its narrowest
// cross-section. narrowestThroat() finds the widest inlet-to-outlet path (the
// one whose narrowest cross-section is largest: a grid that cannot resolve it
// cannot resolve any path) and that cross-section's width and position.
#pragma once
#include <limits>
#include <stdexcept>

#include <Eigen/Core>

#include "mmval/simulate/Geometry.hpp"

namespace mmval::simulate {

using BoolArray = Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic>;

/// Thrown when no fluid path joins the inlet to the outlet.
class NoFlowPath : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct PoreSpaceReport {
  double porosity_total = 0;      ///< fluid pixels / all pixels
  double porosity_connected = 0;  ///< pixels of inlet-to-outlet components / all pixels
  int components = 0;             ///< 4-connected fluid components
  int spanning_components = 0;    ///< of which touch inlet and outlet
  BoolArray solid_connected;      ///< the mask with every non-spanning pore made solid
};

/// Flow along x from column 0 (inlet) to the last column (outlet); rows are y.
/// periodic_y joins the first and last rows. Throws NoFlowPath when no
/// component spans (an all-solid mask included).
PoreSpaceReport analysePoreSpace(const BoolArray& solid, bool periodic_y = false);

/// The narrowest cross-section of the widest inlet-to-outlet path, in metres.
struct Throat {
  bool path = false;   ///< a 4-connected fluid path joins the inlet (left) and the outlet (right)
  double width_m = std::numeric_limits<double>::infinity();  ///< infinite: no solid narrows the path
  double x_m = 0, y_m = 0;  ///< centre of the pixel where the widest path is narrowest
};

/// Widest path through the fluid of a mask (row 0 at the top, y = origin_y + (rows - row - 1/2) pixel,
/// x = origin_x + (col + 1/2) pixel), flow along x. The local width of a fluid pixel is its shortest
/// fluid chord: the run of fluid pixels through it along x, y (x pixel) and the two diagonals (x
/// sqrt 2 pixel), a run that reaches the edge of the mask not counting as narrow (an inlet, an
/// outlet, a slip side); periodic directions wrap the x and y runs. A one-pixel slot is one pixel
/// wide, a gap of g pixels g pixels, to one pixel. periodic_x / periodic_y wrap the runs; paths join
/// the left and right edges within the mask (periodic_y paths may cross the top / bottom edge).
/// mirror_y: the top and bottom edges are mirror planes (a strip with mirror sides, `mmval chip
/// --wall-px 0`): a run that reaches one of them ends at the solid's mirror image, so it counts
/// twice its length (a run reaching both, or an inlet or outlet, still counts as open).
Throat narrowestThroat(const BoolArray& solid, double pixel_m, bool periodic_x = false, bool periodic_y = false, double origin_x = 0,
                       double origin_y = 0, bool mirror_y = false);

/// The same for a Shape on [x0, x1] x [y0, y1], sampled at the centres of square samples of about
/// sample_m (at most `max_samples` in all: coarser samples for a larger domain). The width is then
/// known to about one sample.
Throat narrowestThroat(const Shape& shape, double x0, double x1, double y0, double y1, double sample_m, bool periodic_x, bool periodic_y,
                       long long max_samples = 4'000'000);

}  // namespace mmval::simulate
