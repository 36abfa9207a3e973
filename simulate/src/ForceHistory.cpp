#include "mmval/simulate/ForceHistory.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <stdexcept>
#include <tuple>
#include <utility>

#include <fmt/format.h>

namespace mmval::simulate {

namespace {

/// Extreme of the parabola through (t[k-1..k+1], y[k-1..k+1]); y[k] if degenerate.
double parabolicPeak(const std::vector<double>& t, const std::vector<double>& y, std::size_t k) {
  if (k == 0 || k + 1 >= y.size()) return y[k];
  const double x0 = t[k - 1] - t[k], x2 = t[k + 1] - t[k];
  const double y0 = y[k - 1] - y[k], y2 = y[k + 1] - y[k];
  // y = a x^2 + b x through (0, 0), (x0, y0), (x2, y2).
  const double det = x0 * x2 * (x0 - x2);
  if (det == 0) return y[k];
  const double a = (y0 * x2 - y2 * x0) / det, b = (y2 * x0 * x0 - y0 * x2 * x2) / det;
  if (a == 0) return y[k];
  const double xs = -b / (2 * a);
  if (xs < std::min(x0, x2) || xs > std::max(x0, x2)) return y[k];
  return y[k] - b * b / (4 * a);
}

}  // namespace

void ForceHistory::add(double t_s, double cd, double cl) {
  m_t.push_back(t_s);
  m_cd.push_back(cd);
  m_cl.push_back(cl);
}

SheddingStats ForceHistory::analyse(double from_s, int max_periods) const {
  SheddingStats s;
  const std::size_t first = static_cast<std::size_t>(std::lower_bound(m_t.begin(), m_t.end(), from_s) - m_t.begin());
  if (first >= m_t.size()) return s;
  double mean = 0;
  for (std::size_t k = first; k < m_t.size(); ++k) mean += m_cl[k];
  mean /= static_cast<double>(m_t.size() - first);
  std::vector<double> up;  // upward crossings of c_L - mean
  for (std::size_t k = first + 1; k < m_t.size(); ++k)
    if (m_cl[k - 1] < mean && m_cl[k] >= mean) up.push_back(m_t[k - 1] + (mean - m_cl[k - 1]) / (m_cl[k] - m_cl[k - 1]) * (m_t[k] - m_t[k - 1]));
  // Samples with t0 <= t <= t1: [begin, end) indices.
  const auto samples = [&](double t0, double t1) {
    return std::pair{static_cast<std::size_t>(std::lower_bound(m_t.begin(), m_t.end(), t0) - m_t.begin()),
                     static_cast<std::size_t>(std::upper_bound(m_t.begin(), m_t.end(), t1) - m_t.begin())};
  };
  std::size_t lo = first, hi = m_t.size();
  if (up.size() >= 2) {
    s.periods = std::min(static_cast<int>(up.size()) - 1, std::max(1, max_periods));
    s.window_start_s = up[up.size() - 1 - static_cast<std::size_t>(s.periods)];
    s.window_end_s = up.back();
    s.frequency_hz = s.periods / (s.window_end_s - s.window_start_s);
    std::tie(lo, hi) = samples(s.window_start_s, s.window_end_s);
  } else {
    s.window_start_s = m_t[first];
    s.window_end_s = m_t.back();
  }
  std::size_t kd = lo, kdm = lo, kl = lo, klm = lo;
  double sd = 0, sl = 0, st = 0;
  for (std::size_t k = lo; k < hi; ++k) {
    if (m_cd[k] > m_cd[kd]) kd = k;
    if (m_cd[k] < m_cd[kdm]) kdm = k;
    if (m_cl[k] > m_cl[kl]) kl = k;
    if (m_cl[k] < m_cl[klm]) klm = k;
    if (k > lo) {  // trapezoidal time averages
      const double dt = m_t[k] - m_t[k - 1];
      sd += 0.5 * (m_cd[k] + m_cd[k - 1]) * dt;
      sl += 0.5 * (m_cl[k] + m_cl[k - 1]) * dt;
      st += dt;
    }
  }
  s.cd_max = parabolicPeak(m_t, m_cd, kd);
  s.cl_max = parabolicPeak(m_t, m_cl, kl);
  std::vector<double> neg_cd(m_cd.size()), neg_cl(m_cl.size());
  std::transform(m_cd.begin(), m_cd.end(), neg_cd.begin(), [](double v) { return -v; });
  std::transform(m_cl.begin(), m_cl.end(), neg_cl.begin(), [](double v) { return -v; });
  s.cd_min = -parabolicPeak(m_t, neg_cd, kdm);
  s.cl_min = -parabolicPeak(m_t, neg_cl, klm);
  s.cd_mean = st > 0 ? sd / st : m_cd[lo];
  s.cl_mean = st > 0 ? sl / st : m_cl[lo];
  s.cl_amplitude = 0.5 * (s.cl_max - s.cl_min);
  if (s.periods >= 2) {
    const auto amplitude = [&](double t0, double t1) {
      const auto [a, b] = samples(t0, t1);
      if (a >= b) return 0.0;
      const auto [mn, mx] = std::minmax_element(m_cl.begin() + static_cast<std::ptrdiff_t>(a), m_cl.begin() + static_cast<std::ptrdiff_t>(b));
      return 0.5 * (*mx - *mn);
    };
    const std::size_t n = up.size();
    const double last = amplitude(up[n - 2], up[n - 1]), prev = amplitude(up[n - 3], up[n - 2]);
    s.cl_amplitude_drift = last > 0 ? (last - prev) / last : 0.0;
  }
  return s;
}

void ForceHistory::writeCsv(const std::filesystem::path& file) const {
  const std::filesystem::path tmp = file.string() + ".tmp";
  {
    std::ofstream f(tmp);
    if (!f) throw std::runtime_error("cannot write " + tmp.string());
    f << "t_s,c_D,c_L\n";
    for (std::size_t k = 0; k < m_t.size(); ++k) f << fmt::format("{:.9g},{:.9g},{:.9g}\n", m_t[k], m_cd[k], m_cl[k]);
    if (!f) throw std::runtime_error("cannot write " + tmp.string());
  }
  std::filesystem::rename(tmp, file);
}

}  // namespace mmval::simulate
