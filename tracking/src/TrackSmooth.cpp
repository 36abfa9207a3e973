#include "mmval/tracking/TrackSmooth.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <vector>

namespace mmval::tracking {
namespace {

/// Value at s = 0 of the least-squares quadratic through (s_k, v_k); the normal
/// equations are solved by Cramer's rule on centred abscissae (|s| <= a few frames,
/// so the 3 x 3 system is well conditioned).
bool quadraticAtZero(const std::vector<double>& s, const std::vector<double>& vx, const std::vector<double>& vy, double& x0, double& y0) {
  std::array<double, 5> m{};  // sums of s^0..s^4
  std::array<double, 3> bx{}, by{};
  for (std::size_t k = 0; k < s.size(); ++k) {
    double p = 1;
    for (int e = 0; e < 5; ++e) {
      m[e] += p;
      if (e < 3) {
        bx[e] += p * vx[k];
        by[e] += p * vy[k];
      }
      p *= s[k];
    }
  }
  // | m0 m1 m2 |
  // | m1 m2 m3 |  c = b; we need c0 only.
  // | m2 m3 m4 |
  const double det = m[0] * (m[2] * m[4] - m[3] * m[3]) - m[1] * (m[1] * m[4] - m[3] * m[2]) + m[2] * (m[1] * m[3] - m[2] * m[2]);
  if (!(std::abs(det) > 1e-9)) return false;
  auto c0 = [&](const std::array<double, 3>& b) {
    return (b[0] * (m[2] * m[4] - m[3] * m[3]) - m[1] * (b[1] * m[4] - m[3] * b[2]) + m[2] * (b[1] * m[3] - m[2] * b[2])) / det;
  };
  x0 = c0(bx);
  y0 = c0(by);
  return true;
}

}  // namespace

SmoothStats smoothTracks(Tracks& tracks, int half_window, double pixel_size) {
  SmoothStats st;
  if (half_window <= 0) return st;
  auto& pts = tracks.points;
  const std::size_t want = 2 * static_cast<std::size_t>(half_window) + 1;
  std::vector<double> s, vx, vy, out_x, out_y;
  std::size_t i = 0;
  while (i < pts.size()) {
    // A stretch: consecutive moving points of one track (a "deposited" point ends it).
    if (pts[i].state == "deposited") {
      ++i;
      continue;
    }
    std::size_t j = i + 1;
    while (j < pts.size() && pts[j].particle == pts[i].particle && pts[j].state != "deposited") ++j;
    const std::size_t n = j - i;
    if (n < 4) {
      st.skipped += static_cast<long long>(n);
      i = j;
      continue;
    }
    out_x.assign(n, 0);
    out_y.assign(n, 0);
    for (std::size_t a = 0; a < n; ++a) {
      // The `want` points nearest in frame: grow a window [lo, hi) around a.
      std::size_t lo = a, hi = a + 1;
      while (hi - lo < std::min(want, n)) {
        const bool can_lo = lo > 0, can_hi = hi < n;
        const auto f = pts[i + a].frame;
        if (can_lo && (!can_hi || f - pts[i + lo - 1].frame <= pts[i + hi].frame - f))
          --lo;
        else
          ++hi;
      }
      s.clear();
      vx.clear();
      vy.clear();
      for (std::size_t b = lo; b < hi; ++b) {
        s.push_back(static_cast<double>(pts[i + b].frame - pts[i + a].frame));
        vx.push_back(pts[i + b].x_px - pts[i + a].x_px);
        vy.push_back(pts[i + b].y_px - pts[i + a].y_px);
      }
      double dx = 0, dy = 0;
      if (!quadraticAtZero(s, vx, vy, dx, dy)) dx = dy = 0;
      out_x[a] = pts[i + a].x_px + dx;
      out_y[a] = pts[i + a].y_px + dy;
    }
    for (std::size_t a = 0; a < n; ++a) {
      TrackPoint& p = pts[i + a];
      p.x_px = out_x[a];
      p.y_px = out_y[a];
      p.x = p.x_px * pixel_size;
      p.y = p.y_px * pixel_size;
    }
    st.points += static_cast<long long>(n);
    i = j;
  }
  return st;
}

}  // namespace mmval::tracking
