// Tracker throughput: detect + link frames per second on synthetic
// frames, 640 x 424 px with ~600 particles (trackpy's walkthrough reports ~45
// frames/s there, single process) and 2048 x 2048 px with ~5,000, on 1 and 2
// threads. Never asserts on time.
//
//   BM_Pipeline/<scene>/<threads>  whole tracker from PNG files on disk (decode,
//                                  detection, linking), no background removal
//   BM_PipelineMemory/<scene>/<threads>/<deblend>  detection + linking of the same frames
//                                  already decoded in memory (what the throughput target counts),
//                                  with the default joint fit of overlapping spots or without
//                                  it (the work trackpy's locate does)
//   BM_Detect/<scene>/<deblend>    detection of one in-memory frame, with the joint fit of
//                                  overlapping spots (the default) or without it
//   BM_Link/<scene>/<linker>       linking of the scene's detections (0 global, 1 paper)
//
// Threads: with an image folder each worker reads (decodes) and detects whole frames;
// the calling thread links in order (BM_PipelineMemory: the same pool without the
// decoding; one thread detects and links in turn). OpenCV's own thread pool is limited
// to the same count, so that "1 thread" is one core. The machine's load changes real
// times a lot: compare builds back to back, and read the CPU column too (it counts the
// calling thread only when there are workers).
#include <benchmark/benchmark.h>

#include <atomic>
#include <condition_variable>
#include <filesystem>
#include <map>
#include <mutex>
#include <thread>

#include <opencv2/core.hpp>

#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Link.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/Synth.hpp"

namespace {

using namespace mmval::tracking;
namespace fs = std::filesystem;

struct Scene {
  fs::path dir;
  SynthResult synth;
};

/// Scene 0: 640 x 424, 600 particles, 40 frames; scene 1: 2048 x 2048, 5,000 particles, 10 frames.
const Scene& scene(int which) {
  static std::map<int, Scene> cache;
  auto it = cache.find(which);
  if (it != cache.end()) return it->second;
  SynthOptions o;
  o.width = which == 0 ? 640 : 2048;
  o.height = which == 0 ? 424 : 2048;
  o.frames = which == 0 ? 40 : 10;
  o.particles = which == 0 ? 600 : 5000;
  o.immobile = 0;
  o.grains = 0;
  o.speed = 2;
  o.seed = 3;
  Scene s;
  s.dir = fs::temp_directory_path() / ("mmval-bench-tracking-" + std::to_string(which));
  fs::remove_all(s.dir);
  s.synth = writeSyntheticVideo(o, s.dir);
  return cache.emplace(which, std::move(s)).first->second;
}

TrackConfig config(int threads) {
  TrackConfig c;
  c.detect.subtract_background = false;  // as trackpy's locate: no temporal background
  c.detect.polarity = Polarity::dark;
  c.threads = threads;
  return c;
}

/// Limits OpenCV's own thread pool (blurs) to `threads` for the benchmark's lifetime.
class CvThreads {
 public:
  explicit CvThreads(int threads) : m_before(cv::getNumThreads()) { cv::setNumThreads(threads); }
  ~CvThreads() { cv::setNumThreads(m_before); }

