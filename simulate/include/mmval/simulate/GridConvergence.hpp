// Grid convergence of a resolution ladder: observed order, Richardson extrapolation and
// Roache's grid convergence index, for grids refined by any ratios.
//
// Three grids (1 finest, spacings h1 < h2 < h3, values f1, f2, f3), after Celik et al. (2008),
// "Procedure for estimation and reporting of uncertainty due to discretization in CFD
// applications", J. Fluids Eng. 130, 078001, Eqs. (3)-(7): with e21 = f2 - f1, e32 = f3 - f2,
// s = sign(e32 / e21), r21 = h2 / h1, r32 = h3 / h2, the observed order p solves
//   p ln r21 = ln|e32 / e21| + ln((r21^p - s) / (r32^p - s))
// (for r21 = r32 the last term vanishes); the extrapolated value is
//   f_ext = (r21^p f1 - f2) / (r21^p - 1)
// and the fine grid's convergence index (Roache 1994, J. Fluids Eng. 116, 405)
//   GCI = Fs |(f1 - f2) / f1| / (r21^p - 1),  Fs = 1.25.
// Convergence that is not monotone (s < 0: the values oscillate) or not converging (the change
// grows on refinement) has no observed order: the result says so, carries no extrapolated value,
// and its GCI falls back to the two-grid form: Fs = 3 with the scheme's formal order. Two grids
// give that form too.
//
// Four or more grids: also a least-squares fit f = f0 + a h^p over every level, after Eca & Hoekstra
// (2014), "A procedure for the estimation of the numerical uncertainty of CFD calculations based on
// grid refinement studies", J. Comput. Phys. 262, 104-130. It stands where three grids cannot: a
// ladder whose level-to-level scatter (the geometry's alignment with each grid) is as large as the
// finest differences, where the three-grid order swings with the choice of levels. f0 and a are the
// linear least-squares fit for each p, p minimises the residual over (0, 8]; as theirs, two fits,
// the levels weighed alike and weighed by 1 / h, the one with the smaller standard deviation
// sqrt(n sum w r^2 / (n - 3)) kept (the scatter below); the uncertainty of the finest level is
// Fs |f1 - f0| + scatter + |f1 - fit(h1)| with Fs = 1.25 when 0.5 <= p <= 2.1 (Eca & Hoekstra's
// range of a credible order for a second-order scheme), else that of the fit at the formal order
// with Fs = 3 (this simplifies their procedure, which also weighs the levels and compares fits).
// The three finest levels decide while their order is credible (0.5 to twice the formal order).
// Where they give no order or one beyond that, and the fitted order lies inside (0.05, 7.9), the fit
// stands for the ladder: status "least squares", observed_order, extrapolated and gci (then this
// uncertainty) are the fit's, and the note keeps what the three finest levels alone say.
#pragma once
#include <limits>
#include <string>
#include <vector>

namespace mmval::simulate {

struct GridConvergence {
  static constexpr double nan = std::numeric_limits<double>::quiet_NaN();
  /// "least squares" (four or more levels, fitted), "monotone" (order observed from the three
  /// finest), "oscillatory", "diverging", "unchanged" (the finest two values are equal), "two
  /// levels" or "one level".
  std::string status;
  bool has_order = false;        ///< status "monotone" or "least squares"
  double observed_order = nan;   ///< p from the three finest levels (has_order only)
  double order_used = nan;       ///< p in the GCI: observed, else the formal order given
  double safety_factor = nan;    ///< Fs: 1.25 with an observed order, else 3
  double extrapolated = nan;     ///< Richardson f_ext (NaN unless has_order or two levels)
  double fine = nan;             ///< value of the finest level
  double gci = nan;              ///< relative GCI of the finest level (fraction of |fine|)
  double band_lo = nan, band_hi = nan;  ///< fine -/+ gci |fine|
  std::string note;              ///< one sentence for people (why no order, ...)
  /// Least-squares fit over every level (four or more levels; see the header's comment).
  bool has_fit = false;
  bool fit_weighted = false;      ///< the fit weighing levels by 1 / h had the smaller standard deviation
  int fit_levels = 0;
  double fit_order = nan;         ///< p of the best fit (an end of (0, 8] when it runs there)
  double fit_extrapolated = nan;  ///< f0 of the best fit
  double fit_scatter = nan;       ///< standard deviation of the residuals (units of f)
  double fit_uncertainty = nan;   ///< relative uncertainty of the finest level (fraction of |fine|)
  double fit_order_used = nan;    ///< p of the fit the uncertainty uses (the formal order outside [0.5, 2.1])
};

/// `h` the grid spacings (or 1 / resolution) of the levels, `f` their values, in the same order;
/// the three (two) finest levels are used. formal_order: the scheme's order, used when no order can
/// be observed. Throws std::invalid_argument for mismatched sizes, spacings that are not positive
/// or two levels with the same spacing.
GridConvergence gridConvergence(const std::vector<double>& h, const std::vector<double>& f, double formal_order);

}  // namespace mmval::simulate
