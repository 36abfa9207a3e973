// Tensor-product Cartesian grids for the staggered (MAC) fluid solver.
//
// An Axis holds the n + 1 face coordinates of one direction (metres). Cells
// may be stretched: the solver's finite-volume stencils use the actual face
// and centre spacings, so a smoothly stretched axis keeps second order
// (ratios <= ~1.15 between neighbouring cells are used by the kinds).
#pragma once
#include <limits>
#include <vector>

namespace mmval::simulate {

class Axis {
 public:
  Axis() = default;
  explicit Axis(std::vector<double> faces);  ///< strictly increasing, >= 2 entries; throws std::invalid_argument
  int cells() const { return static_cast<int>(m_faces.size()) - 1; }
  double face(int i) const { return m_faces[static_cast<std::size_t>(i)]; }
  double width(int i) const { return m_faces[static_cast<std::size_t>(i) + 1] - m_faces[static_cast<std::size_t>(i)]; }
  double centre(int i) const { return 0.5 * (face(i) + face(i + 1)); }
  double lo() const { return m_faces.front(); }
  double hi() const { return m_faces.back(); }
  double length() const { return hi() - lo(); }
  double minWidth() const;
  double maxWidth() const;
  /// Index of the cell holding coordinate x (clamped to [0, cells - 1]).
  int cellOf(double x) const;
  const std::vector<double>& faces() const { return m_faces; }

 private:
  std::vector<double> m_faces;
};

/// n equal cells on [lo, hi].
Axis uniformAxis(double lo, double hi, int n);

/// Cells of size ~h_fine on [a, b] (rounded so they fit exactly), growing
/// geometrically by at most `ratio` per cell outside it, up to h_max, and
/// rescaled so the outer parts end exactly at lo and hi.
/// Needs lo <= a < b <= hi, 0 < h_fine <= h_max, ratio >= 1.
/// With an anchor in [a, b]: cells of exactly h_fine with a face at the anchor, the box
/// trimmed to whole cells (a remainder thinner than h_fine / 2 next to lo or hi joins the
/// neighbouring cell), so a body centred at the anchor is cut symmetrically about it.
Axis refinedAxis(double lo, double hi, double a, double b, double h_fine, double ratio, double h_max,
                 double anchor = std::numeric_limits<double>::quiet_NaN());

/// `axis` with its cells next to both ends replaced by cells that start at h_end
/// at the end and grow by `ratio` per cell until they reach the axis's own
/// cells, which are kept from the first original face the graded cells reach
/// (the graded part is rescaled to end exactly there). For wall layers, e.g. the
/// unsteady Stokes layer on channel walls. Ends whose cells are already <= h_end
/// are left as they are. Needs h_end > 0, ratio > 1.
Axis wallGradedAxis(const Axis& axis, double h_end, double ratio);

/// `axis` with each cell between the faces nearest to a and b split into m equal cells, and
/// graded layers outside that box (widths growing by `ratio` per cell from the fine width)
/// until they reach the axis's own cells. Every original face is kept, so a face through a
/// body's centre stays. For a second, finer box about a body inside refinedAxis's box. Where
/// the layer cannot reach the axis's cells before its end (a wall within the layer's span, or
/// cells there growing as fast as the layer), the box extends to that end.
/// m = 1 returns the axis; needs m >= 1, ratio > 1, a < b and a whole cell between them.
Axis innerRefinedAxis(const Axis& axis, double a, double b, int m, double ratio);

}  // namespace mmval::simulate
