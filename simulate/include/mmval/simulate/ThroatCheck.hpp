// Resolution checks the fluid case kinds run before a solve (issue 22). A flow path
// is only as resolved as its narrowest throat: narrower than one cell the grid cannot carry flow
// through it (the solve fails or returns a number that means nothing), narrower than two the
// answer can be off by a large factor (a one-pixel throat at 1 cell per pixel: +197 %). The case
// kinds know which key sets the resolution; these helpers name it.
#pragma once
#include <string>

#include "mmval/core/CaseKind.hpp"
#include "mmval/simulate/FlowSolver.hpp"

namespace mmval::simulate {

/// Throats narrower than this many cells get a warning.
inline constexpr double kWarnThroatCells = 2.0;

/// The narrowest throat of the widest inlet-to-outlet path of `p` (flow along x; a MaskShape is
/// read at its pixels, other shapes sampled at 1/8 cell), in cells of p's grid there. Throws
/// NumericalFailure naming `key` (the case key that set the resolution, whose value is
/// `key_value`) and the value that gives the throat 2 cells when it is narrower than one cell;
/// below kWarnThroatCells appends a warning to out.details["warnings"] and prints it on stderr
/// (rank 0, unless quiet). Returns the width in cells (infinity: no solid narrows the path; no
/// check without a shape).
double checkThroats(const FlowProblem& p, const std::string& key, double key_value, RunOutput& out, bool quiet);

/// s.solve(), with a FlowFailure rethrown naming `key`.
const FlowStats& solveNamingKey(SteadyFlowSolver& s, const std::string& key);

}  // namespace mmval::simulate
