#include "mmval/simulate/Grid.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mmval::simulate {

Axis::Axis(std::vector<double> faces) : m_faces(std::move(faces)) {
  if (m_faces.size() < 2) throw std::invalid_argument("an axis needs at least one cell");
  for (std::size_t i = 1; i < m_faces.size(); ++i)
    if (!(m_faces[i] > m_faces[i - 1])) throw std::invalid_argument("axis faces must increase strictly");
}

double Axis::minWidth() const {
  double w = width(0);
  for (int i = 1; i < cells(); ++i) w = std::min(w, width(i));
  return w;
}

double Axis::maxWidth() const {
  double w = width(0);
  for (int i = 1; i < cells(); ++i) w = std::max(w, width(i));
  return w;
}

int Axis::cellOf(double x) const {
  auto it = std::upper_bound(m_faces.begin(), m_faces.end(), x);
  int i = static_cast<int>(it - m_faces.begin()) - 1;
  return std::clamp(i, 0, cells() - 1);
}

Axis uniformAxis(double lo, double hi, int n) {
  if (n < 1 || !(hi > lo)) throw std::invalid_argument("uniformAxis needs n >= 1 and hi > lo");
  std::vector<double> f(static_cast<std::size_t>(n) + 1);
  for (int i = 0; i <= n; ++i) f[static_cast<std::size_t>(i)] = lo + (hi - lo) * i / n;
  f.back() = hi;
  return Axis(std::move(f));
}

namespace {

/// Widths of a geometric progression starting after a cell of size h, growing by
/// `ratio` up to h_max, covering `span` exactly (the progression is rescaled).
std::vector<double> stretchedWidths(double span, double h, double ratio, double h_max) {
  std::vector<double> w;
  if (span <= 1e-12 * h) return w;
  double sum = 0, cur = h;
  while (sum < span) {
    cur = std::min(cur * ratio, h_max);
    w.push_back(cur);
    sum += cur;
  }
  // Drop or keep the last cell, whichever leaves the smaller rescaling.
  if (w.size() > 1 && sum - span > 0.5 * w.back()) {
    sum -= w.back();
    w.pop_back();
  }
  for (double& x : w) x *= span / sum;
  return w;
}

}  // namespace

Axis refinedAxis(double lo, double hi, double a, double b, double h_fine, double ratio, double h_max, double anchor) {
  if (!(lo <= a && a < b && b <= hi) || !(h_fine > 0) || h_max < h_fine || ratio < 1)
    throw std::invalid_argument("refinedAxis needs lo <= a < b <= hi, 0 < h_fine <= h_max, ratio >= 1");
  if (!std::isnan(anchor)) {
    if (!(a <= anchor && anchor <= b)) throw std::invalid_argument("refinedAxis: the anchor must lie in the refined box [a, b]");
    // Whole cells of h_fine counted from the anchor; a remainder thinner than h_fine / 2 at an
    // end of the axis joins the next cell (no slivers next to a boundary).
    const auto cellsTo = [&](double span, double room) {
      int k = static_cast<int>(std::lround(span / h_fine));
      if (k * h_fine > room + 1e-9 * h_fine) --k;
      const double rest = room - k * h_fine;
      if (rest > 1e-9 * h_fine && rest < 0.5 * h_fine && k > 0) --k;
      return std::max(k, 0);
    };
    const int n_lo = cellsTo(anchor - a, anchor - lo), n_hi = cellsTo(b - anchor, hi - anchor);
    if (n_lo + n_hi < 1) throw std::invalid_argument("refinedAxis: no whole cell fits around the anchor");
    a = anchor - n_lo * h_fine;
    b = anchor + n_hi * h_fine;
    if (a - lo < 1e-9 * h_fine) a = lo;
    if (hi - b < 1e-9 * h_fine) b = hi;
  }
  const int n_fine = std::max(1, static_cast<int>(std::lround((b - a) / h_fine)));
  const double h = (b - a) / n_fine;
  std::vector<double> f;
  const auto left = stretchedWidths(a - lo, h, ratio, h_max);
  double x = a;
  std::vector<double> lf;
  for (double w : left) {
    x -= w;
    lf.push_back(x);
  }
  for (auto it = lf.rbegin(); it != lf.rend(); ++it) f.push_back(*it);
  if (!f.empty()) f.front() = lo;
  for (int i = 0; i <= n_fine; ++i) f.push_back(a + h * i);
  f.back() = b;
  x = b;
  for (double w : stretchedWidths(hi - b, h, ratio, h_max)) {
    x += w;
    f.push_back(x);
  }
  f.back() = std::max(f.back(), hi);
  f.back() = hi;
  return Axis(std::move(f));
}

