#include "BrownianOutputs.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "MsdTable.hpp"
#include "mmval/core/JsonNumbers.hpp"
#include "mmval/tracking/Statistics.hpp"

namespace mmval::tracking::detail {

namespace {

constexpr double kUm = 1e6, kUm2 = 1e12;

using detail::csvNumber;

/// Bin edges over the per-track D values: from min(0, 1st percentile) to the 99th
/// percentile, 30 bins (a few tracks of wild D from linking errors do not set the scale).
std::vector<double> histogramEdges(std::vector<double> d) {
  std::sort(d.begin(), d.end());
  const auto q = [&](double f) { return d[std::min(d.size() - 1, static_cast<std::size_t>(f * static_cast<double>(d.size())))]; };
  double lo = std::min(0.0, q(0.01)), hi = q(0.99);
  if (!(hi > lo)) hi = lo + (std::abs(lo) > 0 ? std::abs(lo) : 1.0);
  std::vector<double> edges;
  const int bins = 30;
  for (int k = 0; k <= bins; ++k) edges.push_back(lo + (hi - lo) * k / bins);
  return edges;
}

}  // namespace

cv::Mat diffusionHistogram(const std::vector<double>& edges, const std::vector<long long>& counts, double ensemble_d) {
  const int w = 640, h = 400, left = 60, right = 20, top = 30, bottom = 50;
  cv::Mat img(h, w, CV_8UC3, cv::Scalar(255, 255, 255));
  if (edges.size() < 2 || counts.empty()) return img;
  const long long peak = std::max<long long>(1, *std::max_element(counts.begin(), counts.end()));
  const double x0 = edges.front(), x1 = edges.back();
  const auto px = [&](double d) { return left + static_cast<int>(std::lround((d - x0) / (x1 - x0) * (w - left - right))); };
  const auto py = [&](double n) { return h - bottom - static_cast<int>(std::lround(n / static_cast<double>(peak) * (h - top - bottom))); };
  for (std::size_t k = 0; k < counts.size(); ++k)
    if (counts[k] > 0) cv::rectangle(img, {px(edges[k]) + 1, py(static_cast<double>(counts[k]))}, {px(edges[k + 1]) - 1, h - bottom}, cv::Scalar(180, 120, 60), cv::FILLED);
  const cv::Scalar black(0, 0, 0);
  cv::line(img, {left, h - bottom}, {w - right, h - bottom}, black);
  cv::line(img, {left, top}, {left, h - bottom}, black);
  const double fs = 0.4;
  for (int k = 0; k <= 4; ++k) {
    const double d = x0 + (x1 - x0) * k / 4;
    cv::line(img, {px(d), h - bottom}, {px(d), h - bottom + 4}, black);
    cv::putText(img, fmt::format("{:.3g}", d), {px(d) - 14, h - bottom + 18}, cv::FONT_HERSHEY_SIMPLEX, fs, black, 1, cv::LINE_AA);
  }
  cv::putText(img, fmt::format("{}", peak), {8, top + 4}, cv::FONT_HERSHEY_SIMPLEX, fs, black, 1, cv::LINE_AA);
  cv::putText(img, "0", {left - 14, h - bottom + 4}, cv::FONT_HERSHEY_SIMPLEX, fs, black, 1, cv::LINE_AA);
  cv::putText(img, "tracks", {8, top - 12}, cv::FONT_HERSHEY_SIMPLEX, fs, black, 1, cv::LINE_AA);
  cv::putText(img, "per-track D (covariance-based estimator), um^2/s", {left + 90, h - 12}, cv::FONT_HERSHEY_SIMPLEX, fs, black, 1, cv::LINE_AA);
  if (std::isfinite(ensemble_d) && ensemble_d >= x0 && ensemble_d <= x1) {
    cv::line(img, {px(ensemble_d), top}, {px(ensemble_d), h - bottom}, cv::Scalar(40, 40, 220), 2, cv::LINE_AA);
    cv::putText(img, fmt::format("ensemble MSD fit: {:.3g}", ensemble_d), {px(ensemble_d) + 5, top + 12}, cv::FONT_HERSHEY_SIMPLEX, fs,
                cv::Scalar(40, 40, 220), 1, cv::LINE_AA);
  }
  return img;
}

nlohmann::json writeBrownianOutputs(const TrackRun& run, const TrackConfig& c, const OutputSink& out) {
  std::optional<BrownianStats> own;  // runTracker's, unless the run was put together otherwise
  if (!run.brownian) own = analyseBrownian(run.tracks, c.analysis.brownian);
  const BrownianStats& b = run.brownian ? *run.brownian : *own;
  std::map<std::int64_t, const TrackDiffusion*> by_id;
  for (const auto& t : b.tracks) by_id[t.particle] = &t;
  {
    Tracks labelled = run.tracks;
    for (auto& p : labelled.points) p.state = by_id.count(p.particle) ? by_id[p.particle]->state : "short";
    writeTracksCsv(out.dir / "tracks.csv", labelled, c.pixel_size);
    out.files->push_back("tracks.csv");
  }
  std::string td = "particle,points,steps,D_um2_per_s,D_se_um2_per_s,sigma2_um2,z_zero,z_free,state\n";
  for (const auto& t : b.tracks)
    td += fmt::format("{},{},{},{},{},{},{},{},{}\n", t.particle, t.points, t.cve.steps, csvNumber(t.cve.d * kUm2), csvNumber(t.cve.d_se * kUm2),
                      csvNumber(t.cve.sigma2 * kUm2), csvNumber(t.test.z_zero, "{:.4g}"), csvNumber(t.test.z_free, "{:.4g}"), t.state);
  out.text("track_diffusion.csv", td);
  {
    // Per frame: the drift, and the spread of the drift-corrected mobile particles.
    const Tracks corrected = driftCorrected(run.tracks, b.drift);
    std::map<std::int64_t, std::pair<std::vector<double>, std::vector<double>>> at;
    for (const auto& p : corrected.points)
      if (by_id.count(p.particle) && by_id[p.particle]->state == "mobile") {
        at[p.frame].first.push_back(p.x);
        at[p.frame].second.push_back(p.y);
      }
    std::string disp = "frame,t_s,count,mean_x_um,mean_y_um,sigma_x_um,sigma_y_um,drift_x_um,drift_y_um\n";
    for (std::size_t k = 0; k < b.drift.frame.size(); ++k) {
      const auto it = at.find(b.drift.frame[k]);
      const bool any = it != at.end() && !it->second.first.empty();
      disp += fmt::format("{},{:.6g},{},{},{},{},{},{:.5g},{:.5g}\n", b.drift.frame[k], b.drift.t[k], any ? it->second.first.size() : 0,
                          any ? csvNumber(mean(it->second.first) * kUm, "{:.5g}") : "", any ? csvNumber(mean(it->second.second) * kUm, "{:.5g}") : "",
                          any ? csvNumber(populationStd(it->second.first) * kUm, "{:.5g}") : "",
                          any ? csvNumber(populationStd(it->second.second) * kUm, "{:.5g}") : "", b.drift.x[k] * kUm, b.drift.y[k] * kUm);
    }
    out.text("dispersion.csv", disp);
  }
  const MsdFit& f = b.msd;
  std::vector<MsdRow> msd;
  for (std::size_t i = 0; i < f.lag.size(); ++i) msd.push_back({f.lag[i], f.msd[i], f.samples[i], f.msd_se[i], f.fitAt(f.lag[i])});
  out.text("msd.csv", msdTable(msd));
  std::string vh = "lag_s,dx_um,density_per_um,gaussian_per_um\n";
  for (const auto& v : b.van_hove)
    for (std::size_t i = 0; i < v.centre.size(); ++i)
      vh += fmt::format("{:.6g},{:.5g},{:.5g},{}\n", v.lag, v.centre[i] * kUm, v.density[i] / kUm, csvNumber(v.gaussian[i] / kUm, "{:.5g}"));
  out.text("van_hove.csv", vh);
  std::vector<double> ds;
  for (const auto& t : b.tracks)
    if (t.state == "mobile") ds.push_back(t.cve.d * kUm2);
  {
    std::vector<double> edges;
    std::vector<long long> counts;
    if (!ds.empty()) {
      edges = histogramEdges(ds);
      counts.assign(edges.size() - 1, 0);
      const double w = edges[1] - edges[0];
      for (double d : ds) {
        const auto k = static_cast<long long>(std::floor((d - edges.front()) / w));
        if (k >= 0 && k < static_cast<long long>(counts.size())) ++counts[static_cast<std::size_t>(k)];
      }
    }
    std::string h = "D_low_um2_per_s,D_high_um2_per_s,tracks\n";
    for (std::size_t k = 0; k < counts.size(); ++k) h += fmt::format("{:.5g},{:.5g},{}\n", edges[k], edges[k + 1], counts[k]);
    out.text("diffusion_histogram.csv", h);
    out.png("diffusion_histogram.png", diffusionHistogram(edges, counts, f.d * kUm2));
  }
  nlohmann::json j;
  const double t0 = b.drift.t.empty() ? 0.0 : b.drift.t.front(), t1 = b.drift.t.empty() ? 0.0 : b.drift.t.back();
  const double net_x = b.drift.x.empty() ? 0.0 : b.drift.x.back(), net_y = b.drift.y.empty() ? 0.0 : b.drift.y.back();
  j["brownian"] = {
      {"D_um2_per_s", finiteOrNull(f.d * kUm2)},
      {"D_se_um2_per_s", finiteOrNull(f.d_se * kUm2)},
      {"A_um2_per_s", finiteOrNull(4 * f.d * kUm2)},
      {"alpha", finiteOrNull(f.alpha)},
      {"alpha_se", finiteOrNull(f.alpha_se)},
      {"sigma_loc_um", finiteOrNull(std::sqrt(std::max(0.0, f.sigma2)) * kUm)},
      {"sigma2_loc_um2", finiteOrNull(f.sigma2 * kUm2)},
      {"sigma2_loc_se_um2", finiteOrNull(f.sigma2_se * kUm2)},
      {"msd_offset_um2", finiteOrNull(f.offset * kUm2)},
      {"reduced_localisation_error", finiteOrNull(f.reduced_error)},
      {"lags_D", f.lags_d},
      {"lags_alpha", f.lags_alpha},
      {"frame_interval_s", finiteOrNull(b.frame_interval)},
      {"exposure_s", c.analysis.brownian.exposure},
      {"n_tracks", f.tracks},
      {"min_points", c.analysis.brownian.min_points},
      {"tracks", {{"mobile", b.mobile}, {"immobile", b.immobile}, {"short", b.short_tracks}}},
      {"drift", {{"net_x_um", net_x * kUm}, {"net_y_um", net_y * kUm}, {"mean_speed_um_per_s", t1 > t0 ? std::hypot(net_x, net_y) / (t1 - t0) * kUm : 0.0}}},
      {"cve",
       {{"n_tracks", ds.size()}, {"mean_um2_per_s", finiteOrNull(b.cve_mean * kUm2)}, {"mean_se_um2_per_s", finiteOrNull(b.cve_mean_se * kUm2)},
        {"median_um2_per_s", finiteOrNull(b.cve_median * kUm2)}}},
      {"model", "MSD = 4 D t + 4 sigma^2 - (4/3) D t_E (Michalet 2010); per-track D by the covariance-based estimator (Vestergaard et al. 2014)"},
      {"immobile_test", fmt::format("CVE D below the ensemble D and not above 0, one-sided at level {:g} each", c.analysis.brownian.immobile_level)}};
  j["msd_exponent"] = finiteOrNull(f.alpha);
  j["msd_D_linear_um2_per_s"] = finiteOrNull(f.d * kUm2);
  j["msd_D_power_um2_per_s"] = finiteOrNull(f.k_alpha * kUm2);
  j["immobile"] = b.immobile;
  j["flow_outputs"] =
      "not written for Brownian motion: velocities, speed over time, retention, deposits and the speed maps describe particles carried by a "
      "flow (analysis.motion = \"flow\" writes them)";
  return j;
}

}  // namespace mmval::tracking::detail
