// Connectivity of the pore space of a binary mask (geometry sanity, issue 4).
//
// Pores are 4-connected fluid pixels (an edge shared, not just a corner: a
// diagonal contact carries no flow on a Cartesian grid). Only components that
// touch both the inlet side and the outlet side carry flow; the others are
// isolated pores, excluded from the flow solve (turned solid) and from the
// connected porosity. Periodic directions wrap.
#pragma once
#include <stdexcept>

#include <Eigen/Core>

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

}  // namespace mmval::simulate
