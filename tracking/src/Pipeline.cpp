#include "mmval/tracking/Pipeline.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <ctime>
#include <condition_variable>
#include <exception>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>
#include <unordered_map>

#include <fmt/format.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "PipelineDetail.hpp"
#include "TrackerTuning.hpp"
#include "mmval/core/Progress.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/tracking/Background.hpp"
#include "mmval/tracking/LargeDiscs.hpp"
#include "mmval/tracking/SceneDecisions.hpp"
#include "mmval/tracking/TrackSmooth.hpp"

namespace mmval::tracking {

using namespace detail;

namespace {

constexpr const PipelineTuning& kTune = kPipelineTuning;

/// Wall and CPU time of runTracker's stages (TrackRun::stage_seconds, stage_cpu_seconds)
/// and the wall time of the whole run.
class StageClock {
 public:
  StageClock() : m_start(std::chrono::steady_clock::now()), m_lap(m_start), m_cpu_lap(processCpuSeconds()) {}
  void lap(TrackRun& run, const char* stage) {
    const auto now = std::chrono::steady_clock::now();
    const double cpu = processCpuSeconds();
    run.stage_seconds.emplace_back(stage, std::chrono::duration<double>(now - m_lap).count());
    run.stage_cpu_seconds.emplace_back(stage, cpu - m_cpu_lap);
    m_lap = now;
    m_cpu_lap = cpu;
  }
  double total() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - m_start).count(); }

 private:
  std::chrono::steady_clock::time_point m_start, m_lap;
  double m_cpu_lap;
};

// ---- Stage 1: which frames the decisions sample -----------------------------------------

/// What the configuration decides before any frame is read.
struct FramePlan {
  int threads = 1;                 ///< workers decoding and detecting frames
  bool large_discs = false;        ///< discs found whole by their rims on the frame itself (LargeDiscs.hpp)
  bool background_wanted = false;  ///< a temporal background may be subtracted: its frames are sampled
  bool sample_polarity = false;    ///< the polarity and ring guesses sample frames
};

FramePlan planFrames(const TrackConfig& c) {
  FramePlan p;
  // threads 0: every core (the decoding and detection of frames are independent).
  p.threads = c.threads > 0 ? c.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  // A disc-centroid size of kMinDiscRadiusPx or more (--diameter 41 and up): large discs,
  // found whole by their rims (LargeDiscs.hpp) on the frame itself, radii 0.7-1.3 x it. That
  // path needs no background, ring or polarity guess, so none of their frames is sampled.
  p.large_discs = c.detect.refinement == Refinement::disc && c.detect.refine_radius >= kMinDiscRadiusPx;
  p.background_wanted = !p.large_discs && c.detect.subtract_background && c.detect.background_mode != BackgroundMode::none;
  p.sample_polarity = !p.large_discs && (c.detect.polarity == Polarity::automatic || c.detect.polarity == Polarity::ring);
  return p;
}

/// Every frame is decoded once: the samplers read only the frames they keep, in one
/// forward pass (videos), into the source's cache, which the main pass reads.
void prefetchSamples(FrameSource& source, const TrackConfig& c, const FramePlan& plan) {
  std::vector<int> sampled;
  if (plan.background_wanted) {
    sampled = samplePositions(source.count(), c.detect.background_samples);
    if (c.background_window > 0)
      for (const auto& block : rollingSamplePositions(source.count(), c.background_window, std::min(c.background_window, c.detect.background_samples)))
        sampled.insert(sampled.end(), block.begin(), block.end());
  }
  if (plan.sample_polarity) {
    const std::vector<int> more = samplePositions(source.count(), kTune.polarity_samples);
    sampled.insert(sampled.end(), more.begin(), more.end());
  }
  source.prefetch(sampled, plan.threads);
}

// ---- Stage 2: the temporal background ---------------------------------------------------

