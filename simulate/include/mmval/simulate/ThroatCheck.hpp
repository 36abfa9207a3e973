// Resolution checks the fluid case kinds run before a solve. A flow path
// is only as resolved as its narrowest throat: narrower than one cell the grid cannot carry flow
// through it (the solve fails or returns a number that means nothing), narrower than two the
// answer can be off by a large factor (a one-pixel throat at 1 cell per pixel: +197 %). The case
// kinds know which key sets the resolution; these helpers name it.
#pragma once
#include <limits>
#include <string>

#include "mmval/core/CaseKind.hpp"
#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::simulate {

/// Throats narrower than this many cells get a warning.
inline constexpr double kWarnThroatCells = 2.0;
/// image-permeability warns below this many cells across: a throat of a staircase
/// mask changes the chip's permeability by several percent until ~4 cells cross it.
inline constexpr double kWarnImageThroatCells = 4.0;

/// Where the check found the narrowest throat, for result.json (pixels: of the image, when
/// the problem's shape is a mask or image_pixel_m was given; else NaN).
struct ThroatFound {
  Throat throat;
  double cells = 0;  ///< width in cells of the grid there
  double x_px = std::numeric_limits<double>::quiet_NaN(), y_px = std::numeric_limits<double>::quiet_NaN(), width_px = std::numeric_limits<double>::quiet_NaN();
};

/// The narrowest throat of the widest inlet-to-outlet path of `p` (flow along x; a MaskShape is
/// read at its pixels, other shapes sampled at 1/8 cell), in cells of p's grid there. Throws
/// NumericalFailure naming `key` (the case key that set the resolution, whose value is
/// `key_value`) and the value that gives the throat 2 cells when it is narrower than one cell;
/// below kWarnThroatCells appends a warning to out.details["warnings"] and prints it on stderr
/// (rank 0, unless quiet). Returns the width in cells (infinity: no solid narrows the path; no
/// check without a shape). warn_cells sets the warning's threshold; image_pixel_m > 0 (the image's
/// pixel size, the image covering p's domain) adds the throat's position and width in pixels of the
/// image to the messages (x from the left edge, y from the top, as the image's columns and rows).
/// `found`, if given, receives the throat.
double checkThroats(const FlowProblem& p, const std::string& key, double key_value, RunOutput& out, bool quiet, double warn_cells = kWarnThroatCells,
                    double image_pixel_m = 0, ThroatFound* found = nullptr);

/// s.solve(), with a FlowFailure rethrown naming `key`.
const FlowStats& solveNamingKey(SteadyFlowSolver& s, const std::string& key);

}  // namespace mmval::simulate
