#include "mmval/tracking/Pipeline.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <exception>
#include <map>
#include <mutex>
#include <optional>
#include <thread>
#include <unordered_map>

#include <fmt/format.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "PipelineDetail.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/tracking/Background.hpp"
#include "mmval/tracking/LargeDiscs.hpp"
#include "mmval/tracking/SceneDecisions.hpp"
#include "mmval/tracking/TrackSmooth.hpp"

namespace mmval::tracking {

using namespace detail;

namespace {

/// analysis.motion as set, or decided from the linked tracks when "auto"; Brownian with
/// link.predict automatic links the stored detections again without prediction (a
/// linker pass costs a small part of the detection).
MotionDecision chooseMotion(const TrackConfig& c, std::vector<LinkedPoint>& linked, TrackRun& run) {
  MotionDecision m;
  m.requested = m.model = c.analysis.motion;
  if (c.analysis.motion != MotionModel::automatic) {
    m.reason = fmt::format("analysis.motion = \"{}\"", motionModelName(c.analysis.motion));
    return m;
  }
  Tracks raw;
  for (const auto& p : linked) raw.points.push_back(trackPoint(c, p.frame, p.particle, p.x, p.y));
  m = decideMotion(raw);
  if (m.model == MotionModel::brownian && c.link.predict == Prediction::automatic) {
    LinkOptions none = c.link;
    none.predict = Prediction::none;
    TrackLinker again(none);
    for (std::size_t k = 0; k < run.detections.size(); ++k) again.push(run.frame_index[k], run.detections[k]);
    linked = again.points();
    run.link = again.stats();
    m.relinked = true;
  }
  return m;
}

/// OpenCV's own thread pool held to `threads` while it lives, restored after: while our
/// workers each detect a frame, each worker's OpenCV calls (blur, subtract) would
/// otherwise fan out over every core again (oversubscription on a machine with few cores).
class OpenCvThreads {
 public:
  explicit OpenCvThreads(int threads) : m_before(cv::getNumThreads()) { cv::setNumThreads(threads); }
  ~OpenCvThreads() { cv::setNumThreads(m_before); }
  OpenCvThreads(const OpenCvThreads&) = delete;
  OpenCvThreads& operator=(const OpenCvThreads&) = delete;

