#include "mmval/tracking/Pipeline.hpp"

#include <chrono>
#include <algorithm>
#include <cmath>
#include <map>
#include <thread>
#include <atomic>
#include <condition_variable>
#include <exception>
#include <mutex>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Progress.hpp"

namespace mmval::tracking {

TrackRun runTracker(FrameSource& source, const TrackConfig& c, bool quiet) {
  const auto t0 = std::chrono::steady_clock::now();
  TrackRun run;
  if (c.detect.subtract_background) run.background = medianBackground(source, c.detect.background_samples);
  TrackLinker linker(c.link);
  Progress progress("tracking", static_cast<std::size_t>(std::max(0, source.count())), quiet);
  Polarity polarity = c.detect.polarity;
  const int threads = std::max(1, c.threads);
  // Stuck-particle candidates (spots of the median background) and, per candidate, the
  // frames in which the spot is missing from the frame: there the frame is brighter (dark
  // polarity) than the background by about the spot's amplitude.
  std::vector<Detection> stuck;
  std::vector<std::atomic<int>> absent;
  bool stuck_ready = !(c.detect.find_stuck && !run.background.empty());
  auto prepare = [&](const cv::Mat& first) {
    if (polarity == Polarity::automatic) polarity = guessPolarity(first, run.background);
    if (!stuck_ready) {
      stuck = detectStuck(run.background, polarity, c.detect);
      absent = std::vector<std::atomic<int>>(stuck.size());
      stuck_ready = true;
    }
  };
  // One frame's work (any thread): detections, and the absence test of the stuck candidates.
  auto process = [&](const cv::Mat& f) {
    if (!stuck.empty()) {
      // Least-squares amplitude of a spot of sigma 1.5 px at the candidate in
      // (background - frame) for dark particles: ~0 while the particle is there, about
      // minus its amplitude once it has gone.
      const double sign = polarity == Polarity::bright ? 1.0 : -1.0;
      for (std::size_t i = 0; i < stuck.size(); ++i) {
        const int cx = static_cast<int>(std::lround(stuck[i].x)), cy = static_cast<int>(std::lround(stuck[i].y));
        double sg = 0, sgg = 0;
        for (int y = std::max(0, cy - 4); y <= std::min(f.rows - 1, cy + 4); ++y)
          for (int x = std::max(0, cx - 4); x <= std::min(f.cols - 1, cx + 4); ++x) {
            const double g = std::exp(-((x - stuck[i].x) * (x - stuck[i].x) + (y - stuck[i].y) * (y - stuck[i].y)) / (2 * 1.5 * 1.5));
            sg += g * sign * (f.at<float>(y, x) - run.background.at<float>(y, x));
            sgg += g * g;
          }
        if (sgg > 0 && sg / sgg > 0.5 * stuck[i].peak) ++absent[i];
      }
    }
    return detect(f, run.background, polarity, c.detect);
  };
  auto link = [&](int index, std::vector<Detection>&& found) {
    linker.push(index, found);
    run.detections.push_back(std::move(found));
    run.frame_index.push_back(index);
    progress.advance();
  };
  cv::Mat frame;
  int index = 0;
  if (threads > 1 && source.randomAccess() && source.next(frame, index)) {
    // Image files: `threads` workers each read (decode) and detect whole frames, taking
    // the next frame number from a shared counter; this thread links them in order as
    // they complete. The first frame, read here, fixes polarity, size and 16-bit range.
    prepare(frame);
    const int n = source.count();
    std::vector<std::vector<Detection>> found(static_cast<std::size_t>(n));
    std::vector<int> frame_of(static_cast<std::size_t>(n), 0);
    std::vector<char> done(static_cast<std::size_t>(n), 0);
    std::vector<std::exception_ptr> failed(static_cast<std::size_t>(n));
    std::mutex m;
    std::condition_variable ready;
    std::atomic<int> next_pos{1};
    std::atomic<bool> stop{false};
    found[0] = process(frame);
    frame_of[0] = index;
    done[0] = 1;
    auto worker = [&] {
      cv::Mat f;
      for (int pos; !stop && (pos = next_pos++) < n;) {
        std::exception_ptr error;
        std::vector<Detection> d;
        int at = 0;
        try {
          source.readAt(pos, f, at);
          d = process(f);
        } catch (...) {
          error = std::current_exception();
        }
        {
          const std::lock_guard<std::mutex> lock(m);
          found[pos] = std::move(d);
          frame_of[pos] = at;
          failed[pos] = error;
          done[pos] = 1;
        }
        ready.notify_all();
      }
    };
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(worker);
    std::exception_ptr error;
    for (int pos = 0; pos < n && !error; ++pos) {
      std::unique_lock<std::mutex> lock(m);
      ready.wait(lock, [&] { return done[pos] != 0; });
      if (failed[pos]) {
        error = failed[pos];
        break;
      }
      std::vector<Detection> d = std::move(found[pos]);
      lock.unlock();
      link(frame_of[pos], std::move(d));
    }
    stop = true;
    for (auto& t : pool) t.join();
    if (error) std::rethrow_exception(error);
  } else {
    // In order (videos, TIFF stacks, one thread): batches of 2 x threads frames are read
    // here, detected in parallel, then linked in frame order.
    std::vector<cv::Mat> batch(static_cast<std::size_t>(2 * threads));
    std::vector<int> batch_index(batch.size());
    std::vector<std::vector<Detection>> found(batch.size());
    for (bool more = true; more;) {
      std::size_t n = 0;
      while (n < batch.size() && (more = source.next(batch[n], batch_index[n]))) ++n;
      if (n == 0) break;
      prepare(batch[0]);
      auto work = [&](std::size_t first) {
        for (std::size_t k = first; k < n; k += static_cast<std::size_t>(threads)) found[k] = process(batch[k]);
      };
      if (threads == 1) {
        work(0);
      } else {
        std::vector<std::thread> pool;
        for (int t = 1; t < threads; ++t) pool.emplace_back(work, static_cast<std::size_t>(t));
        work(0);
        for (auto& t : pool) t.join();
      }
      for (std::size_t k = 0; k < n; ++k) link(batch_index[k], std::move(found[k]));
    }
  }
  progress.finish();
  run.polarity = polarity;
  run.link = linker.stats();
  std::int64_t next_id = 0;
  for (const auto& p : linker.points()) next_id = std::max(next_id, p.particle + 1);
  if (c.detect.find_stuck && !run.background.empty() && !run.frame_index.empty()) {
    // Stuck for the whole video: invisible after background removal, found in the background.
    // Stuck particles look like the moving ones: keep background spots whose blob area
    // is within a factor 2 of the median area of the moving detections.
    // ... and whose peak is at least half the moving ones' median peak (grain edges leave
    // faint round residues in the hat).
    std::vector<double> areas, peaks;
    for (const auto& frame : run.detections)
      for (const auto& m : frame) {
        areas.push_back(m.area);
        peaks.push_back(m.peak);
      }
    double typical = 0, typical_peak = 0;
    if (!areas.empty()) {
      std::nth_element(areas.begin(), areas.begin() + areas.size() / 2, areas.end());
      typical = areas[areas.size() / 2];
      std::nth_element(peaks.begin(), peaks.begin() + peaks.size() / 2, peaks.end());
      typical_peak = peaks[peaks.size() / 2];
    }
    for (std::size_t i = 0; i < stuck.size(); ++i) {
      const Detection& d = stuck[i];
      if (typical > 0 && (d.area < 0.5 * typical || d.area > 2.0 * typical || d.peak < 0.5 * typical_peak)) continue;
      // A particle that only lingers (stationary for most, not all, of the video) also
      // shows in the median; it is missing from the frames where it was elsewhere.
      if (absent[i] > static_cast<int>(run.frame_index.size() / 10)) continue;
      for (int f : run.frame_index) {
        TrackPoint t;
        t.frame = f;
        t.particle = next_id;
        t.t = f / c.fps;
        t.x_px = d.x;
        t.y_px = d.y;
        t.x = d.x * c.pixel_size;
        t.y = d.y * c.pixel_size;
        run.tracks.points.push_back(t);
      }
      ++next_id;
      ++run.stuck_found;
    }
  }
  for (const auto& p : linker.points()) {
    TrackPoint t;
    t.frame = p.frame;
    t.particle = p.particle;
    t.t = p.frame / c.fps;
    t.x_px = p.x;
    t.y_px = p.y;
    t.x = p.x * c.pixel_size;
    t.y = p.y * c.pixel_size;
    run.tracks.points.push_back(t);
  }
  std::stable_sort(run.tracks.points.begin(), run.tracks.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return run;
}

std::vector<std::string> writeTrackOutputs(const TrackRun& run, const TrackConfig& c, const std::filesystem::path& dir,
                                           const nlohmann::json& extra) {
  std::filesystem::create_directories(dir);
  std::vector<std::string> files;
  auto put = [&](const std::string& name, const std::string& text) {
    writeFileAtomic(dir / name, text);
    files.push_back(name);
  };
  std::string det = "frame,t_s,x_px,y_px,x_um,y_um,area_px2,mass,peak\n";
  for (std::size_t k = 0; k < run.detections.size(); ++k)
    for (const auto& d : run.detections[k])
      det += fmt::format("{},{:.6g},{:.4f},{:.4f},{:.4f},{:.4f},{:.1f},{:.4g},{:.4g}\n", run.frame_index[k], run.frame_index[k] / c.fps, d.x, d.y,
                         d.x * c.pixel_size * 1e6, d.y * c.pixel_size * 1e6, d.area, d.mass, d.peak);
  put("detections.csv", det);
  const TrackStats s = analyseTracks(run.tracks, c.analysis);
  {
    std::map<std::int64_t, std::string> state;
    for (const auto& t : s.tracks) state[t.particle] = t.state;
    Tracks labelled = run.tracks;
    for (auto& p : labelled.points) p.state = state[p.particle];
    writeTracksCsv(dir / "tracks.csv", labelled, c.pixel_size);
    files.push_back("tracks.csv");
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
  std::string disp = "frame,t_s,count,mean_x_um,mean_y_um,sigma_x_um,sigma_y_um\n";
  for (const auto& f : s.frames)
    disp += fmt::format("{},{:.6g},{},{:.5g},{:.5g},{:.5g},{:.5g}\n", f.frame, f.t, f.count, f.mean_x * 1e6, f.mean_y * 1e6, f.sigma_x * 1e6,
                        f.sigma_y * 1e6);
  put("dispersion.csv", disp);
  std::string msd = "lag_s,msd_um2,samples\n";
  for (std::size_t i = 0; i < s.msd.lag.size(); ++i) msd += fmt::format("{:.6g},{:.6g},{}\n", s.msd.lag[i], s.msd.msd[i] * 1e12, s.msd.samples[i]);
  put("msd.csv", msd);
  std::string speed = "t_s,mean_speed_um_per_s,median_speed_um_per_s,sigma_x_um,sigma_y_um,steps\n";
  for (std::size_t i = 0; i < s.series.t.size(); ++i)
    speed += fmt::format("{:.6g},{:.5g},{:.5g},{:.5g},{:.5g},{}\n", s.series.t[i], s.series.mean_speed[i] * 1e6, s.series.median_speed[i] * 1e6,
                         s.series.sigma_x[i] * 1e6, s.series.sigma_y[i] * 1e6, s.series.count[i]);
  put("speed_time.csv", speed);
  // Deposited over time: mobile particles whose track has ended in a stop by time t.
  std::string ret = "quantity,value\n";
  ret += fmt::format("particles,{}\nimmobile,{}\nmobile,{}\nretained,{}\nretained_fraction,{:.5g}\n", s.particles, s.immobile, s.mobile, s.retained,
                     s.retained_fraction);
  put("retention.csv", ret);
  {
    // Deposited over time: a deposited particle counts from the first frame after which
    // it stays within stuck_distance of where it ends.
    std::map<std::int64_t, std::string> state;
    for (const auto& t : s.tracks) state[t.particle] = t.state;
    std::vector<double> stop_times;
    const auto& pts = run.tracks.points;
    for (std::size_t i = 0; i < pts.size();) {
      std::size_t j = i;
      while (j < pts.size() && pts[j].particle == pts[i].particle) ++j;
      if (state[pts[i].particle] == "deposited") {
        std::size_t k = j - 1;
        while (k > i && std::hypot(pts[k - 1].x - pts[j - 1].x, pts[k - 1].y - pts[j - 1].y) < c.analysis.stuck_distance) --k;
        stop_times.push_back(pts[k].t);
      }
      i = j;
    }
    std::sort(stop_times.begin(), stop_times.end());
    std::string rt = "frame,t_s,deposited\n";
    std::size_t n = 0;
    for (int f : run.frame_index) {
      const double t = f / c.fps;
      while (n < stop_times.size() && stop_times[n] <= t + 1e-12) ++n;
      rt += fmt::format("{},{:.6g},{}\n", f, t, n);
    }
    put("retention_time.csv", rt);
  }
  // Streamline composite: every position of every frame, over the background.
  if (!run.detections.empty()) {
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
    cv::Mat img;
    cv::cvtColor(base, img, cv::COLOR_GRAY2BGR);
    img = img * 0.6;
    for (std::size_t i = 1; i < run.tracks.points.size(); ++i) {
      const auto& a = run.tracks.points[i - 1];
      const auto& b = run.tracks.points[i];
      if (a.particle != b.particle) continue;
      const cv::Scalar colour((a.particle * 67) % 200 + 55, (a.particle * 131) % 200 + 55, (a.particle * 29) % 200 + 55);
      cv::line(img, cv::Point2d(a.x_px, a.y_px), cv::Point2d(b.x_px, b.y_px), colour, 1, cv::LINE_AA);
    }
    const auto tmp = temporaryPathFor(dir / "streamlines.png");
    cv::imwrite(tmp.string(), img);
    commitTemporary(tmp, dir / "streamlines.png");
    files.push_back("streamlines.png");
  }
  nlohmann::json summary = extra;
  summary["frames"] = run.frame_index.size();
  summary["tracks"] = s.particles;
  summary["immobile"] = s.immobile;
  summary["retained"] = s.retained;
  summary["retained_fraction"] = s.retained_fraction;
  summary["mean_speed_um_per_s"] = s.mean_speed * 1e6;
  summary["median_speed_um_per_s"] = s.median_speed * 1e6;
  summary["polarity"] = run.polarity == Polarity::dark ? "dark" : "bright";
  summary["links"] = run.link.links;
  summary["gap_closures"] = run.link.gap_closures;
  summary["largest_component"] = run.link.largest_component;
  summary["greedy_components"] = run.link.greedy_components;
  summary["msd_exponent"] = s.msd.alpha;
  summary["msd_D_power_um2_per_s"] = s.msd.d_power * 1e12;
  summary["msd_D_linear_um2_per_s"] = s.msd.d_linear * 1e12;
  summary["parameters"] = {{"pixel_size_um", c.pixel_size * 1e6}, {"fps", c.fps}, {"blur_sigma", c.detect.blur_sigma},
                           {"subtract_background", c.detect.subtract_background}, {"search_radius_px", c.link.search_radius},
                           {"memory", c.link.memory}, {"linker", c.link.method == Linker::global ? "global" : "paper"},
                           {"seeds", c.detect.method == SeedMethod::peaks ? "peaks" : "contours"}, {"threads", c.threads}};
  summary["stuck_found_in_background"] = run.stuck_found;
  summary["seconds"] = run.seconds;
  summary["frames_per_second"] = run.seconds > 0 ? run.frame_index.size() / run.seconds : 0.0;
  put("summary.json", summary.dump(2) + "\n");
  return files;
}

}  // namespace mmval::tracking
