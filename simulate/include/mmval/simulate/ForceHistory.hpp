// Force-coefficient history of an unsteady run and its periodic statistics
// (vortex shedding): frequency from the upward zero crossings of c_L about
// its mean, extrema over whole periods refined by a parabola through the
// three samples around each extreme (the benchmark's c_D max / c_L max).
#pragma once
#include <filesystem>
#include <vector>

namespace mmval::simulate {

struct SheddingStats {
  int periods = 0;           ///< whole c_L periods in the window (0: no shedding detected)
  double frequency_hz = 0;   ///< 1 / mean period
  double window_start_s = 0, window_end_s = 0;
  double cd_max = 0, cd_min = 0, cd_mean = 0;
  double cl_max = 0, cl_min = 0, cl_mean = 0, cl_amplitude = 0;  ///< amplitude: (max - min) / 2
  /// Growth of the c_L amplitude over the window's last period: (A_last - A_prev) / A_last with A the
  /// half peak-to-peak of c_L in a period (0 with fewer than 2 periods). Near 0 once the shedding is
  /// periodic; a start-up that has not saturated shows as a positive drift.
  double cl_amplitude_drift = 0;
};

class ForceHistory {
 public:
  void add(double t_s, double cd, double cl);
  std::size_t size() const { return m_t.size(); }
  const std::vector<double>& times() const { return m_t; }
  const std::vector<double>& drag() const { return m_cd; }
  const std::vector<double>& lift() const { return m_cl; }
  /// Statistics over the last `max_periods` whole c_L periods after `from_s`;
  /// if fewer than one period is found, over all samples after from_s (periods = 0).
  SheddingStats analyse(double from_s, int max_periods = 4) const;
  /// CSV with header t_s,c_D,c_L. Throws std::runtime_error on I/O failure.
  void writeCsv(const std::filesystem::path& file) const;

 private:
  std::vector<double> m_t, m_cd, m_cl;
};

}  // namespace mmval::simulate