 private:
  int m_before;
};

void BM_Pipeline(benchmark::State& state) {
  const Scene& s = scene(static_cast<int>(state.range(0)));
  const TrackConfig c = config(static_cast<int>(state.range(1)));
  const CvThreads cv_threads(c.threads);
  std::size_t frames = 0, points = 0;
  for (auto _ : state) {
    FrameSource src((s.dir / "frames").string());
    const TrackRun run = runTracker(src, c, true);
    frames = run.frame_index.size();
    points = run.tracks.points.size();
  }
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(frames), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["particles_per_frame"] = frames ? static_cast<double>(points) / frames : 0.0;
}
BENCHMARK(BM_Pipeline)->ArgsProduct({{0, 1}, {1, 2}})->ArgNames({"scene", "threads"})->Unit(benchmark::kMillisecond)->UseRealTime();

/// The scene's frames, decoded once (float grey, as FrameSource gives them).
const std::vector<cv::Mat>& decoded(int which) {
  static std::map<int, std::vector<cv::Mat>> cache;
  auto it = cache.find(which);
  if (it != cache.end()) return it->second;
  FrameSource src((scene(which).dir / "frames").string());
  std::vector<cv::Mat> frames;
  cv::Mat f;
  int i = 0;
  while (src.next(f, i)) frames.push_back(f.clone());
  return cache.emplace(which, std::move(frames)).first->second;
}

/// Detection + linking of in-memory frames as runTracker does it: `threads` workers take
/// the next frame from a shared counter and detect it, the calling thread links in frame
/// order as they complete; one thread detects and links in turn.
std::size_t detectAndLink(const std::vector<cv::Mat>& frames, const TrackConfig& c) {
  const int n = static_cast<int>(frames.size());
  TrackLinker linker(c.link);
  if (c.threads <= 1) {
    for (int k = 0; k < n; ++k) linker.push(k, detect(frames[k], {}, c.detect.polarity, c.detect));
    return linker.points().size();
  }
  std::vector<std::vector<Detection>> found(static_cast<std::size_t>(n));
  std::vector<char> done(static_cast<std::size_t>(n), 0);
  std::mutex m;
  std::condition_variable ready;
  std::atomic<int> next{0};
  auto worker = [&] {
    for (int k; (k = next++) < n;) {
      std::vector<Detection> d = detect(frames[k], {}, c.detect.polarity, c.detect);
      {
        const std::lock_guard<std::mutex> lock(m);
        found[k] = std::move(d);
        done[k] = 1;
      }
      ready.notify_all();
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < c.threads; ++t) pool.emplace_back(worker);
  for (int k = 0; k < n; ++k) {
    std::unique_lock<std::mutex> lock(m);
    ready.wait(lock, [&] { return done[k] != 0; });
    std::vector<Detection> d = std::move(found[k]);
    lock.unlock();
    linker.push(k, d);
  }
  for (auto& t : pool) t.join();
  return linker.points().size();
}

void BM_PipelineMemory(benchmark::State& state) {
  const std::vector<cv::Mat>& frames = decoded(static_cast<int>(state.range(0)));
  TrackConfig c = config(static_cast<int>(state.range(1)));
  c.detect.deblend = state.range(2) != 0;  // 0: no joint fit of overlapping spots, like trackpy's locate
  const CvThreads cv_threads(c.threads);
  std::size_t points = 0;
  for (auto _ : state) points = detectAndLink(frames, c);
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(frames.size()), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["particles_per_frame"] = frames.empty() ? 0.0 : static_cast<double>(points) / frames.size();
}
BENCHMARK(BM_PipelineMemory)->ArgsProduct({{0, 1}, {1, 2}, {1, 0}})->ArgNames({"scene", "threads", "deblend"})->Unit(benchmark::kMillisecond)->UseRealTime();

const std::vector<std::vector<Detection>>& detections(int which) {
  static std::map<int, std::vector<std::vector<Detection>>> cache;
  auto it = cache.find(which);
  if (it != cache.end()) return it->second;
  FrameSource src((scene(which).dir / "frames").string());
  const TrackRun run = runTracker(src, config(1), true);
  return cache.emplace(which, run.detections).first->second;
}

void BM_Detect(benchmark::State& state) {
  const Scene& s = scene(static_cast<int>(state.range(0)));
  FrameSource src((s.dir / "frames").string());
  cv::Mat f;
  int i = 0;
  src.next(f, i);
  TrackConfig c = config(1);
  c.detect.deblend = state.range(1) != 0;
  const CvThreads cv_threads(1);
  std::size_t n = 0;
  for (auto _ : state) n = detect(f, {}, Polarity::dark, c.detect).size();
  state.counters["particles"] = static_cast<double>(n);
  state.counters["frames_per_s"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Detect)->ArgsProduct({{0, 1}, {1, 0}})->ArgNames({"scene", "deblend"})->Unit(benchmark::kMillisecond);

void BM_Link(benchmark::State& state) {
  const auto& frames = detections(static_cast<int>(state.range(0)));
  LinkOptions o;
  o.method = state.range(1) == 0 ? Linker::global : Linker::paper;
  for (auto _ : state) {
    TrackLinker l(o);
    for (std::size_t k = 0; k < frames.size(); ++k) l.push(static_cast<int>(k), frames[k]);
    benchmark::DoNotOptimize(l.stats().links);
  }
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(frames.size()), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Link)->ArgsProduct({{0, 1}, {0, 1}})->ArgNames({"scene", "paper"})->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