struct SampledBackground {
  std::vector<cv::Mat> frames;  ///< the median's frames, kept for the background decision (read once)
  cv::Mat median;               ///< their per-pixel quantile (c.background_quantile)
  RollingBackground rolling;    ///< per block of c.background_window frames, when set
};

SampledBackground sampleBackground(FrameSource& source, const TrackConfig& c, const FramePlan& plan) {
  SampledBackground b;
  if (!plan.background_wanted) return b;
  b.frames = sampleFrames(source, c.detect.background_samples);
  b.median = quantileOfFrames(b.frames, c.background_quantile);
  if (c.background_window > 0)
    b.rolling = rollingBackground(source, c.background_window, std::min(c.background_window, c.detect.background_samples), c.background_quantile);
  return b;
}

/// Brownian steps are uncorrelated: linked without prediction when the motion is known
/// to be Brownian; with "auto" the tracks decide after linking (chooseMotion).
LinkOptions linkOptions(const TrackConfig& c) {
  LinkOptions o = c.link;
  if (c.analysis.motion == MotionModel::brownian && o.predict == Prediction::automatic) o.predict = Prediction::none;
  return o;
}

// ---- Stages 3-5: polarity and background decisions ---------------------------------------

/// What each frame's detection is given: the polarity and the options with what the
/// video decides (ring filter, spatial high-pass).
struct DetectionSetup {
  Polarity polarity = Polarity::automatic;
  std::string reason;  ///< why this polarity (TrackRun::polarity_reason)
  DetectOptions options;
};

/// detect.polarity as set, or guessed from `frames` (spread over the video, not the first
/// alone: the first frame of a scene can hold no moving particle yet, only the absence of
/// deposits that arrive later); ring colloids get their matched filter.
DetectionSetup choosePolarity(const TrackConfig& c, const FramePlan& plan, const RingGuess& ring, const std::vector<cv::Mat>& frames, const cv::Mat& median) {
  DetectionSetup s;
  s.options = c.detect;
  s.polarity = c.detect.polarity;
  if (plan.large_discs) {
    s.polarity = Polarity::bright;
    s.reason = fmt::format("large discs: detect.refinement = \"disc\" with detect.refine_radius = {} px (>= {} px, e.g. --diameter {}): "
                           "each disc found once, at the centre of a circle fitted to its bright rim, radii {:.0f}-{:.0f} px",
                           c.detect.refine_radius, kMinDiscRadiusPx, 2 * c.detect.refine_radius + 1, kTune.disc_radius_low * c.detect.refine_radius,
                           kTune.disc_radius_high * c.detect.refine_radius);
  } else if (s.polarity == Polarity::automatic) {
    if (ring.rings) {
      s.polarity = Polarity::ring;
      s.reason = ring.reason;
    } else {
      s.polarity = guessPolarity(frames, median);
      s.reason = fmt::format("{}; the side (darker or brighter than the background) with more moving foreground", ring.reason);
    }
  } else {
    s.reason = fmt::format("detect.polarity = \"{}\"", polarityName(s.polarity));
  }
  if (s.polarity == Polarity::ring) {
    s.options.ring_radius_px = ring.rings ? ring.radius_px : static_cast<double>(c.detect.refine_radius);
    s.options.ring_kernel = ringKernel(ring.rings ? ring.profile : std::vector<float>{}, s.options.ring_radius_px);
  }
  return s;
}

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
    d = decideBackground(frames, median, Polarity::automatic, options);
  } else {
    d = decideBackground(frames, median, polarity, options);
  }
  d.requested = "auto";
  return d;
}