namespace {

/// The graded layer at the end f[0] of the faces f (ordered inwards from that end): widths
/// h_end * ratio^k until the next width would reach the original width there, then snapped to
/// the nearest original face (its index in f returned in `keep`). An empty layer: keep = 0 if
/// the end's cell is already no wider than h_end, keep = f.size() if the layer would swallow
/// the faces before reaching their widths.
std::vector<double> gradedLayer(const std::vector<double>& f, double h_end, double ratio, std::size_t& keep) {
  // f: faces ordered from the end being graded inwards (|f[k] - f[0]| increasing).
  std::vector<double> widths;
  double pos = 0, w = h_end;
  std::size_t k = 0;  // original cell holding pos
  while (k + 1 < f.size()) {
    const double orig = std::abs(f[k + 1] - f[k]);
    if (w >= orig) break;
    widths.push_back(w);
    pos += w;
    w *= ratio;
    while (k + 1 < f.size() && std::abs(f[k + 1] - f[0]) <= pos) ++k;
  }
  keep = 0;
  if (widths.empty()) return {};
  // Snap: end the layer on the original face nearest to pos (the graded cells are rescaled by
  // at most half an original cell over the layer).
  std::size_t m = 1;
  while (m + 1 < f.size() && std::abs(f[m] - f[0]) < pos) ++m;
  if (m > 1 && pos - std::abs(f[m - 1] - f[0]) < std::abs(f[m] - f[0]) - pos) --m;
  if (m + 1 >= f.size()) {
    keep = f.size();  // the layer would swallow the axis
    return {};
  }
  const double target = std::abs(f[m] - f[0]);
  keep = m;
  std::vector<double> out;
  double acc = 0;
  for (double x : widths) {
    acc += x * target / pos;
    out.push_back(acc);
  }
  out.back() = target;
  return out;  // distances from the end of the graded faces (excluding the end itself)
}

}  // namespace

Axis wallGradedAxis(const Axis& axis, double h_end, double ratio) {
  if (!(h_end > 0) || !(ratio > 1)) throw std::invalid_argument("wallGradedAxis needs h_end > 0 and ratio > 1");
  const std::vector<double>& f = axis.faces();
  std::size_t keep_lo = 0, keep_hi = 0;
  const std::vector<double> lo = gradedLayer(f, h_end, ratio, keep_lo);
  const std::vector<double> rf(f.rbegin(), f.rend());
  const std::vector<double> hi = gradedLayer(rf, h_end, ratio, keep_hi);
  // A layer that would swallow the axis is left out.
  if (keep_lo == f.size()) keep_lo = 0;
  if (keep_hi == f.size()) keep_hi = 0;
  if (keep_lo + keep_hi + 1 >= f.size()) return axis;  // the layers would meet: leave the axis
  std::vector<double> out{f.front()};
  for (double d : lo) out.push_back(f.front() + d);
  for (std::size_t i = keep_lo + 1; i + keep_hi + 1 < f.size(); ++i) out.push_back(f[i]);
  for (auto it = hi.rbegin(); it != hi.rend(); ++it) out.push_back(f.back() - *it);
  out.push_back(f.back());
  return Axis(std::move(out));
}

Axis innerRefinedAxis(const Axis& axis, double a, double b, int m, double ratio) {
  if (m < 1 || !(ratio > 1) || !(a < b)) throw std::invalid_argument("innerRefinedAxis needs m >= 1, ratio > 1 and a < b");
  if (m == 1) return axis;
  const std::vector<double>& f = axis.faces();
  // The box snapped to the nearest faces of the axis: every original face is kept, so faces
  // through a body's centre (refinedAxis's anchor) stay where they are.
  const auto nearest = [&](double x) {
    const auto i = static_cast<std::size_t>(axis.cellOf(x));
    return std::abs(f[i + 1] - x) < std::abs(f[i] - x) ? i + 1 : i;
  };
  std::size_t ia = nearest(a), ib = nearest(b);
  if (ia >= ib) throw std::invalid_argument("innerRefinedAxis: the box holds no whole cell of the axis");
  // Graded layers outside the box, from the fine width at its edges back to the axis's cells. A
  // layer that cannot reach them before the end of the axis (a wall too close, or cells growing
  // as fast as the layer) is left out and the box extended to that end instead.
  std::size_t keep_lo = 0, keep_hi = 0;
  std::vector<double> lo, hi;
  const auto layers = [&] {
    const std::vector<double> lf(f.rend() - static_cast<std::ptrdiff_t>(ia) - 1, f.rend());  // f[ia], f[ia-1], ..., f[0]
    const std::vector<double> rf(f.begin() + static_cast<std::ptrdiff_t>(ib), f.end());       // f[ib], ..., f.back()
    lo = gradedLayer(lf, axis.width(static_cast<int>(ia)) / m * ratio, ratio, keep_lo);
    hi = gradedLayer(rf, axis.width(static_cast<int>(ib) - 1) / m * ratio, ratio, keep_hi);
    return std::pair{keep_lo == lf.size(), keep_hi == rf.size()};
  };
  const auto [swallow_lo, swallow_hi] = layers();
  if (swallow_lo) ia = 0;
  if (swallow_hi) ib = f.size() - 1;
  if (swallow_lo || swallow_hi) layers();
  std::vector<double> out(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(ia - keep_lo));
  for (auto it = lo.rbegin(); it != lo.rend(); ++it) out.push_back(f[ia] - *it);
  if (!lo.empty()) out[ia - keep_lo] = f[ia - keep_lo];
  for (std::size_t i = ia; i < ib; ++i)
    for (int k = 0; k < m; ++k) out.push_back(f[i] + (f[i + 1] - f[i]) * k / m);
  out.push_back(f[ib]);
  for (double e : hi) out.push_back(f[ib] + e);
  if (!hi.empty()) out.back() = f[ib + keep_hi];
  out.insert(out.end(), f.begin() + static_cast<std::ptrdiff_t>(ib + keep_hi) + 1, f.end());
  return Axis(std::move(out));
}

}  // namespace mmval::simulate
