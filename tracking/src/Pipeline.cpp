#include "mmval/tracking/Pipeline.hpp"

#include <chrono>
#include <algorithm>
#include <cmath>
#include <map>
#include <unordered_map>
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
#include "mmval/tracking/Background.hpp"
#include "mmval/tracking/TrackImages.hpp"
#include "mmval/tracking/TrackSmooth.hpp"

namespace mmval::tracking {

namespace {

/// Points bucketed in square cells of `cell` px: everything within `cell` of a position
/// is in its 3 x 3 neighbourhood of cells (keeps the joins below linear in the tracks).
class CellGrid {
 public:
  explicit CellGrid(double cell) : m_cell(cell) {}
  void add(std::size_t item, double x, double y) { m_bins[key(cell(x), cell(y))].push_back(item); }
  template <class F>
  void near(double x, double y, F&& visit) const {
    const long long cx = cell(x), cy = cell(y);
    for (long long i = cx - 1; i <= cx + 1; ++i)
      for (long long j = cy - 1; j <= cy + 1; ++j) {
        const auto it = m_bins.find(key(i, j));
        if (it != m_bins.end())
          for (std::size_t item : it->second) visit(item);
      }
  }

 private:
  long long cell(double v) const { return static_cast<long long>(std::floor(v / m_cell)); }
  static long long key(long long i, long long j) { return i * 1000003LL + j; }
  double m_cell;
  std::unordered_map<long long, std::vector<std::size_t>> m_bins;
};

/// A tracker point at pixel position (x, y) of `frame`, with its time and metres.
TrackPoint trackPoint(const TrackConfig& c, std::int64_t frame, std::int64_t particle, double x, double y) {
  TrackPoint t;
  t.frame = frame;
  t.particle = particle;
  t.t = static_cast<double>(frame) / c.fps;
  t.x_px = x;
  t.y_px = y;
  t.x = x * c.pixel_size;
  t.y = y * c.pixel_size;
  return t;
}

/// First and last index of each track in points sorted by particle, then frame.
struct Span {
  std::size_t first, last;
};
std::vector<Span> trackSpans(const std::vector<TrackPoint>& pts) {
  std::vector<Span> spans;
  for (std::size_t i = 0; i < pts.size();) {
    std::size_t j = i;
    while (j < pts.size() && pts[j].particle == pts[i].particle) ++j;
    spans.push_back({i, j - 1});
    i = j;
  }
  return spans;
}

/// Back into the tracks order: by particle, then frame.
void sortTracks(std::vector<TrackPoint>& pts) {
  std::stable_sort(pts.begin(), pts.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
}

/// Appends `end`'s particle at rest at (x, y) in every frame after `end`, labelled deposited.
void restUntilTheEnd(const TrackConfig& c, const TrackPoint& end, double x, double y, const std::vector<int>& frames, std::vector<TrackPoint>& out) {
  for (int f : frames)
    if (f > end.frame) {
      out.push_back(trackPoint(c, f, end.particle, x, y));
      out.back().state = "deposited";
    }
}

/// Least-squares amplitude of a spot (sigma 1.5 px) at (x, y) in sign x (frame - background):
/// ~0 where frame and background agree, about minus a particle's depth where the
/// background holds a particle the frame does not.
double spotDifference(const cv::Mat& f, const cv::Mat& background, double x, double y, double sign) {
  const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
  double sg = 0, sgg = 0;
  for (int yy = std::max(0, cy - 4); yy <= std::min(f.rows - 1, cy + 4); ++yy)
    for (int xx = std::max(0, cx - 4); xx <= std::min(f.cols - 1, cx + 4); ++xx) {
      const double g = std::exp(-((xx - x) * (xx - x) + (yy - y) * (yy - y)) / (2 * 1.5 * 1.5));
      sg += g * sign * (f.at<float>(yy, xx) - background.at<float>(yy, xx));
      sgg += g * g;
    }
  return sgg > 0 ? sg / sgg : 0.0;
}

/// Deposits the background search did not isolate (a particle against a grain wall, a
/// pair): a moving track that ends in the interior, continued by no other track, where
/// the median background holds a particle that the reference frames before the end lack
/// and those after the end show. The particle arrived there and stayed; its track
/// continues there, at rest, to the end of the video, labelled deposited.
void joinByReference(TrackRun& run, const TrackConfig& c, const std::map<int, cv::Mat>& refs, Polarity polarity, double typical_peak) {
  auto& pts = run.tracks.points;
  if (pts.empty() || run.frame_index.empty()) return;
  const int last_frame = *std::max_element(run.frame_index.begin(), run.frame_index.end());
  const double gate_px = std::max(3.0, c.link.search_radius);
  const int gate_frames = std::max(10, 3 * (c.link.memory + 1));
  const double sign = polarity == Polarity::bright ? 1.0 : -1.0;
  const double margin = std::max(1.0, static_cast<double>(c.detect.refine_radius));
  const std::vector<Span> spans = trackSpans(pts);
  CellGrid starts(gate_px);
  for (std::size_t k = 0; k < spans.size(); ++k) starts.add(k, pts[spans[k].first].x_px, pts[spans[k].first].y_px);
  std::vector<int> frames = run.frame_index;
  std::sort(frames.begin(), frames.end());
  std::vector<TrackPoint> added;
  for (const Span& s : spans) {
    const TrackPoint& e = pts[s.last];
    if (e.state == "deposited" || e.frame + gate_frames > last_frame || s.last - s.first + 1 < static_cast<std::size_t>(c.analysis.min_points)) continue;
    if (e.x_px < margin || e.y_px < margin || e.x_px > run.background.cols - 1 - margin || e.y_px > run.background.rows - 1 - margin) continue;
    double reach = 0;
    for (std::size_t k = s.first; k <= s.last; ++k) reach = std::max(reach, std::hypot(pts[k].x - pts[s.first].x, pts[k].y - pts[s.first].y));
    if (reach < c.analysis.immobile_distance) continue;
    bool continued = false;
    starts.near(e.x_px, e.y_px, [&](std::size_t k) {
      const TrackPoint& b = pts[spans[k].first];
      continued = continued || (b.frame > e.frame && b.frame <= e.frame + gate_frames && std::hypot(b.x_px - e.x_px, b.y_px - e.y_px) <= gate_px);
    });
    if (continued) continue;
    // Where it rests: its last position, or one more step along its last velocity.
    std::vector<cv::Point2d> places = {{e.x_px, e.y_px}};
    if (s.last > s.first) places.emplace_back(2 * e.x_px - pts[s.last - 1].x_px, 2 * e.y_px - pts[s.last - 1].y_px);
    for (const cv::Point2d& q : places) {
      int before = 0, missing_before = 0, after = 0, missing_after = 0;
      for (const auto& [f, img] : refs) {
        if (f < e.frame - 1) {
          ++before;
          missing_before += spotDifference(img, run.background, q.x, q.y, sign) < -0.5 * typical_peak ? 1 : 0;
        } else if (f > e.frame + 1) {
          ++after;
          missing_after += spotDifference(img, run.background, q.x, q.y, sign) < -0.5 * typical_peak ? 1 : 0;
        }
      }
      if (before == 0 || after == 0 || missing_before * 4 < before * 3 || missing_after * 4 > after) continue;
      restUntilTheEnd(c, e, q.x, q.y, frames, added);
      ++run.deposits_by_reference;
      break;
    }
  }
  pts.insert(pts.end(), added.begin(), added.end());
  sortTracks(pts);
}

/// Particles that deposit onto particles already at rest (clusters, bridges) vanish into
/// their blob: the track ends, in the interior, at a resting place after the particle
/// there stopped, and no track begins nearby in the frames after (which a particle
/// passing over the blob would start). Such a track continues at the resting place, at
/// rest, to the end of the video, labelled deposited.
void joinClusterArrivals(TrackRun& run, const TrackConfig& c) {
  auto& pts = run.tracks.points;
  if (pts.empty() || run.frame_index.empty()) return;
  const int last_frame = *std::max_element(run.frame_index.begin(), run.frame_index.end());
  const double near = std::max(1.0, static_cast<double>(c.detect.refine_radius));
  const double gate_px = std::max(3.0, c.link.search_radius);
  const int gate_frames = std::max(10, 3 * (c.link.memory + 1));
  const std::vector<Span> spans = trackSpans(pts);
  struct Site {
    double x, y;
    std::int64_t since;
  };
  std::vector<Site> sites;  // resting places: deposited tracks from their stop, immobile ones throughout
  for (const Span& s : spans) {
    const TrackPoint& l = pts[s.last];
    if (l.state == "deposited") {
      std::size_t k = s.last;
      while (k > s.first && pts[k - 1].state == "deposited") --k;
      sites.push_back({l.x_px, l.y_px, pts[k].frame});
    } else if (s.last - s.first + 1 >= static_cast<std::size_t>(c.analysis.min_points) && l.frame == last_frame) {
      double reach = 0;
      for (std::size_t k = s.first; k <= s.last; ++k) reach = std::max(reach, std::hypot(pts[k].x - pts[s.first].x, pts[k].y - pts[s.first].y));
      if (reach < c.analysis.immobile_distance) sites.push_back({l.x_px, l.y_px, pts[s.first].frame});
    }
  }
  if (sites.empty()) return;
  CellGrid site_grid(near);
  for (std::size_t k = 0; k < sites.size(); ++k) site_grid.add(k, sites[k].x, sites[k].y);
  std::vector<std::size_t> by_start(spans.size());
  for (std::size_t k = 0; k < spans.size(); ++k) by_start[k] = k;
  std::sort(by_start.begin(), by_start.end(), [&](std::size_t a, std::size_t b) { return pts[spans[a].first].frame < pts[spans[b].first].frame; });
  std::vector<TrackPoint> added;
  std::vector<int> frames = run.frame_index;
  std::sort(frames.begin(), frames.end());
  for (const Span& s : spans) {
    const TrackPoint& e = pts[s.last];
    if (e.state == "deposited" || e.frame + gate_frames > last_frame || s.last - s.first + 1 < static_cast<std::size_t>(c.analysis.min_points)) continue;
    double reach = 0;  // a moving track: a stationary one here is the resting particle itself
    for (std::size_t k = s.first; k <= s.last; ++k) reach = std::max(reach, std::hypot(pts[k].x - pts[s.first].x, pts[k].y - pts[s.first].y));
    if (reach < c.analysis.immobile_distance) continue;
    const Site* site = nullptr;
    site_grid.near(e.x_px, e.y_px, [&](std::size_t k) {
      const Site& st = sites[k];
      const double d = std::hypot(e.x_px - st.x, e.y_px - st.y);
      if (e.frame + 1 >= st.since && d <= near && (site == nullptr || d < std::hypot(e.x_px - site->x, e.y_px - site->y))) site = &st;
    });
    if (site == nullptr) continue;
    bool continued = false;
    auto from = std::lower_bound(by_start.begin(), by_start.end(), e.frame + 1,
                                 [&](std::size_t k, std::int64_t f) { return pts[spans[k].first].frame < f; });
    for (auto it = from; it != by_start.end() && pts[spans[*it].first].frame <= e.frame + gate_frames; ++it) {
      const Span& o = spans[*it];
      const TrackPoint& b = pts[o.first];
      if (std::hypot(b.x_px - e.x_px, b.y_px - e.y_px) > gate_px) continue;
      // A track that begins there and leaves the resting place is the particle moving on;
      // one that stays is the cluster itself.
      for (std::size_t k = o.first; k <= o.last && !continued; ++k) continued = std::hypot(pts[k].x_px - site->x, pts[k].y_px - site->y) > near;
      if (continued) break;
    }
    if (continued) continue;
    restUntilTheEnd(c, e, site->x, site->y, frames, added);
    ++run.cluster_arrivals;
  }
  pts.insert(pts.end(), added.begin(), added.end());
  sortTracks(pts);
}

}  // namespace

TrackRun runTracker(FrameSource& source, const TrackConfig& c, bool quiet) {
  const auto t0 = std::chrono::steady_clock::now();
  TrackRun run;
  RollingBackground rolling;
  if (c.detect.subtract_background) {
    run.background = quantileOfFrames(sampleFrames(source, c.detect.background_samples), c.background_quantile);
    if (c.background_window > 0)
      rolling = rollingBackground(source, c.background_window, std::min(c.background_window, c.detect.background_samples), c.background_quantile);
  }
  TrackLinker linker(c.link);
  Progress progress("tracking", static_cast<std::size_t>(std::max(0, source.count())), quiet);
  Polarity polarity = c.detect.polarity;
  // From frames spread over the video, not the first alone: the first frame of a scene can
  // hold no moving particle yet, only the absence of deposits that arrive later.
  if (polarity == Polarity::automatic) polarity = guessPolarity(sampleFrames(source, 24), run.background);
  const int threads = std::max(1, c.threads);
  // Stuck-particle candidates (spots of the median background) and, per candidate, the
  // frames in which the spot is missing from the frame: there the frame is brighter (dark
  // polarity) than the background by about the spot's amplitude.
  std::vector<Detection> stuck;
  // About a dozen frames spread over the video, kept whole: where a track ends, they tell
  // whether a particle of the background was missing before and there after.
  std::map<int, cv::Mat> references;
  std::mutex reference_mutex;
  const int reference_stride = source.count() > 0 ? std::max(1, source.count() / 12) : 25;
  std::vector<std::vector<int>> absent;  // per candidate: the frames it is missing from
  std::mutex absent_mutex;
  bool stuck_ready = !(c.detect.find_stuck && !run.background.empty());
  auto prepare = [&](const cv::Mat& first) {
    if (polarity == Polarity::automatic) polarity = guessPolarity(first, run.background);
    if (!stuck_ready) {
      stuck = detectStuck(run.background, polarity, c.detect);
      absent.assign(stuck.size(), {});
      stuck_ready = true;
    }
  };
  // One frame's work (any thread): detections, and the absence test of the stuck candidates.
  auto process = [&](const cv::Mat& f, int frame_number) {
    if (c.detect.find_stuck && !run.background.empty() && frame_number % reference_stride == 0) {
      const std::lock_guard<std::mutex> lock(reference_mutex);
      if (references.size() < 24) references[frame_number] = f.clone();
    }
    if (!stuck.empty()) {
      std::vector<std::size_t> missing;
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
        if (sgg > 0 && sg / sgg < -0.5 * stuck[i].peak) missing.push_back(i);
      }
      const std::lock_guard<std::mutex> lock(absent_mutex);
      for (std::size_t i : missing) absent[i].push_back(frame_number);
    }
    return detect(f, rolling.backgrounds.empty() ? run.background : rolling.at(frame_number), polarity, c.detect);
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
    found[0] = process(frame, index);
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
          d = process(f, at);
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
        for (std::size_t k = first; k < n; k += static_cast<std::size_t>(threads)) found[k] = process(batch[k], batch_index[k]);
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
  auto point = [&](std::int64_t frame, std::int64_t particle, double x, double y) { return trackPoint(c, frame, particle, x, y); };
  for (const auto& p : linker.points()) run.tracks.points.push_back(point(p.frame, p.particle, p.x, p.y));
  double typical_peak = 0;  // median peak of the moving detections
  if (c.detect.find_stuck && !run.background.empty() && !run.frame_index.empty()) {
    // Particles at rest for most of the video are part of the median background: found
    // there, each is either stuck all along (immobile, left out as the paper does), or a
    // particle that arrived and deposited: missing from the frames before its arrival and
    // present in all after. Its moving track ends where it merged into the background, so
    // it is joined to the track that ends there then and continues, at rest, to the end.
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
    double typical = 0;
    if (!areas.empty()) {
      std::nth_element(areas.begin(), areas.begin() + areas.size() / 2, areas.end());
      typical = areas[areas.size() / 2];
      std::nth_element(peaks.begin(), peaks.begin() + peaks.size() / 2, peaks.end());
      typical_peak = peaks[peaks.size() / 2];
    }
    std::vector<int> frames = run.frame_index;
    std::sort(frames.begin(), frames.end());
    const int n = static_cast<int>(frames.size());
    const int tolerance = n / 10;  // frames the absence test may get wrong
    struct Candidate {
      const Detection* d;
      bool all_along;   // missing from at most a tenth of the frames: stuck from the start
      int arrival = -1; // deposited: first frame of the best absent-then-present split, -1: none
    };
    std::vector<Candidate> candidates;
    for (std::size_t i = 0; i < stuck.size(); ++i) {
      const Detection& d = stuck[i];
      if (typical > 0 && (d.area < 0.5 * typical || d.area > 2.0 * typical || d.peak < 0.5 * typical_peak)) continue;
      std::vector<int>& a = absent[i];
      std::sort(a.begin(), a.end());
      // Step fit: missing before frames[k], present from it on. Mismatches at split k:
      // present frames before k plus absent frames from k = k - 2 (absent before k) + |a|.
      int best_k = 0, best_err = static_cast<int>(a.size());
      std::size_t before = 0;
      for (int k = 1; k <= n; ++k) {
        while (before < a.size() && a[before] <= frames[k - 1]) ++before;
        const int err = k - 2 * static_cast<int>(before) + static_cast<int>(a.size());
        if (err < best_err) {
          best_err = err;
          best_k = k;
        }
      }
      Candidate cand{&d, static_cast<int>(a.size()) <= tolerance, -1};
      if (best_k > 0 && best_k < n && best_err <= tolerance) cand.arrival = frames[best_k];
      // A particle that only lingers (stationary for most, not all, of the video) also
      // shows in the median; it is missing from the frames where it was elsewhere.
      if (cand.all_along || cand.arrival >= 0) candidates.push_back(cand);
    }
    // Track ends that can be joined: the track's last point, a few pixels from the
    // particle's resting place, within a few frames of its arrival there.
    std::map<std::int64_t, const TrackPoint*> last;
    for (const auto& p : run.tracks.points) {
      auto& l = last[p.particle];
      if (l == nullptr || p.frame > l->frame) l = &p;
    }
    const double gate_px = std::max(3.0, c.link.search_radius);
    const int gate_frames = std::max(10, 3 * (c.link.memory + 1));
    struct Join {
      double cost;
      std::size_t candidate;
      const TrackPoint* end;
    };
    std::vector<Join> joins;
    std::vector<const TrackPoint*> ends;
    CellGrid end_grid(gate_px);
    for (const auto& [id, end] : last) {
      end_grid.add(ends.size(), end->x_px, end->y_px);
      ends.push_back(end);
    }
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      if (candidates[k].arrival < 0) continue;
      end_grid.near(candidates[k].d->x, candidates[k].d->y, [&](std::size_t e) {
        const TrackPoint* end = ends[e];
        const double dist = std::hypot(end->x_px - candidates[k].d->x, end->y_px - candidates[k].d->y);
        const auto lag = std::abs(end->frame + 1 - candidates[k].arrival);
        if (dist <= gate_px && lag <= gate_frames) joins.push_back({dist / gate_px + static_cast<double>(lag) / gate_frames, k, end});
      });
    }
    std::sort(joins.begin(), joins.end(), [](const Join& a, const Join& b) { return a.cost < b.cost; });
    std::vector<char> joined(candidates.size(), 0);
    std::map<std::int64_t, char> used;
    std::vector<TrackPoint> rest;
    // A particle half merged into the median background (at rest for about half the
    // video) still leaves faint detections at its resting place after it arrived: they
    // are the deposited particle, labelled so on its own track, and other tracks made
    // only of them are duplicates of it and dropped.
    const double near = std::max(1.0, static_cast<double>(c.detect.refine_radius));
    std::map<std::int64_t, std::pair<std::size_t, int>> deposit_of;  // track -> (candidate, arrival)
    for (const Join& j : joins) {
      if (joined[j.candidate] || used[j.end->particle]) continue;
      joined[j.candidate] = used[j.end->particle] = 1;
      const Detection& d = *candidates[j.candidate].d;
      restUntilTheEnd(c, *j.end, d.x, d.y, frames, rest);
      deposit_of[j.end->particle] = {j.candidate, candidates[j.candidate].arrival};
      ++run.deposits_joined;
    }
    if (!deposit_of.empty()) {
      std::vector<std::pair<std::int64_t, std::pair<std::size_t, int>>> deposits(deposit_of.begin(), deposit_of.end());
      CellGrid deposit_grid(near);
      for (std::size_t k = 0; k < deposits.size(); ++k)
        deposit_grid.add(k, candidates[deposits[k].second.first].d->x, candidates[deposits[k].second.first].d->y);
      std::map<std::int64_t, char> duplicate;  // 1 while every point so far sits at a deposit after its arrival
      for (auto& p : run.tracks.points) {
        bool at_deposit = false;
        deposit_grid.near(p.x_px, p.y_px, [&](std::size_t k) {
          const auto& [track, ca] = deposits[k];
          const Detection& d = *candidates[ca.first].d;
          if (p.frame < ca.second || std::hypot(p.x_px - d.x, p.y_px - d.y) > near) return;
          at_deposit = true;
          if (track == p.particle) p.state = "deposited";
        });
        const auto it = duplicate.find(p.particle);
        const char keep = deposit_of.count(p.particle) == 0 && at_deposit ? 1 : 0;
        duplicate[p.particle] = it == duplicate.end() ? keep : static_cast<char>(it->second & keep);
      }
      std::erase_if(run.tracks.points, [&](const TrackPoint& p) { return duplicate[p.particle] != 0; });
      // The joined track's own labelled points must be its trailing ones: a label followed
      // by an unlabelled point (it moved again) is removed.
      std::map<std::int64_t, std::int64_t> last_unlabelled;
      for (const auto& p : run.tracks.points)
        if (deposit_of.count(p.particle) && p.state != "deposited") last_unlabelled[p.particle] = std::max(last_unlabelled[p.particle], p.frame);
      for (auto& p : run.tracks.points)
        if (deposit_of.count(p.particle) && p.state == "deposited" && last_unlabelled.count(p.particle) && p.frame < last_unlabelled[p.particle])
          p.state.clear();
    }
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      if (joined[k]) continue;
      if (!candidates[k].all_along) {
        ++run.deposits_unjoined;  // arrived, but no track brought it: left out
        continue;
      }
      for (int f : frames) rest.push_back(point(f, next_id, candidates[k].d->x, candidates[k].d->y));
      ++next_id;
      ++run.stuck_found;
    }
    run.tracks.points.insert(run.tracks.points.end(), rest.begin(), rest.end());
  }
  sortTracks(run.tracks.points);
  // Particles seen to stop (at rest over the final window) are labelled deposited from
  // where they stopped, so their resting positions stay out of velocity statistics.
  markDeposits(run.tracks, c.analysis);
  if (!references.empty() && typical_peak > 0) {
    joinByReference(run, c, references, polarity, typical_peak);
    markDeposits(run.tracks, c.analysis);
  }
  joinClusterArrivals(run, c);
  run.smoothed_points = smoothTracks(run.tracks, c.smooth_frames, c.pixel_size).points;
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
  ret += fmt::format("particles,{}\nimmobile,{}\nmobile,{}\nentered,{}\nretained,{}\nretained_fraction,{:.5g}\n", s.particles, s.immobile, s.mobile,
                     s.entered, s.retained, s.retained_fraction);
  put("retention.csv", ret);
  {
    // Deposited over time: a deposited particle counts from the time it stopped for good.
    std::vector<double> stop_times;
    for (const auto& t : s.tracks)
      if (t.state == "deposited" && std::isfinite(t.stop_time)) stop_times.push_back(t.stop_time);
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
    const auto png = [&](const std::string& name, const cv::Mat& m) {
      const auto t = temporaryPathFor(dir / name);
      cv::imwrite(t.string(), m);
      commitTemporary(t, dir / name);
      files.push_back(name);
    };
    png("streamlines.png", img);
    // Steps coloured by speed, and the mean speed binned on the pore space (bins of
    // about two particle diameters).
    png("velocity_overlay.png", velocityOverlay(base, s, c.pixel_size, 1.0 / c.fps));
    png("speed_map.png", speedMap(base, s, c.pixel_size, std::max(4, 2 * c.detect.refine_radius)));
  }
  nlohmann::json summary = extra;
  summary["frames"] = run.frame_index.size();
  summary["tracks"] = s.particles;
  summary["immobile"] = s.immobile;
  summary["retained"] = s.retained;
  summary["entered"] = s.entered;
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

}  // namespace mmval::tracking