/// Whether the temporal background is subtracted (large discs: never), and what follows
/// when it is not: the median and the rolling background are dropped from `background`,
/// a guessed polarity is judged within each frame instead, and a spatial high-pass evens
/// the illumination. The sampled frames are released.
BackgroundDecision settleBackground(const TrackConfig& c, const FramePlan& plan, const std::vector<cv::Mat>& polarity_frames, SampledBackground& background,
                                    DetectionSetup& setup) {
  BackgroundDecision d;
  if (plan.large_discs) {
    d.requested = c.detect.subtract_background ? backgroundModeName(c.detect.background_mode) : "none";
    d.subtract = false;
    d.reason = "large discs are detected on the frame itself (a still disc is its own median)";
  } else {
    d = chooseBackground(background.frames, c, setup.polarity, setup.options, background.median);
  }
  background.frames.clear();
  if (!d.subtract) {
    background.median.release();
    background.rolling = RollingBackground{};
    // Without a temporal background the polarity is judged within each frame (a temporal
    // median of still particles is the particles, and the foreground against it noise).
    if (c.detect.polarity == Polarity::automatic && setup.polarity != Polarity::ring && !plan.large_discs) {
      setup.polarity = guessPolaritySpatial(polarity_frames);
      setup.reason += fmt::format("; with no background subtracted: {} (more band-passed excess on that side)", polarityName(setup.polarity));
    }
    // Decided from the video: a spatial high-pass of the particle's radius (trackpy's band
    // pass) evens the illumination instead.
    if (plan.background_wanted && setup.options.local_background == 0 && setup.polarity != Polarity::ring)
      setup.options.local_background = std::max(2, setup.options.refine_radius);
  }
  return d;
}

// ---- Stage 6: detection over the frames, linked in order ---------------------------------

/// What the pass over the frames leaves beside the linked detections, for the joins of
/// stuck and deposited particles: the stuck-particle candidates (spots of the median
/// background), per candidate the frames it is missing from (there the frame is brighter,
/// for dark polarity, than the background by about the spot's amplitude), and about a
/// dozen frames spread over the video kept whole (where a track ends, they tell whether a
/// particle of the background was missing before and there after).
struct StuckEvidence {
  std::vector<Detection> stuck;
  std::vector<std::vector<int>> absent;
  std::map<int, cv::Mat> references;
};

/// One frame's work, callable from any thread once prepare() has seen the first frame:
/// its detections, and the absence test of the stuck candidates.
class FrameDetector {
 public:
  FrameDetector(const TrackConfig& c, const FramePlan& plan, const cv::Mat& background, const RollingBackground& rolling, DetectionSetup& setup,
                int frame_count)
      : m_c(c),
        m_plan(plan),
        m_background(background),
        m_rolling(rolling),
        m_setup(setup),
        m_reference_stride(frame_count > 0 ? std::max(1, frame_count / kTune.reference_spacing) : kTune.reference_stride_unknown),
        m_stuck_ready(!(c.detect.find_stuck && !background.empty())) {}

  /// Fixes what the first frame decides: a polarity still open, and the stuck candidates.
  void prepare(const cv::Mat& first) {
    if (m_setup.polarity == Polarity::automatic) m_setup.polarity = guessPolarity(first, m_background);
    if (!m_stuck_ready) {
      m_evidence.stuck = detectStuck(m_background, m_setup.polarity, m_setup.options);
      m_evidence.absent.assign(m_evidence.stuck.size(), {});
      m_stuck_ready = true;
    }
  }

  std::vector<Detection> operator()(const cv::Mat& f, int frame_number) {
    if (m_c.detect.find_stuck && !m_background.empty() && frame_number % m_reference_stride == 0) {
      const std::lock_guard<std::mutex> lock(m_reference_mutex);
      if (m_evidence.references.size() < kTune.max_references) m_evidence.references[frame_number] = f.clone();
    }
    if (!m_evidence.stuck.empty()) {
      std::vector<std::size_t> missing;
      // Dark particles: (background - frame), ~0 while the particle is there, about minus
      // its amplitude once it has gone.
      const double sign = m_setup.polarity == Polarity::dark ? -1.0 : 1.0;
      for (std::size_t i = 0; i < m_evidence.stuck.size(); ++i) {
        const Detection& s = m_evidence.stuck[i];
        if (spotDifference(f, m_background, s.x, s.y, sign) < -kTune.missing_fraction * s.peak) missing.push_back(i);
      }
      const std::lock_guard<std::mutex> lock(m_absent_mutex);
      for (std::size_t i : missing) m_evidence.absent[i].push_back(frame_number);
    }
    if (m_plan.large_discs)
      return detectDiscs(f, kTune.disc_radius_low * m_setup.options.refine_radius, kTune.disc_radius_high * m_setup.options.refine_radius);
    return detect(f, m_rolling.backgrounds.empty() ? m_background : m_rolling.at(frame_number), m_setup.polarity, m_setup.options);
  }

