// The files of a Brownian analysis (writeTrackOutputs, Pipeline.hpp, in Brownian mode):
//   tracks.csv               the shared schema; state mobile / immobile / short (Brownian.hpp's test)
//   track_diffusion.csv      particle, points, steps, D_um2_per_s, D_se_um2_per_s, sigma2_um2, z_zero, z_free, state
//   dispersion.csv           frame, t_s, count, mean_x_um, mean_y_um, sigma_x_um, sigma_y_um, drift_x_um, drift_y_um
//                            (count, means and sigmas over the drift-corrected mobile tracks)
//   msd.csv                  MsdTable.hpp's schema (drift-corrected, mobile tracks of at least
//                            analysis.brownian_min_points; fit: 4 D t + offset, over every lag)
//   van_hove.csv             lag_s, dx_um, density_per_um, gaussian_per_um (x and y pooled)
//   diffusion_histogram.csv  D_low_um2_per_s, D_high_um2_per_s, tracks (per-track CVE D of mobile tracks)
//   diffusion_histogram.png  the same as bars, the ensemble D marked
#pragma once
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "mmval/tracking/Pipeline.hpp"

namespace mmval::tracking::detail {

struct OutputSink {
  std::filesystem::path dir;
  std::function<void(const std::string&, const std::string&)> text;  ///< name, contents (atomic, recorded)
  std::function<void(const std::string&, const cv::Mat&)> png;       ///< name, picture (atomic, recorded)
  std::vector<std::string>* files = nullptr;                         ///< records a file written otherwise
};

/// Writes the files above and returns the summary.json entries of the analysis: a
/// "brownian" block (D, D_se, alpha, alpha_se, sigma_loc, lags, drift, tracks, CVE),
/// the msd_* keys from it, and why the flow outputs are missing.
nlohmann::json writeBrownianOutputs(const TrackRun& run, const TrackConfig& config, const OutputSink& out);

/// Bars of the per-track D (um^2/s) in `edges` bins, with a vertical line at `ensemble_d`.
cv::Mat diffusionHistogram(const std::vector<double>& edges, const std::vector<long long>& counts, double ensemble_d);

}  // namespace mmval::tracking::detail