 private:
  int m_before;
};

/// Frames the polarity and ring guesses sample, spread over the video.
constexpr int kPolaritySamples = 24;
/// Large discs: radii searched, as multiples of detect.refine_radius (the real discs video
/// has radii ~40-60 px, +-20 % about its middle; 0.7-1.3 also allows a size given roughly).
constexpr double kDiscRadiusLow = 0.7, kDiscRadiusHigh = 1.3;

/// detect.background: as set, or decided from `frames`, those sampled for the median.
BackgroundDecision chooseBackground(const std::vector<cv::Mat>& frames, const TrackConfig& c, Polarity polarity, const DetectOptions& options, const cv::Mat& median) {
  BackgroundDecision d;
  d.requested = c.detect.subtract_background ? backgroundModeName(c.detect.background_mode) : "none";
  if (!c.detect.subtract_background || c.detect.background_mode == BackgroundMode::none) {
    d.subtract = false;
    d.reason = c.detect.subtract_background ? "detect.background = \"none\"" : "detect.subtract_background = false";
    return d;
  }
  if (c.detect.background_mode == BackgroundMode::median) {
    d.reason = "detect.background = \"median\"";
    return d;
  }
  if (c.detect.polarity == Polarity::automatic && polarity != Polarity::ring) {
    // The polarity guess leans on the median, which is what is in question: judged on the
    // side that shows more spots against a spatial high-pass (the particles).
    const BackgroundDecision dark = decideBackground(frames, median, Polarity::dark, options);
    const BackgroundDecision bright = decideBackground(frames, median, Polarity::bright, options);
    d = dark.spots_per_frame >= bright.spots_per_frame ? dark : bright;
  } else {
    d = decideBackground(frames, median, polarity, options);
  }
  d.requested = "auto";
  return d;
}

}  // namespace

TrackRun runTracker(FrameSource& source, const TrackConfig& c, bool quiet) {
  const auto t0 = std::chrono::steady_clock::now();
  TrackRun run;
  auto lap_start = t0;
  auto lap = [&](const char* stage) {
    const auto now = std::chrono::steady_clock::now();
    run.stage_seconds.emplace_back(stage, std::chrono::duration<double>(now - lap_start).count());
    lap_start = now;
  };
  RollingBackground rolling;
  // threads 0: every core (the decoding and detection of frames are independent).
  const int threads = c.threads > 0 ? c.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  // A disc-centroid size of kMinDiscRadiusPx or more (--diameter 41 and up): large discs,
  // found whole by their rims (LargeDiscs.hpp) on the frame itself, radii 0.7-1.3 x it. That
  // path needs no background, ring or polarity guess, so none of their frames is sampled.
  const bool large_discs = c.detect.refinement == Refinement::disc && c.detect.refine_radius >= kMinDiscRadiusPx;
  const bool background_wanted = !large_discs && c.detect.subtract_background && c.detect.background_mode != BackgroundMode::none;
  const bool sample_polarity = !large_discs && (c.detect.polarity == Polarity::automatic || c.detect.polarity == Polarity::ring);
  {
    // Every frame is decoded once: the samplers below read only the frames they keep,
    // in one forward pass (videos), into the source's cache, which the main pass reads.
    std::vector<int> sampled;
    if (background_wanted) {
      sampled = samplePositions(source.count(), c.detect.background_samples);
      if (c.background_window > 0)
        for (const auto& block : rollingSamplePositions(source.count(), c.background_window, std::min(c.background_window, c.detect.background_samples)))
          sampled.insert(sampled.end(), block.begin(), block.end());
    }
    if (sample_polarity) {
      const std::vector<int> more = samplePositions(source.count(), kPolaritySamples);
      sampled.insert(sampled.end(), more.begin(), more.end());
    }
    source.prefetch(sampled, threads);
  }
  lap("sampling");
  // The frames of the median, kept for the background decision below (read once).
  std::vector<cv::Mat> background_frames;
  if (background_wanted) {
    background_frames = sampleFrames(source, c.detect.background_samples);
    run.background = quantileOfFrames(background_frames, c.background_quantile);
    if (c.background_window > 0)
      rolling = rollingBackground(source, c.background_window, std::min(c.background_window, c.detect.background_samples), c.background_quantile);
  }
  lap("background");
  // Brownian steps are uncorrelated: linked without prediction when the motion is known
  // to be Brownian; with "auto" the tracks decide after linking (below).
  LinkOptions link_options = c.link;
  if (c.analysis.motion == MotionModel::brownian && link_options.predict == Prediction::automatic) link_options.predict = Prediction::none;
  TrackLinker linker(link_options);
  Progress progress("tracking", static_cast<std::size_t>(std::max(0, source.count())), quiet);
  DetectOptions options = c.detect;  // with what the video decides: ring filter, spatial high-pass
  const Polarity polarity_in = c.detect.polarity;
  Polarity polarity = polarity_in;
  const std::vector<cv::Mat> polarity_frames = sample_polarity ? sampleFrames(source, kPolaritySamples) : std::vector<cv::Mat>{};
  if (sample_polarity) run.ring = guessRings(polarity_frames);
  lap("rings");
  if (large_discs) {
    polarity = Polarity::bright;
    run.polarity_reason = fmt::format("large discs: detect.refinement = \"disc\" with detect.refine_radius = {} px (>= {} px, e.g. --diameter {}): "
                                      "each disc found once, at the centre of a circle fitted to its bright rim, radii {:.0f}-{:.0f} px",
                                      c.detect.refine_radius, kMinDiscRadiusPx, 2 * c.detect.refine_radius + 1, kDiscRadiusLow * c.detect.refine_radius,
                                      kDiscRadiusHigh * c.detect.refine_radius);
  } else if (polarity == Polarity::automatic) {
    // From frames spread over the video, not the first alone: the first frame of a scene can
    // hold no moving particle yet, only the absence of deposits that arrive later.
    if (run.ring.rings) {
      polarity = Polarity::ring;
      run.polarity_reason = run.ring.reason;
    } else {
      polarity = guessPolarity(polarity_frames, run.background);
      run.polarity_reason = fmt::format("{}; the side (darker or brighter than the background) with more moving foreground", run.ring.reason);
    }
  } else {
    run.polarity_reason = fmt::format("detect.polarity = \"{}\"", polarityName(polarity));
  }
  if (polarity == Polarity::ring) {
    options.ring_radius_px = run.ring.rings ? run.ring.radius_px : static_cast<double>(c.detect.refine_radius);
    options.ring_kernel = ringKernel(run.ring.rings ? run.ring.profile : std::vector<float>{}, options.ring_radius_px);
  }
  lap("polarity");
  if (large_discs) {
    run.background_decision.requested = c.detect.subtract_background ? backgroundModeName(c.detect.background_mode) : "none";
    run.background_decision.subtract = false;
    run.background_decision.reason = "large discs are detected on the frame itself (a still disc is its own median)";
  } else {
    run.background_decision = chooseBackground(background_frames, c, polarity, options, run.background);
  }
  background_frames.clear();
  if (!run.background_decision.subtract) {
    run.background.release();
    rolling = RollingBackground{};
    // Without a temporal background the polarity is judged within each frame (a temporal
    // median of still particles is the particles, and the foreground against it noise).
    if (polarity_in == Polarity::automatic && polarity != Polarity::ring && !large_discs) {
      polarity = guessPolaritySpatial(polarity_frames);
      run.polarity_reason += fmt::format("; with no background subtracted: {} (more band-passed excess on that side)", polarityName(polarity));
    }
    // Decided from the video: a spatial high-pass of the particle's radius (trackpy's band
    // pass) evens the illumination instead.
    if (background_wanted && options.local_background == 0 && polarity != Polarity::ring) options.local_background = std::max(2, options.refine_radius);
  }
  lap("decisions");
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
      stuck = detectStuck(run.background, polarity, options);
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
      const double sign = polarity == Polarity::dark ? -1.0 : 1.0;
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
    if (large_discs) return detectDiscs(f, kDiscRadiusLow * options.refine_radius, kDiscRadiusHigh * options.refine_radius);
    return detect(f, rolling.backgrounds.empty() ? run.background : rolling.at(frame_number), polarity, options);
  };
  auto link = [&](int index, std::vector<Detection>&& found) {
    linker.push(index, found);
    run.detections.push_back(std::move(found));
    run.frame_index.push_back(index);
    progress.advance();
  };
  cv::Mat frame;
  int index = 0;
  // One OpenCV thread per worker of ours (the workers are the parallelism); one worker
  // keeps OpenCV's pool.
  std::optional<OpenCvThreads> opencv_threads;
  if (threads > 1) opencv_threads.emplace(1);
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
  opencv_threads.reset();
  lap("frames");
  run.polarity = polarity;
  run.link = linker.stats();
  auto point = [&](std::int64_t frame, std::int64_t particle, double x, double y) { return trackPoint(c, frame, particle, x, y); };
  std::vector<LinkedPoint> linked = linker.points();
  run.motion = chooseMotion(c, linked, run);
  const bool flow = run.motion.model == MotionModel::flow;
  std::int64_t next_id = 0;
  for (const auto& p : linked) next_id = std::max(next_id, p.particle + 1);
  for (const auto& p : linked) {
    run.tracks.points.push_back(point(p.frame, p.particle, p.x, p.y));
    run.tracks.points.back().quality = p.detection.quality;  // the spot's quality columns of tracks.csv
  }
  double typical_peak = 0;  // median peak of the moving detections
  if (flow && c.detect.find_stuck && !run.background.empty() && !run.frame_index.empty()) {
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
  if (flow) {
    // Particles seen to stop (at rest over the final window) are labelled deposited from
    // where they stopped, so their resting positions stay out of velocity statistics.
    markDeposits(run.tracks, c.analysis);
    if (!references.empty() && typical_peak > 0) {
      joinByReference(run, c, references, polarity, typical_peak);
      markDeposits(run.tracks, c.analysis);
    }
    joinClusterArrivals(run, c);
  }
  lap("joins");
  run.smoothed_points = smoothTracks(run.tracks, c.smooth_frames, c.pixel_size).points;
  if (!flow) run.brownian = analyseBrownian(run.tracks, c.analysis.brownian);
  lap("analysis");
  run.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return run;
}

}  // namespace mmval::tracking
