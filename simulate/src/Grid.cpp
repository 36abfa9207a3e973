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

Axis refinedAxis(double lo, double hi, double a, double b, double h_fine, double ratio, double h_max) {
  if (!(lo <= a && a < b && b <= hi) || !(h_fine > 0) || h_max < h_fine || ratio < 1)
    throw std::invalid_argument("refinedAxis needs lo <= a < b <= hi, 0 < h_fine <= h_max, ratio >= 1");
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

}  // namespace mmval::simulate
