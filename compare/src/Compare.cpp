#include "mmval/compare/Compare.hpp"

#include <algorithm>
#include <cmath>
#include <map>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/compare/TrackChecks.hpp"
#include "mmval/tracking/Statistics.hpp"
#include "mmval/core/AtomicFile.hpp"

namespace mmval::compare {

using namespace mmval::tracking;

namespace {

MetricResult against(const std::string& name, double sim, double exp, const std::string& unit, Tolerance tol,
                     const std::string& reason, const std::string& source) {
  Acceptance a;
  a.metric = name;
  a.reference.value = exp * parseUnit(unit).to_si;
  a.reference.unit = unit;
  a.reference.dim = parseUnit(unit).dim;
  a.reference.source = source;
  a.tolerance = tol;
  a.reason = reason;
  return evaluateMetric(a, sim * parseUnit(unit).to_si);
}

MetricResult info(const std::string& name, double value, const std::string& unit, const std::string& reason) {
  MetricResult m;
  m.name = name;
  m.value = value;
  m.unit = unit;
  m.reason = reason;
  return m;
}

Tolerance relative(double f) { return {Tolerance::Kind::relative, f, fmt::format("{:g} %", 100 * f)}; }

/// Whether the window [b, e] of one track is at rest (RestRule, labelRests: the tracker's own
/// window test, tracking::restWindow); marks its resting points in `rest` (indexed from `i`, the
/// track's first point): all of them when every point is within the distance of the last, else
/// those within the noisy test's radius of the window's median.
void markRestingWindow(const std::vector<TrackPoint>& pts, std::size_t i, std::size_t b, std::size_t e, double distance, std::vector<char>& rest) {
  const tracking::RestWindow w = tracking::restWindow(pts, b, e + 1, distance);
  if (!w.at_rest) return;
  for (std::size_t k = b; k <= e; ++k)
    if (w.exact || std::hypot(pts[k].x - w.centre_x, pts[k].y - w.centre_y) <= w.radius) rest[k - i] = 1;
}

}  // namespace

RestCount labelRests(Tracks& tracks, const RestRule& rule) {
  RestCount count;
  auto& pts = tracks.points;
  count.points = pts.size();
  for (const auto& p : pts) count.labelled_in_file += p.state == "deposited" ? 1 : 0;
  if (rule.window <= 0) {
    count.at_rest = count.labelled_in_file;
    return count;
  }
  const double eps = 1e-9 * std::max(1.0, rule.window);
  for (std::size_t i = 0; i < pts.size();) {
    std::size_t j = i;
    while (j < pts.size() && pts[j].particle == pts[i].particle) ++j;
    std::vector<char> rest(j - i, 0);
    std::size_t b = i;
    for (std::size_t e = i; e < j; ++e) {
      if (pts[e].t - pts[i].t < rule.window - eps) continue;
      while (pts[b].t < pts[e].t - rule.window - eps) ++b;
      if (e > b) markRestingWindow(pts, i, b, e, rule.distance, rest);
    }
    for (std::size_t k = i; k < j; ++k) {
      if (rest[k - i]) {
        pts[k].state = "deposited";
        ++count.at_rest;
      } else if (pts[k].state == "deposited") {
        pts[k].state = "mobile";
      }
    }
    i = j;
  }
  return count;
}

RetentionSeries retentionOverTime(const RetentionCount& count, const std::vector<double>& times) {
  // The same count as the final fraction: chains retained by t (at rest from their stop
  // time on) over chains entered by t. A retained chain stops after it entered, so no
  // point exceeds 1.
  RetentionSeries r;
  for (double t : times) {
    const auto n = std::count_if(count.entry_times.begin(), count.entry_times.end(), [&](double s) { return s <= t; });
    const auto k = std::count_if(count.stop_times.begin(), count.stop_times.end(), [&](double s) { return s <= t; });
    r.t.push_back(t);
    r.fraction.push_back(n > 0 ? double(k) / double(n) : std::nan(""));
  }
  return r;
}

Comparison compareTracks(const Tracks& experiment, const Tracks& simulation, const CompareOptions& o) {
  checkComparable(experiment, "experiment");
  checkComparable(simulation, "simulation");
  Comparison c;
  // One rest rule on both files for everything that depends on what moves (labelRests):
  // the files' own labels come from different rules (a tracker's stuck window, an engine's
  // attachments). Retention has its own one rule (countRetention) on the files as read.
  c.rest_rule = o.rest;
  Tracks exp_rest = experiment, sim_rest = simulation;
  c.rest_experiment = labelRests(exp_rest, o.rest);
  c.rest_simulation = labelRests(sim_rest, o.rest);
  c.experiment = analyseTracks(exp_rest, o.tracks);
  checkReferenceMoves(exp_rest, c.experiment, o.tracks);
  c.simulation = analyseTracks(sim_rest, o.tracks);
  std::vector<double> se, ss;
  for (const auto& s : c.experiment.steps) se.push_back(s.speed);
  for (const auto& s : c.simulation.steps) ss.push_back(s.speed);
  if (!se.empty() && !ss.empty()) {
    c.wasserstein = wasserstein1(se, ss);
    const KsResult ks = kolmogorovSmirnov(se, ss);
    c.ks_statistic = ks.statistic;
    c.ks_p_value = ks.p_value;
  }
  // One sample per moving track: its mean speed (TrackSummary::mean_speed).
  auto trackSpeeds = [](const TrackStats& st) {
    std::vector<double> v;
    for (const auto& t : st.tracks)
      if ((t.state == "mobile" || t.state == "deposited") && std::isfinite(t.mean_speed)) v.push_back(t.mean_speed);
    return v;
  };
  const std::vector<double> te = trackSpeeds(c.experiment), ts = trackSpeeds(c.simulation);
  c.track_samples_experiment = static_cast<int>(te.size());
  c.track_samples_simulation = static_cast<int>(ts.size());
  if (!te.empty() && !ts.empty()) {
    const KsResult ks = kolmogorovSmirnov(te, ts);
    c.track_ks_statistic = ks.statistic;
    c.track_ks_p_value = ks.p_value;
  }
  // Occupancy on the union bounding box.
  double x0 = 1e300, y0 = 1e300, x1 = -1e300, y1 = -1e300;
  for (const auto* t : {&experiment, &simulation})
    for (const auto& p : t->points) {
      x0 = std::min(x0, p.x);
      y0 = std::min(y0, p.y);
      x1 = std::max(x1, p.x);
      y1 = std::max(y1, p.y);
    }
  if (x1 > x0 && y1 > y0) {
    c.occupancy_experiment = occupancyMap(experiment, o.occupancy_cell, x0, y0, x1 + o.occupancy_cell, y1 + o.occupancy_cell);
    c.occupancy_simulation = occupancyMap(simulation, o.occupancy_cell, x0, y0, x1 + o.occupancy_cell, y1 + o.occupancy_cell);
    c.iou = intersectionOverUnion(c.occupancy_experiment, c.occupancy_simulation);
  }
  // Retention against time on a common grid.
  {
    const double t0 = std::min(c.experiment.t_begin, c.simulation.t_begin), t1 = std::max(c.experiment.t_end, c.simulation.t_end);
    std::vector<double> times;
    const int n = std::max(2, o.tracks.time_bins + 1);
    for (int i = 0; i < n; ++i) times.push_back(t0 + (t1 - t0) * i / (n - 1));
    RetentionOptions ro;
    ro.tracks = o.tracks;
    if (o.regions != nullptr) {
      // Both files are in the geometry window's frame: it is the view of both.
      const auto& f = o.regions->frame;
      ro.view = cv::Rect2d(0, 0, f.cols * f.pixel_size, f.rows * f.pixel_size);
    }
    c.retention_count_experiment = countRetention(experiment, ro);
    c.retention_count_simulation = countRetention(simulation, ro);
    c.retention_experiment = retentionOverTime(c.retention_count_experiment, times);
    c.retention_simulation = retentionOverTime(c.retention_count_simulation, times);
  }
  c.alignment = o.alignment;
  const auto& e = c.experiment;
  const auto& s = c.simulation;
  const std::string rests =
      o.rest.window > 0
          ? fmt::format("; steps at rest left out by one rule on both files (within {:g} um over {:g} s): {} of {} reference points "
                        "and {} of {} simulated points at rest",
                        o.rest.distance * 1e6, o.rest.window, c.rest_experiment.at_rest, c.rest_experiment.points, c.rest_simulation.at_rest,
                        c.rest_simulation.points)
          : std::string("; steps at rest left out where each file labels them deposited (rest rule off)");
  c.metrics.push_back(against("mean_speed", s.mean_speed * 1e6, e.mean_speed * 1e6, "um/s", relative(o.speed_tolerance),
                              "mean particle speed, paper Fig. 15" + rests, o.reference_name));
  c.metrics.push_back(against("median_speed", s.median_speed * 1e6, e.median_speed * 1e6, "um/s", relative(o.speed_tolerance),
                              "median particle speed, paper Fig. 15" + rests, o.reference_name));
  c.metrics.push_back(against("sigma_x", s.sigma_x * 1e6, e.sigma_x * 1e6, "um", relative(o.dispersion_tolerance),
                              "time-averaged dispersion along x, paper Eq. 18 / Fig. 16", o.reference_name));
  c.metrics.push_back(against("sigma_y", s.sigma_y * 1e6, e.sigma_y * 1e6, "um", relative(o.dispersion_tolerance),
                              "time-averaged dispersion along y, paper Eq. 18 / Fig. 16", o.reference_name));
  {
    // One rule on both files (Retention.hpp): the simulation's engine label is not used.
    const auto& re = c.retention_count_experiment;
    const auto& rs = c.retention_count_simulation;
    c.metrics.push_back(against("retention_fraction", rs.fraction, re.fraction, "1",
        {Tolerance::Kind::absolute, o.retention_tolerance, fmt::format("{:g}", o.retention_tolerance)},
        fmt::format("particles at rest at the end (drift over the final {:g} s below {:g} um/s plus 3 standard errors of the position noise) / "
                    "particles that entered, fragments of one particle's track chained, the same rule on both files: reference {} / {} "
                    "({} tracks chained as continuations, {} chains neither entering nor continuing left out), simulation {} / {} ({}, {}); "
                    "paper: 42.3 % measured vs 44.1 % simulated",
                    o.tracks.stuck_window, rs.rest_speed * 1e6, re.retained, re.entered, re.continued, re.orphans, rs.retained, rs.entered,
                    rs.continued, rs.orphans),
        o.reference_name));
    if (rs.entered > 0)
      c.metrics.push_back(info("retention_simulation_labelled", double(rs.labelled_deposited) / rs.entered, "1",
                               fmt::format("simulated particles whose trajectory ends on a row labelled deposited (the engine's attachment), "
                                           "{} of the {} that entered; not compared: the reference's labels come from another rule",
                                           rs.labelled_deposited, rs.entered)));
  }
  {
    Acceptance a;
    a.metric = "streamline_iou";
    a.reference.low = o.iou_minimum;
    a.reference.high = 1.0;
    a.reference.value = 0.5 * (1 + o.iou_minimum);
    a.reference.unit = "1";
    a.reference.source = "overlap of the occupancy maps (paper Fig. 14 composite)";
    a.tolerance = {Tolerance::Kind::interval, 0, "interval"};
    a.reason = "the simulated particles visit the pores the reference tracks did";
    c.metrics.push_back(evaluateMetric(a, c.iou));
  }
  if (o.regions != nullptr) {
    c.regions_experiment = regionSpeeds(e.steps, *o.regions);
    c.regions_simulation = regionSpeeds(s.steps, *o.regions);
    c.region_picture = o.regions->picture();
    const double px = o.regions->frame.pixel_size;
    c.regions_info = {{"rule", o.regions->rule},
                      {"throat_width_threshold_um", o.regions->threshold_px * px * 1e6},
                      {"pore_body_pixels", cv::countNonZero(o.regions->label == 1)},
                      {"throat_pixels", cv::countNonZero(o.regions->label == 2)},
                      {"experiment", c.regions_experiment->toJson()},
                      {"simulation", c.regions_simulation->toJson()}};
    auto region = [&](const char* name, double sim, double exp, const char* what) {
      if (std::isfinite(sim) && std::isfinite(exp) && exp > 0) {
        c.metrics.push_back(against(name, sim * 1e6, exp * 1e6, "um/s", relative(o.speed_tolerance),
                                    std::string("mean speed of the steps in ") + what + " (error: relative difference simulation vs reference tracks)",
                                    o.reference_name));
        c.regions_info[std::string(name) + "_relative_difference"] = (sim - exp) / exp;
      } else {
        c.regions_info[std::string(name) + "_missing"] = std::string("no step of ") + (std::isfinite(exp) ? "the simulation" : "the reference tracks") + " in " + what;
      }
    };
    region("speed_pore_bodies", c.regions_simulation->body_mean, c.regions_experiment->body_mean, "pore bodies");
    region("speed_throats", c.regions_simulation->throat_mean, c.regions_experiment->throat_mean, "pore throats");
    const int exp_total = c.regions_experiment->body_steps + c.regions_experiment->throat_steps + c.regions_experiment->grain_steps;
    if (exp_total > 0)
      c.metrics.push_back(info("experiment_steps_in_grains", double(c.regions_experiment->grain_steps) / exp_total, "1",
                               "share of the reference tracks' steps inside grains of the mask: large values mean a poor alignment"));
  }
  c.metrics.push_back(info("speed_wasserstein1", c.wasserstein * 1e6, "um/s", "W1 distance between the speed distributions"));
  c.metrics.push_back(info("speed_ks_statistic", c.ks_statistic, "1", "two-sample Kolmogorov-Smirnov D of the speeds"));
  c.metrics.push_back(info("speed_ks_p_value", c.ks_p_value, "1",
                           fmt::format("asymptotic p-value of D over {} and {} per-frame steps taken as independent; steps along one track are "
                                       "correlated, so it is far too small: see track_speed_ks_p_value",
                                       e.steps.size(), s.steps.size())));
  if (c.track_samples_experiment > 0 && c.track_samples_simulation > 0) {
    c.metrics.push_back(info("track_speed_ks_statistic", c.track_ks_statistic, "1",
                             "two-sample Kolmogorov-Smirnov D of the per-track mean speeds (one value per moving track)"));
    c.metrics.push_back(info("track_speed_ks_p_value", c.track_ks_p_value, "1",
                             fmt::format("asymptotic p-value of that D over {} and {} moving tracks, each track one independent sample "
                                         "(small: the two sets of track speeds differ)",
                                         c.track_samples_experiment, c.track_samples_simulation)));
  }
  return c;
}

std::vector<std::string> failedMetrics(const Comparison& c) {
  std::vector<std::string> names;
  for (const auto& m : c.metrics)
    if (m.pass.has_value() && !*m.pass) names.push_back(m.name);
  return names;
}

nlohmann::json Comparison::toJson() const {
  nlohmann::json m = nlohmann::json::array();
  bool all = true;
  for (const auto& r : metrics) {
    m.push_back(r.toJson());
    if (r.pass.has_value() && !*r.pass) all = false;
  }
  auto counts = [](const TrackStats& s, const RestCount& r) {
    return nlohmann::json{{"particles", s.particles}, {"immobile", s.immobile}, {"mobile", s.mobile}, {"retained", s.retained},
                          {"steps", s.steps.size()}, {"t_begin_s", s.t_begin}, {"t_end_s", s.t_end}, {"points", r.points},
                          {"points_at_rest", r.at_rest}, {"points_labelled_deposited", r.labelled_in_file}};
  };
  nlohmann::json j{{"schema", "mmval-compare/1"},
                   {"metrics", m},
                   {"all_pass", all},
                   {"experiment", counts(experiment, rest_experiment)},
                   {"simulation", counts(simulation, rest_simulation)},
                   {"rest_rule", {{"window_s", rest_rule.window}, {"distance_um", rest_rule.distance * 1e6}}}};
  if (!alignment.is_null()) j["alignment"] = alignment;
  if (!regions_info.is_null()) j["regions"] = regions_info;
  return j;
}

std::vector<std::string> writeComparison(const Comparison& c, const std::filesystem::path& dir) {
  std::filesystem::create_directories(dir);
  std::vector<std::string> files;
  writeFileAtomic(dir / "metrics.json", c.toJson().dump(2) + "\n");
  files.push_back("metrics.json");
  auto series = [&](const char* name, auto column) {
    std::string out = std::string("t_s,experiment,simulation\n");
    const auto& a = c.experiment.series;
    const auto& b = c.simulation.series;
    for (std::size_t i = 0; i < std::max(a.t.size(), b.t.size()); ++i) {
      const double t = i < a.t.size() ? a.t[i] : b.t[i];
      auto val = [&](const TimeSeries& s) { return i < s.t.size() ? fmt::format("{:.6g}", column(s)[i] * 1e6) : std::string("nan"); };
      out += fmt::format("{:.6g},{},{}\n", t, val(a), val(b));
    }
    writeFileAtomic(dir / name, out);
    files.push_back(name);
  };
  series("mean_speed_time_um_per_s.csv", [](const TimeSeries& s) -> const std::vector<double>& { return s.mean_speed; });
  series("median_speed_time_um_per_s.csv", [](const TimeSeries& s) -> const std::vector<double>& { return s.median_speed; });
  series("sigma_x_time_um.csv", [](const TimeSeries& s) -> const std::vector<double>& { return s.sigma_x; });
  series("sigma_y_time_um.csv", [](const TimeSeries& s) -> const std::vector<double>& { return s.sigma_y; });
  {
    // The paper's Eq. 18 frame by frame, the values the two files above average per bin: for
    // each side and frame, the moving particles in it (analyseTracks: no immobile track, no
    // deposited particle's resting tail), their mean position and population standard
    // deviation. Frames with one particle have sigma 0 and are left out of the bins' means.
    std::string out = "side,frame,t_s,count,mean_x_um,mean_y_um,sigma_x_um,sigma_y_um\n";
    for (const auto& [side, stats] : {std::pair{"experiment", &c.experiment}, std::pair{"simulation", &c.simulation}})
      for (const auto& f : stats->frames)
        out += fmt::format("{},{},{:.9g},{},{:.9g},{:.9g},{:.9g},{:.9g}\n", side, f.frame, f.t, f.count, f.mean_x * 1e6, f.mean_y * 1e6,
                           f.sigma_x * 1e6, f.sigma_y * 1e6);
    writeFileAtomic(dir / "dispersion_frames.csv", out);
    files.push_back("dispersion_frames.csv");
  }
  {
    std::string out = "t_s,experiment,simulation\n";
    const auto& a = c.retention_experiment;
    const auto& b = c.retention_simulation;
    for (std::size_t i = 0; i < a.t.size() && i < b.t.size(); ++i)
      out += fmt::format("{:.6g},{:.6g},{:.6g}\n", a.t[i], a.fraction[i], b.fraction[i]);
    writeFileAtomic(dir / "retention_time.csv", out);
    files.push_back("retention_time.csv");
  }
  if (c.regions_experiment && c.regions_simulation) {
    std::string out = "region,experiment_mean_speed_um_per_s,simulation_mean_speed_um_per_s,relative_difference,experiment_steps,simulation_steps\n";
    auto row = [&](const char* name, double e, double s, int ne, int ns) {
      const bool ok = std::isfinite(e) && std::isfinite(s) && e > 0;
      out += fmt::format("{},{:.6g},{:.6g},{},{},{}\n", name, e * 1e6, s * 1e6, ok ? fmt::format("{:.6g}", (s - e) / e) : "nan", ne, ns);
    };
    row("pore_body", c.regions_experiment->body_mean, c.regions_simulation->body_mean, c.regions_experiment->body_steps, c.regions_simulation->body_steps);
    row("throat", c.regions_experiment->throat_mean, c.regions_simulation->throat_mean, c.regions_experiment->throat_steps, c.regions_simulation->throat_steps);
    writeFileAtomic(dir / "region_speeds.csv", out);
    files.push_back("region_speeds.csv");
  }
  for (const auto& [picture, name] : {std::pair{&c.region_picture, "regions.png"}, std::pair{&c.registration_picture, "registration.png"}}) {
    if (picture->empty()) continue;
    const auto tmp = temporaryPathFor(dir / name);
    if (!cv::imwrite(tmp.string(), *picture)) throw std::runtime_error("cannot write " + tmp.string());
    commitTemporary(tmp, dir / name);
    files.push_back(name);
  }
  // Speed histograms on common bins.
  double vmax = 0;
  for (const auto* s : {&c.experiment, &c.simulation})
    for (const auto& st : s->steps) vmax = std::max(vmax, st.speed);
  const int nb = 30;
  std::vector<double> he(nb, 0), hs(nb, 0);
  auto fill = [&](const TrackStats& s, std::vector<double>& h) {
    for (const auto& st : s.steps) h[std::min(nb - 1, static_cast<int>(st.speed / std::max(vmax, 1e-300) * nb))] += 1;
    for (auto& x : h) x /= std::max<std::size_t>(1, s.steps.size());
  };
  fill(c.experiment, he);
  fill(c.simulation, hs);
  std::string hist = "speed_um_per_s,experiment_fraction,simulation_fraction\n";
  for (int i = 0; i < nb; ++i) hist += fmt::format("{:.6g},{:.6g},{:.6g}\n", (i + 0.5) * vmax / nb * 1e6, he[i], hs[i]);
  writeFileAtomic(dir / "speed_histogram.csv", hist);
  files.push_back("speed_histogram.csv");
  if (!c.occupancy_experiment.empty()) {
    // Experiment | simulation | overlay (experiment magenta, simulation green, both white).
    const cv::Mat& a = c.occupancy_experiment;
    const cv::Mat& b = c.occupancy_simulation;
    cv::Mat overlay;
    cv::merge(std::vector<cv::Mat>{a, b, a}, overlay);  // B, G, R
    cv::Mat ga, gb;
    cv::cvtColor(a, ga, cv::COLOR_GRAY2BGR);
    cv::cvtColor(b, gb, cv::COLOR_GRAY2BGR);
    cv::Mat sep(a.rows, 2, CV_8UC3, cv::Scalar(128, 128, 128));
    cv::Mat row;
    cv::hconcat(std::vector<cv::Mat>{ga, sep, gb, sep, overlay}, row);
    const auto tmp = temporaryPathFor(dir / "streamlines.png");
    if (!cv::imwrite(tmp.string(), row)) throw std::runtime_error("cannot write " + tmp.string());
    commitTemporary(tmp, dir / "streamlines.png");
    files.push_back("streamlines.png");
  }
  return files;
}

}  // namespace mmval::compare