  StuckEvidence take() { return std::move(m_evidence); }

 private:
  const TrackConfig& m_c;
  const FramePlan& m_plan;
  const cv::Mat& m_background;
  const RollingBackground& m_rolling;
  DetectionSetup& m_setup;
  const int m_reference_stride;
  bool m_stuck_ready;
  StuckEvidence m_evidence;
  std::mutex m_reference_mutex, m_absent_mutex;
};

/// The linkers of the pass over the frames: `linker` as configured, and, while the motion
/// model is still open (analysis.motion "auto" with link.predict automatic), `unpredicted`,
/// the same detections linked without prediction, which chooseMotion takes if the tracks
/// turn out Brownian (linked here, in the linking thread, while the workers detect, instead
/// of in a second pass after them).
struct FrameLinkers {
  TrackLinker& linker;
  std::optional<TrackLinker> unpredicted;
};

FrameLinkers frameLinkers(TrackLinker& linker, const TrackConfig& c) {
  FrameLinkers l{linker, std::nullopt};
  if (c.analysis.motion == MotionModel::automatic && c.link.predict == Prediction::automatic) {
    LinkOptions none = c.link;
    none.predict = Prediction::none;
    l.unpredicted.emplace(none);
  }
  return l;
}

/// Takes each frame's detections in frame order: linked, and kept (run.detections,
/// run.frame_index).
class InOrderLinker {
 public:
  InOrderLinker(FrameLinkers& linkers, TrackRun& run, Progress& progress) : m_linkers(linkers), m_run(run), m_progress(progress) {}
  void operator()(int index, std::vector<Detection>&& found) {
    m_linkers.linker.push(index, found);
    if (m_linkers.unpredicted) m_linkers.unpredicted->push(index, found);
    m_run.detections.push_back(std::move(found));
    m_run.frame_index.push_back(index);
    m_progress.advance();
  }

 private:
  FrameLinkers& m_linkers;
  TrackRun& m_run;
  Progress& m_progress;
};

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

