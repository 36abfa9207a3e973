#include "mmval/core/JsonNumbers.hpp"
#include "mmval/tracking/Pipeline.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <future>
#include <iterator>
#include <limits>
#include <map>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "BrownianOutputs.hpp"
#include "MsdTable.hpp"
#include "PngWriter.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/core/VtkWriter.hpp"
#include "mmval/tracking/TrackImages.hpp"

namespace mmval::tracking {

namespace {

/// The flow-mode files (tracks.csv to retention.csv); returns their statistics.
TrackStats writeFlowOutputs(const TrackRun& run, const TrackConfig& c, const std::filesystem::path& dir,
                            const std::function<void(const std::string&, const std::string&)>& put, std::vector<std::string>& files);
cv::Mat baseImage(const TrackRun& run);
cv::Mat streamlines(const TrackRun& run);
/// retention.csv (mmval/core/OutputTables.hpp) from the tracks, one row per frame of
/// `frame_index` (t = frame / fps): injected = moving tracks begun by t (particles that
/// entered the field of view), retained = those stopped for good by t, left = those
/// that ended by t without stopping, inside = the rest.
std::string retentionTable(const Tracks& tracks, const TrackStats& s, const std::vector<int>& frame_index, double fps);

/// tracks.vtp: one polyline per particle in the frame of docs/outputs.md (metres, x right,
/// y up, origin at the image's bottom-left corner), so that the tracks overlay the fields
/// of a simulation of the same mask at the same pixel size. A tracker position (x_px, y_px)
/// has pixel (c, r)'s centre at (c, r), as in tracks.csv (trackpy's convention), so
/// X = (x_px + 1/2) p and Y = (rows - y_px - 1/2) p. Returns false (nothing written) when
/// the frame height is unknown (no background image was taken).
bool writeTracksVtp(const std::filesystem::path& file, const Tracks& tracks, double pixel_size_m, int rows) {
  if (rows <= 0 || !(pixel_size_m > 0)) return false;
  vtk::PolyData d;
  std::vector<std::int64_t> particle, frame, line_particle;
  std::vector<double> t;
  std::vector<std::uint8_t> deposited;
  for (const auto& q : tracks.points) {
    if (d.lines.empty() || q.particle != line_particle.back()) {
      d.lines.emplace_back();
      line_particle.push_back(q.particle);
    }
    const double xp = std::isfinite(q.x_px) ? q.x_px : q.x / pixel_size_m;
    const double yp = std::isfinite(q.y_px) ? q.y_px : q.y / pixel_size_m;
    d.lines.back().push_back(static_cast<std::int64_t>(d.points.size()));
    d.points.push_back({(xp + 0.5) * pixel_size_m, (rows - yp - 0.5) * pixel_size_m, 0.0});
    particle.push_back(q.particle);
    frame.push_back(q.frame);
    t.push_back(q.t);
    deposited.push_back(q.state == "deposited" ? 1 : 0);
  }
  d.point_data = {vtk::Array::int64("particle", "1", particle), vtk::Array::int64("frame", "1", frame), vtk::Array::float64("t", "s", 1, t),
                  vtk::Array::uint8("deposited", "1", deposited)};
  d.cell_data = {vtk::Array::int64("particle", "1", line_particle)};
  vtk::writeVtp(file, d);
  return true;
}

/// detections.csv: every detection of every processed frame.
std::string detectionsCsv(const TrackRun& run, const TrackConfig& c) {
  std::string det = "frame,t_s,x_px,y_px,x_um,y_um,area_px2,mass,peak\n";
  // Formatted straight into the file's text (no string per row).
  auto det_out = std::back_inserter(det);
  for (std::size_t k = 0; k < run.detections.size(); ++k)
    for (const auto& d : run.detections[k])
      fmt::format_to(det_out, "{},{:.6g},{:.4f},{:.4f},{:.4f},{:.4f},{:.1f},{:.4g},{:.4g}\n", run.frame_index[k], run.frame_index[k] / c.fps, d.x, d.y,
                     d.x * c.pixel_size * 1e6, d.y * c.pixel_size * 1e6, d.area, d.mass, d.peak);
  return det;
}

}  // namespace

std::vector<std::string> writeTrackOutputs(const TrackRun& run, const TrackConfig& c, const std::filesystem::path& dir,
                                           const nlohmann::json& extra) {
  std::filesystem::create_directories(dir);
  std::vector<std::string> files;
  auto put = [&](const std::string& name, const std::string& text) {
    writeFileAtomic(dir / name, text);
    files.push_back(name);
  };
  // The pictures are encoded here (PngWriter.hpp), not by OpenCV's codec module, which
  // `mmval track` then never loads.
  const auto writePng = [&](const std::string& name, const cv::Mat& m) { writeFileAtomic(dir / name, detail::encodePng(m)); };
  const auto png = [&](const std::string& name, const cv::Mat& m) {
    writePng(name, m);
    files.push_back(name);
  };
  const bool brownian = run.motion.model == MotionModel::brownian;
  // The files that depend on nothing written here (detections.csv; in Brownian mode
  // tracks.vtp and streamlines.png) are written by a second thread while this one writes
  // the analysis' files (one thread when c.threads is 1); `files` keeps the same order.
  const auto independent = [&] {
    writeFileAtomic(dir / "detections.csv", detectionsCsv(run, c));
    if (!brownian) return false;
    const bool vtp = writeTracksVtp(dir / "tracks.vtp", run.tracks, c.pixel_size, run.background.rows);
    if (!run.detections.empty()) writePng("streamlines.png", streamlines(run));
    return vtp;
  };
  std::future<bool> side;
  bool vtp_written = false;
  if (c.threads == 1)
    vtp_written = independent();
  else
    side = std::async(std::launch::async, independent);
  files.push_back("detections.csv");
  nlohmann::json summary = extra;
  TrackStats s;
  if (brownian)
    summary.update(detail::writeBrownianOutputs(run, c, {dir, put, png, &files}));
  else
    s = writeFlowOutputs(run, c, dir, put, files);
  if (side.valid()) vtp_written = side.get();
  if (vtp_written) files.push_back("tracks.vtp");
  // Streamline composite: every position of every frame, over the background.
  if (!run.detections.empty()) {
    if (brownian)
      files.push_back("streamlines.png");
    else
      png("streamlines.png", streamlines(run));
    // Steps coloured by speed, and the mean speed binned on the pore space (bins of
    // about two particle diameters).
    if (!brownian) {
      const cv::Mat base = baseImage(run);
      png("velocity_overlay.png", velocityOverlay(base, s, c.pixel_size, 1.0 / c.fps));
      png("speed_map.png", speedMap(base, s, c.pixel_size, std::max(4, 2 * c.detect.refine_radius)));
    }
  }
  summary["motion"] = {{"requested", motionModelName(run.motion.requested)}, {"model", motionModelName(run.motion.model)},
                       {"reason", run.motion.reason}, {"relinked_without_prediction", run.motion.relinked}};
  if (std::isfinite(run.motion.step_correlation))
    summary["motion"]["numbers"] = {{"step_correlation", run.motion.step_correlation}, {"step_correlation_se", run.motion.step_correlation_se},
                                    {"brownian_bound", run.motion.correlation_bound}, {"z_directed", run.motion.z_directed},
                                    {"z_diffusing", run.motion.z_diffusing},
                                    {"drift_peclet", finiteOrNull(run.motion.drift_peclet)},
                                    {"step_pairs", run.motion.step_pairs}, {"tracks", run.motion.tracks}};
  if (run.motion.persistence_tracks > 0) {
    // The persistence test's counts (MotionDecision.cpp): tracks judged, persistent, the count
    // diffusion would give by chance, and the binomial chance of at least as many.
    auto& n = summary["motion"]["numbers"];
    n["persistence_tracks"] = run.motion.persistence_tracks;
    n["persistent_tracks"] = run.motion.persistent_tracks;
    n["persistent_expected"] = run.motion.persistent_alpha * run.motion.persistence_tracks;
    n["persistent_p"] = finiteOrNull(run.motion.persistent_p);
  }
  summary["frames"] = run.frame_index.size();
  if (!brownian) {
    summary["tracks"] = s.particles;
    summary["immobile"] = s.immobile;
    summary["mobile"] = s.mobile;
    summary["retained"] = s.retained;
    summary["entered"] = s.entered;
    summary["retained_fraction"] = s.retained_fraction;
    summary["mean_speed_um_per_s"] = s.mean_speed * 1e6;
    summary["median_speed_um_per_s"] = s.median_speed * 1e6;
  } else {
    summary["tracks"] = summary["brownian"]["tracks"]["mobile"].get<int>() + summary["brownian"]["tracks"]["immobile"].get<int>() +
                        summary["brownian"]["tracks"]["short"].get<int>();
  }
  summary["polarity"] = polarityName(run.polarity);
  summary["links"] = run.link.links;
  summary["gap_closures"] = run.link.gap_closures;
  summary["largest_component"] = run.link.largest_component;
  summary["greedy_components"] = run.link.greedy_components;
  if (!brownian) {
    summary["msd_exponent"] = s.msd.alpha;
    summary["msd_D_power_um2_per_s"] = s.msd.d_power * 1e6 * 1e6;
    summary["msd_D_linear_um2_per_s"] = s.msd.d_linear * 1e6 * 1e6;
  }
  summary["parameters"] = {{"pixel_size_um", c.pixel_size * 1e6}, {"fps", c.fps}, {"blur_sigma", c.detect.blur_sigma},
                           {"background", run.background_decision.subtract ? "median" : "none"}, {"search_radius_px", c.link.search_radius},
                           {"memory", c.link.memory}, {"linker", c.link.method == Linker::global ? "global" : "paper"},
                           {"seeds", c.detect.method == SeedMethod::peaks ? "peaks" : "contours"}, {"threads", c.threads},
                           {"smooth_frames", c.smooth_frames}, {"background_quantile", c.background_quantile},
                           {"background_window", c.background_window}};
  summary["stuck_found_in_background"] = run.stuck_found;
  summary["deposits_joined_from_background"] = run.deposits_joined;
  summary["deposits_not_joined"] = run.deposits_unjoined;
  summary["cluster_arrivals"] = run.cluster_arrivals;
  summary["deposits_found_by_reference_frames"] = run.deposits_by_reference;
  summary["smoothed_points"] = run.smoothed_points;
  summary["seconds"] = run.seconds;
  summary["frames_per_second"] = run.seconds > 0 ? run.frame_index.size() / run.seconds : 0.0;
  put("summary.json", summary.dump(2) + "\n");
  return files;
}

namespace {

TrackStats writeFlowOutputs(const TrackRun& run, const TrackConfig& c, const std::filesystem::path& dir,
                            const std::function<void(const std::string&, const std::string&)>& put, std::vector<std::string>& files) {
  // Resting ends labelled (idempotent: runTracker has done it), so that every reader of
  // tracks.csv (compare) sees where a deposited particle stopped.
  Tracks labelled = run.tracks;
  markDeposits(labelled, c.analysis);
  const TrackStats s = analyseTracks(labelled, c.analysis);
  {
    // state per point: the track's state, except that a deposited track is "mobile" up to
    // where it stopped and "deposited" from there on (and a mobile one "deposited" where it rested).
    std::map<std::int64_t, std::string> state;
    for (const auto& t : s.tracks) state[t.particle] = t.state;
    for (auto& p : labelled.points) {
      const std::string& track = state[p.particle];
      // A mobile track keeps the "deposited" labels of stretches where it rested mid-track
      // (markDeposits), so that readers of tracks.csv leave those steps out too.
      p.state = track != "deposited" && track != "mobile" ? track : (p.state == "deposited" ? "deposited" : "mobile");
    }
    writeTracksCsv(dir / "tracks.csv", labelled, c.pixel_size);
    files.push_back("tracks.csv");
    if (writeTracksVtp(dir / "tracks.vtp", labelled, c.pixel_size, run.background.rows)) files.push_back("tracks.vtp");
  }
  std::string summ = "particle,points,duration_s,mean_speed_um_per_s,path_length_um,net_displacement_um,straightness,state\n";
  for (const auto& t : s.tracks)
    summ += fmt::format("{},{},{:.6g},{:.5g},{:.5g},{:.5g},{:.4f},{}\n", t.particle, t.points, t.duration, t.mean_speed * 1e6, t.path_length * 1e6,
                        t.net_displacement * 1e6, t.straightness, t.state);
  put("track_summary.csv", summ);
  std::string vel = "particle,t_s,x_um,y_um,vx_um_per_s,vy_um_per_s,speed_um_per_s\n";
  for (const auto& st : s.steps)
    vel += fmt::format("{},{:.6g},{:.4f},{:.4f},{:.5g},{:.5g},{:.5g}\n", st.particle, st.t, st.x * 1e6, st.y * 1e6, st.vx * 1e6, st.vy * 1e6,
                       st.speed * 1e6);
  put("velocities.csv", vel);
  // The ensemble drift (Brownian.hpp) beside the dispersion: in a flow, the mean displacement.
  const EnsembleDrift drift = ensembleDrift(labelled);
  std::string disp = "frame,t_s,count,mean_x_um,mean_y_um,sigma_x_um,sigma_y_um,drift_x_um,drift_y_um\n";
  for (const auto& f : s.frames) {
    double dx, dy;
    drift.at(f.frame, dx, dy);
    disp += fmt::format("{},{:.6g},{},{:.5g},{:.5g},{:.5g},{:.5g},{:.5g},{:.5g}\n", f.frame, f.t, f.count, f.mean_x * 1e6, f.mean_y * 1e6,
                        f.sigma_x * 1e6, f.sigma_y * 1e6, dx * 1e6, dy * 1e6);
  }
  put("dispersion.csv", disp);
  // msd.csv (MsdTable.hpp): no standard error in flow mode; the fit is the power law
  // MSD = 4 D t^alpha behind summary.json's msd_exponent (none without two positive lags).
  std::vector<detail::MsdRow> msd;
  const bool power_fit = s.msd.d_power > 0;
  for (std::size_t i = 0; i < s.msd.lag.size(); ++i)
    msd.push_back({s.msd.lag[i], s.msd.msd[i], s.msd.samples[i], std::numeric_limits<double>::quiet_NaN(),
                   power_fit ? 4.0 * s.msd.d_power * std::pow(s.msd.lag[i], s.msd.alpha) : std::numeric_limits<double>::quiet_NaN()});
  put("msd.csv", detail::msdTable(msd));
  std::string speed = "t_s,mean_speed_um_per_s,median_speed_um_per_s,sigma_x_um,sigma_y_um,steps\n";
  for (std::size_t i = 0; i < s.series.t.size(); ++i)
    speed += fmt::format("{:.6g},{:.5g},{:.5g},{:.5g},{:.5g},{}\n", s.series.t[i], s.series.mean_speed[i] * 1e6, s.series.median_speed[i] * 1e6,
                         s.series.sigma_x[i] * 1e6, s.series.sigma_y[i] * 1e6, s.series.count[i]);
  put("speed_time.csv", speed);
  put("retention.csv", retentionTable(labelled, s, run.frame_index, c.fps));
  return s;
}

std::string retentionTable(const Tracks& tracks, const TrackStats& s, const std::vector<int>& frame_index, double fps) {
  // Per moving track (state mobile or deposited; immobile and short tracks are no
  // particles the flow brought): when it was first and last seen, and when it stopped.
  constexpr double kInf = std::numeric_limits<double>::infinity();
  struct Life {
    double first = kInf, last = -kInf;
    bool deposited = false;
    double stop = kInf;  ///< s; deposited tracks only
  };
  std::map<std::int64_t, Life> lives;
  for (const auto& t : s.tracks)
    if (t.state == "mobile" || t.state == "deposited") lives[t.particle] = {kInf, -kInf, t.state == "deposited", t.stop_time};
  for (const auto& p : tracks.points)
    if (const auto it = lives.find(p.particle); it != lives.end()) {
      it->second.first = std::min(it->second.first, p.t);
      it->second.last = std::max(it->second.last, p.t);
    }
  // Each count as sorted event times, so that a row is three binary searches (long videos
  // have tens of thousands of frames and tracks). A track enters at its first point; a
  // deposited one is retained once it has entered and stopped (without a stop time: from its
  // last point); any other leaves after its last point (which is never before its first).
  std::vector<double> entered, retained, left;
  for (const auto& [id, l] : lives) {
    entered.push_back(l.first);
    if (l.deposited)
      retained.push_back(std::max(l.first, std::isfinite(l.stop) ? l.stop : l.last));
    else
      left.push_back(l.last);
  }
  for (auto* v : {&entered, &retained, &left}) std::sort(v->begin(), v->end());
  const auto atMost = [](const std::vector<double>& v, double t) { return std::upper_bound(v.begin(), v.end(), t) - v.begin(); };
  const auto before = [](const std::vector<double>& v, double t) { return std::lower_bound(v.begin(), v.end(), t) - v.begin(); };
  const double half_frame = 0.5 / fps;  // s: "at or before t" within the frames' resolution
  std::string out = tables::retentionHeader();
  for (int f : frame_index) {
    const double t = f / fps;
    tables::RetentionRow r{f, t, 0, 0, 0, 0};
    r.injected = atMost(entered, t + half_frame);
    r.retained = atMost(retained, t + half_frame);
    r.left = before(left, t - half_frame);
    r.inside = r.injected - r.retained - r.left;
    out += tables::formatRow(r);
  }
  return out;
}

/// 8-bit grey picture under the drawings: the background, or white the size of the tracks.
cv::Mat baseImage(const TrackRun& run) {
  cv::Mat base;
  if (!run.background.empty()) {
    run.background.convertTo(base, CV_8U, 255.0);
  } else {
    int w = 1, h = 1;
    for (const auto& p : run.tracks.points) {
      w = std::max(w, static_cast<int>(p.x_px) + 2);
      h = std::max(h, static_cast<int>(p.y_px) + 2);
    }
    base = cv::Mat(h, w, CV_8U, cv::Scalar(255));
  }
  return base;
}

/// Every track drawn over the dimmed base, one colour per particle.
cv::Mat streamlines(const TrackRun& run) {
  cv::Mat img;
  cv::cvtColor(baseImage(run), img, cv::COLOR_GRAY2BGR);
  img = img * 0.6;
  for (std::size_t i = 1; i < run.tracks.points.size(); ++i) {
    const auto& a = run.tracks.points[i - 1];
    const auto& b = run.tracks.points[i];
    if (a.particle != b.particle) continue;
    const cv::Scalar colour((a.particle * 67) % 200 + 55, (a.particle * 131) % 200 + 55, (a.particle * 29) % 200 + 55);
    cv::line(img, cv::Point2d(a.x_px, a.y_px), cv::Point2d(b.x_px, b.y_px), colour, 1, cv::LINE_AA);
  }
  return img;
}

}  // namespace

}  // namespace mmval::tracking