/// Image files: `threads` workers each read (decode) and detect whole frames, taking the
/// next frame number from a shared counter; this thread links them in order as they
/// complete. The first frame, `frame` (`index`), already read, fixes polarity, size and
/// 16-bit range.
void detectFilesInParallel(FrameSource& source, int threads, const cv::Mat& frame, int index, FrameDetector& detector, InOrderLinker& link) {
  detector.prepare(frame);
  const int n = source.count();
  std::vector<std::vector<Detection>> found(static_cast<std::size_t>(n));
  std::vector<int> frame_of(static_cast<std::size_t>(n), 0);
  std::vector<char> done(static_cast<std::size_t>(n), 0);
  std::vector<std::exception_ptr> failed(static_cast<std::size_t>(n));
  std::mutex m;
  std::condition_variable ready;
  std::atomic<int> next_pos{1};
  std::atomic<bool> stop{false};
  auto worker = [&] {
    cv::Mat f;
    for (int pos; !stop && (pos = next_pos++) < n;) {
      std::exception_ptr error;
      std::vector<Detection> d;
      int at = 0;
      try {
        source.readAt(pos, f, at);
        d = detector(f, at);
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
  // The first frame here while the workers start on the next ones (not before them).
  std::exception_ptr error;
  try {
    std::vector<Detection> d = detector(frame, index);
    const std::lock_guard<std::mutex> lock(m);
    found[0] = std::move(d);
    frame_of[0] = index;
    done[0] = 1;
  } catch (...) {
    error = std::current_exception();
  }
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
}

/// In order (videos, TIFF stacks, one thread): batches of 2 x threads frames are read
/// here, detected in parallel, then linked in frame order.
void detectInOrder(FrameSource& source, int threads, FrameDetector& detector, InOrderLinker& link) {
  std::vector<cv::Mat> batch(static_cast<std::size_t>(2 * threads));
  std::vector<int> batch_index(batch.size());
  std::vector<std::vector<Detection>> found(batch.size());
  for (bool more = true; more;) {
    std::size_t n = 0;
    while (n < batch.size() && (more = source.next(batch[n], batch_index[n]))) ++n;
    if (n == 0) break;
    detector.prepare(batch[0]);
    auto work = [&](std::size_t first) {
      for (std::size_t k = first; k < n; k += static_cast<std::size_t>(threads)) found[k] = detector(batch[k], batch_index[k]);
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

/// Detects every frame and links the detections in frame order (into `linker`,
/// run.detections, run.frame_index); returns the evidence for the stuck-particle joins.
/// setup.polarity is final afterwards.
StuckEvidence detectFrames(FrameSource& source, const TrackConfig& c, const FramePlan& plan, const cv::Mat& background, const RollingBackground& rolling,
                           DetectionSetup& setup, FrameLinkers& linkers, Progress& progress, TrackRun& run) {
  FrameDetector detector(c, plan, background, rolling, setup, source.count());
  InOrderLinker link(linkers, run, progress);
  cv::Mat frame;
  int index = 0;
  // One OpenCV thread per worker of ours (the workers are the parallelism); one worker
  // keeps OpenCV's pool.
  std::optional<OpenCvThreads> opencv_threads;
  if (plan.threads > 1) opencv_threads.emplace(1);
  if (plan.threads > 1 && source.randomAccess() && source.next(frame, index))
    detectFilesInParallel(source, plan.threads, frame, index, detector, link);
  else
    detectInOrder(source, plan.threads, detector, link);
  progress.finish();
  opencv_threads.reset();
  return detector.take();
}

// ---- Stage 7: motion model, stuck and deposited particles --------------------------------

/// analysis.motion as set, or decided from the linked tracks when "auto"; Brownian with
/// link.predict automatic takes the detections linked without prediction (`unpredicted`,
/// linked during the pass over the frames; linked here if absent).
MotionDecision chooseMotion(const TrackConfig& c, std::vector<LinkedPoint>& linked, std::optional<TrackLinker>& unpredicted, TrackRun& run) {
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
    if (!unpredicted) {
      LinkOptions none = c.link;
      none.predict = Prediction::none;
      unpredicted.emplace(none);
      for (std::size_t k = 0; k < run.detections.size(); ++k) unpredicted->push(run.frame_index[k], run.detections[k]);
    }
    linked = unpredicted->points();
    run.link = unpredicted->stats();
    m.relinked = true;
  }
  return m;
}

/// The linked points as tracks (px and m), with each spot's quality columns.
std::vector<TrackPoint> trackPoints(const TrackConfig& c, const std::vector<LinkedPoint>& linked) {
  std::vector<TrackPoint> points;
  for (const auto& p : linked) {
    points.push_back(trackPoint(c, p.frame, p.particle, p.x, p.y));
    points.back().quality = p.detection.quality;  // the spot's quality columns of tracks.csv
  }
  return points;
}

/// Median blob area and peak of the moving detections (0 when there are none): what a
/// particle looks like, against which the spots of the median background are judged.
struct TypicalSpot {
  double area = 0, peak = 0;
};

TypicalSpot typicalSpot(const std::vector<std::vector<Detection>>& detections) {
  std::vector<double> areas, peaks;
  for (const auto& frame : detections)
    for (const auto& m : frame) {
      areas.push_back(m.area);
      peaks.push_back(m.peak);
    }
  TypicalSpot t;
  if (!areas.empty()) {
    std::nth_element(areas.begin(), areas.begin() + areas.size() / 2, areas.end());
    t.area = areas[areas.size() / 2];
    std::nth_element(peaks.begin(), peaks.begin() + peaks.size() / 2, peaks.end());
    t.peak = peaks[peaks.size() / 2];
  }
  return t;
}

struct StuckCandidate {
  const Detection* d;
  bool all_along;    ///< missing from at most a tenth of the frames: stuck from the start
  int arrival = -1;  ///< deposited: first frame of the best absent-then-present split, -1: none
};

/// The spots of the median background that are particles at rest: stuck all along, or
/// arrived and deposited (missing from the frames before their arrival and present in
/// all after). Stuck particles look like the moving ones (`typical`: blob area within a
/// factor 2, peak at least half). `frames`: the processed frame numbers, sorted;
/// evidence.absent's lists are sorted in place.
/// Whether the pixel of (x, y) or one of its four edge neighbours is solid in `solids`
/// (TrackConfig::solids; empty: never). A particle's centre lies at least its radius, a
/// pixel or more for a spot seen as a particle, beyond the solid's surface (half a pixel
/// past a solid pixel's centre): a spot centred on or beside a solid pixel is the scene.
/// On the paper window (2 um/px, 5 um particles) the 662 such spots of the median lie on
/// or beside grain pixels and the 239 deposits' centres >= 1.4 px from any.
bool onSolid(const cv::Mat& solids, double x, double y) {
  if (solids.empty()) return false;
  const int cx = static_cast<int>(std::lround(x)), cy = static_cast<int>(std::lround(y));
  const int dx[] = {0, 1, -1, 0, 0}, dy[] = {0, 0, 0, 1, -1};
  for (int k = 0; k < 5; ++k) {
    const int px = cx + dx[k], py = cy + dy[k];
    if (px >= 0 && py >= 0 && px < solids.cols && py < solids.rows && solids.at<std::uint8_t>(py, px) != 0) return true;
  }
  return false;
}

std::vector<StuckCandidate> stuckCandidates(StuckEvidence& evidence, const TypicalSpot& typical, const std::vector<int>& frames, const cv::Mat& solids,
                                            int& on_solids) {
  const int n = static_cast<int>(frames.size());
  const int tolerance = n / kTune.absence_error_divisor;  // frames the absence test may get wrong
  std::vector<StuckCandidate> candidates;
  for (std::size_t i = 0; i < evidence.stuck.size(); ++i) {
    const Detection& d = evidence.stuck[i];
    if (onSolid(solids, d.x, d.y)) {
      ++on_solids;  // a grain of the scene, not a particle
      continue;
    }
    if (typical.area > 0 &&
        (d.area < typical.area / kTune.stuck_area_ratio || d.area > kTune.stuck_area_ratio * typical.area || d.peak < kTune.stuck_peak_fraction * typical.peak))
      continue;
    std::vector<int>& a = evidence.absent[i];
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
    StuckCandidate cand{&d, static_cast<int>(a.size()) <= tolerance, -1};
    if (best_k > 0 && best_k < n && best_err <= tolerance) cand.arrival = frames[best_k];
    // A particle that only lingers (stationary for most, not all, of the video) also
    // shows in the median; it is missing from the frames where it was elsewhere.
    if (cand.all_along || cand.arrival >= 0) candidates.push_back(cand);
  }
  return candidates;
}

/// Deposited candidates joined to the track that brought them.
struct DepositJoins {
  std::vector<char> joined;                                         ///< per candidate
  std::map<std::int64_t, std::pair<std::size_t, int>> deposit_of;  ///< track -> (candidate, arrival)
};

/// Each deposited candidate is joined to the track whose last point lies a few pixels
/// from its resting place within a few frames of its arrival there (the cheapest first,
/// each track and candidate once): that track continues there at rest to the end
/// (appended to `rest`, labelled deposited).
DepositJoins joinDeposits(const TrackConfig& c, const std::vector<StuckCandidate>& candidates, const std::vector<TrackPoint>& points, const std::vector<int>& frames,
                          std::vector<TrackPoint>& rest, int& joined_count) {
  std::map<std::int64_t, const TrackPoint*> last;
  for (const auto& p : points) {
    auto& l = last[p.particle];
    if (l == nullptr || p.frame > l->frame) l = &p;
  }
  const double gate_px = joinGatePx(c);
  const int gate_frames = joinGateFrames(c);
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
  DepositJoins out;
  out.joined.assign(candidates.size(), 0);
  std::map<std::int64_t, char> used;
  for (const Join& j : joins) {
    if (out.joined[j.candidate] || used[j.end->particle]) continue;
    out.joined[j.candidate] = used[j.end->particle] = 1;
    const Detection& d = *candidates[j.candidate].d;
    restUntilTheEnd(c, *j.end, d.x, d.y, frames, rest);
    out.deposit_of[j.end->particle] = {j.candidate, candidates[j.candidate].arrival};
    ++joined_count;
  }
  return out;
}

/// A particle half merged into the median background (at rest for about half the video)
/// still leaves faint detections at its resting place after it arrived: they are the
/// deposited particle, labelled so on its own track, and other tracks made only of them
/// are duplicates of it and dropped. The joined track's labelled points must be its
/// trailing ones: a label followed by an unlabelled point (it moved again) is removed.
void labelDeposits(const TrackConfig& c, const std::vector<StuckCandidate>& candidates, const DepositJoins& joins, std::vector<TrackPoint>& points) {
  const auto& deposit_of = joins.deposit_of;
  if (deposit_of.empty()) return;
  const double near = restingRadiusPx(c);
  std::vector<std::pair<std::int64_t, std::pair<std::size_t, int>>> deposits(deposit_of.begin(), deposit_of.end());
  CellGrid deposit_grid(near);
  for (std::size_t k = 0; k < deposits.size(); ++k)
    deposit_grid.add(k, candidates[deposits[k].second.first].d->x, candidates[deposits[k].second.first].d->y);
  std::map<std::int64_t, char> duplicate;  // 1 while every point so far sits at a deposit after its arrival
  for (auto& p : points) {
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
  std::erase_if(points, [&](const TrackPoint& p) { return duplicate[p.particle] != 0; });
  std::map<std::int64_t, std::int64_t> last_unlabelled;
  for (const auto& p : points)
    if (deposit_of.count(p.particle) && p.state != "deposited") last_unlabelled[p.particle] = std::max(last_unlabelled[p.particle], p.frame);
  for (auto& p : points)
    if (deposit_of.count(p.particle) && p.state == "deposited" && last_unlabelled.count(p.particle) && p.frame < last_unlabelled[p.particle]) p.state.clear();
}

/// Particles at rest for most of the video are part of the median background: found
/// there (evidence.stuck), each is either stuck all along (an immobile track of its own,
/// left out as the paper does), or a particle that arrived and deposited: its moving track
/// ends where it merged into the background, so it is joined to the track that ends there
/// then and continues, at rest, to the end. Arrivals no track brought are left out
/// (run.deposits_unjoined). Adds to run.tracks; returns the moving detections' typical spot.
TypicalSpot joinStuckParticles(const TrackConfig& c, StuckEvidence& evidence, std::int64_t next_id, TrackRun& run) {
  const TypicalSpot typical = typicalSpot(run.detections);
  std::vector<int> frames = run.frame_index;
  std::sort(frames.begin(), frames.end());
  if (!c.solids.empty() && (c.solids.type() != CV_8UC1 || c.solids.size() != run.background.size()))
    throw std::invalid_argument(fmt::format("TrackConfig::solids: {} x {} px, one 8-bit channel expected of the frames' {} x {} px", c.solids.cols, c.solids.rows,
                                            run.background.cols, run.background.rows));
  int on_solids = 0;
  const std::vector<StuckCandidate> candidates = stuckCandidates(evidence, typical, frames, c.solids, on_solids);
  run.stuck_on_solids = on_solids;
  std::vector<TrackPoint> rest;
  const DepositJoins joins = joinDeposits(c, candidates, run.tracks.points, frames, rest, run.deposits_joined);
  labelDeposits(c, candidates, joins, run.tracks.points);
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    if (joins.joined[k]) continue;
    if (!candidates[k].all_along) {
      ++run.deposits_unjoined;  // arrived, but no track brought it: left out
      continue;
    }
    for (int f : frames) rest.push_back(trackPoint(c, f, next_id, candidates[k].d->x, candidates[k].d->y));
    ++next_id;
    ++run.stuck_found;
  }
  run.tracks.points.insert(run.tracks.points.end(), rest.begin(), rest.end());
  return typical;
}

/// The tracks from the linker: motion model (run.motion), and in flow mode the stuck and
/// deposited particles (detect.find_stuck), tracks that stop labelled deposited from where
/// they stopped (so their resting positions stay out of velocity statistics), and the
/// joins by reference frames and onto clusters.
void buildTracks(const TrackConfig& c, FrameLinkers& linkers, StuckEvidence& evidence, TrackRun& run) {
  std::vector<LinkedPoint> linked = linkers.linker.points();
  run.motion = chooseMotion(c, linked, linkers.unpredicted, run);
  const bool flow = run.motion.model == MotionModel::flow;
  std::int64_t next_id = 0;
  for (const auto& p : linked) next_id = std::max(next_id, p.particle + 1);
  run.tracks.points = trackPoints(c, linked);
  double typical_peak = 0;  // median peak of the moving detections
  if (flow && c.detect.find_stuck && !run.background.empty() && !run.frame_index.empty()) typical_peak = joinStuckParticles(c, evidence, next_id, run).peak;
  sortTracks(run.tracks.points);
  if (flow) {
    markDeposits(run.tracks, c.analysis);
    if (!evidence.references.empty() && typical_peak > 0) {
      joinByReference(run, c, evidence.references, run.polarity, typical_peak);
      markDeposits(run.tracks, c.analysis);
    }
    joinClusterArrivals(run, c);
  }
}

}  // namespace

TrackRun runTracker(FrameSource& source, const TrackConfig& c, bool quiet) {
  StageClock clock;
  TrackRun run;
  const FramePlan plan = planFrames(c);
  prefetchSamples(source, c, plan);
  clock.lap(run, "sampling");
  SampledBackground background = sampleBackground(source, c, plan);
  clock.lap(run, "background");
  TrackLinker linker(linkOptions(c));
  Progress progress("tracking", static_cast<std::size_t>(std::max(0, source.count())), quiet);
  const std::vector<cv::Mat> polarity_frames = plan.sample_polarity ? sampleFrames(source, kTune.polarity_samples) : std::vector<cv::Mat>{};
  if (plan.sample_polarity) run.ring = guessRings(polarity_frames);
  clock.lap(run, "rings");
  DetectionSetup setup = choosePolarity(c, plan, run.ring, polarity_frames, background.median);
  clock.lap(run, "polarity");
  run.background_decision = settleBackground(c, plan, polarity_frames, background, setup);
  run.background = std::move(background.median);
  clock.lap(run, "decisions");
  FrameLinkers linkers = frameLinkers(linker, c);
  StuckEvidence evidence = detectFrames(source, c, plan, run.background, background.rolling, setup, linkers, progress, run);
  clock.lap(run, "frames");
  run.polarity = setup.polarity;
  run.polarity_reason = setup.reason;
  run.link = linker.stats();
  buildTracks(c, linkers, evidence, run);
  clock.lap(run, "joins");
  run.smoothed_points = smoothTracks(run.tracks, c.smooth_frames, c.pixel_size).points;
  if (run.motion.model != MotionModel::flow) run.brownian = analyseBrownian(run.tracks, c.analysis.brownian);
  clock.lap(run, "analysis");
  run.seconds = clock.total();
  return run;
}

}  // namespace mmval::tracking
