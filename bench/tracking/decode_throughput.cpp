// Tracker speed on real-format input: a synthetic Brownian slab
// video (640 x 424 px, ~600 particles, `mmval synth --scene brownian-slab`) written
// as an RGBA PNG folder, 16-bit TIFF files and an mp4, tracked end to end (decode,
// background and polarity sampling, detection, linking, analysis, output files) with
// default settings, next to a pure-decoding loop over the same files, so that the
// gap to the decoding limit is visible. Never asserts on time.
//
//   decode-1     cv::imread (cv::VideoCapture::read for the mp4) of every frame, one thread
//   decode-N     the same with N threads taking frames from a shared counter (files only)
//   source-1     FrameSource::next() over every frame, one thread: the tracker's own decoding
//                (8-bit PNG: its libdeflate reader when built with it, else cv::imread) and
//                the conversion to float grey
//   source-N     the same with N threads (FrameSource::readAt, files only): the decoding floor
//                of a tracking run's wall time
//   track-1/-N   runTracker + writeTrackOutputs with detect.threads 1 / N
//   grab        (mp4) cv::VideoCapture::grab() of every frame: what skipping costs
//   stages       track-N's own account (TrackRun::stage_seconds, wall, and stage_cpu_seconds,
//                CPU summed over threads): sampling, background,
//                rings, polarity, decisions, frames (decode + detect + link of the rest),
//                joins, analysis, outputs; and the CPU time its threads spent decoding
//                (FrameSource::decodeSeconds), summed over threads, next to the run's CPU time;
//                detect + link alone: the same frames decoded into memory first, detected
//                by N threads against the run's background and polarity while the main thread
//                links them in frame order as they complete, as the tracker does (wall and CPU)
//   old-1        emulated old path, one thread: the old samplers read the video twice
//                more in order (background: every frame up to its 60th sample; polarity:
//                up to its 24th) before the main pass decoded every frame: track-1 plus
//                the time of those two in-order passes of FrameSource::next().
//
// The "decode share" of a tracking run is decode-1 time x threads used / run time
// for one thread (the time the run spends decoding, if it decodes as fast as the pure
// loop); frames/s are frames / wall time. The machine's load changes wall times: quote
// ratios from one run.
//
// Usage: bench_tracking_decode [--frames N] [--threads N] [--dir DIR] [--formats rgba,tiff16,mp4]
//                              [--detect-only REPEATS]
// --detect-only: only detection on frames in memory, one thread, REPEATS passes (CPU time).
// DIR holds (or receives) one folder per format, as mmval synth writes them.
#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <filesystem>
#include <functional>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>

#include "mmval/tracking/Frames.hpp"
#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/SynthSlab.hpp"

namespace {

namespace fs = std::filesystem;
using namespace mmval::tracking;

double seconds(const std::function<void()>& f) {
  const auto t0 = std::chrono::steady_clock::now();
  f();
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// The input FrameSource opens for a synth folder: frames/ or video.mp4.
fs::path inputOf(const fs::path& dir) { return fs::exists(dir / "video.mp4") ? dir / "video.mp4" : dir / "frames"; }

fs::path prepare(const fs::path& root, const std::string& format, int frames) {
  const fs::path dir = root / (format + "-" + std::to_string(frames));
  if (fs::exists(dir / "truth.csv")) return dir;
  BrownianSlabOptions o;
  o.frames = frames;
  o.format = parseSynthFormat(format);
  std::printf("writing %s (%d frames of %d x %d) ...\n", dir.string().c_str(), frames, o.width, o.height);
  std::fflush(stdout);
  writeBrownianSlabVideo(o, dir);
  return dir;
}

/// Pure decoding with `threads` threads (files) or in order (a video); returns the frames read.
int decodeAll(const fs::path& input, int threads) {
  if (!fs::is_directory(input)) {
    cv::VideoCapture cap(input.string());
    cv::Mat f;
    int n = 0;
    while (cap.read(f)) ++n;
    return n;
  }
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(input)) files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  std::atomic<std::size_t> next{0};
  auto work = [&] {
    for (std::size_t k; (k = next++) < files.size();) (void)cv::imread(files[k], cv::IMREAD_UNCHANGED);
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work);
  work();
  for (auto& t : pool) t.join();
  return static_cast<int>(files.size());
}

TrackConfig defaults(int threads) {
  TrackConfig c;  // the tracker's defaults (as mmval track uses them), Brownian slab units
  c.pixel_size = 0.15e-6;
  c.fps = 24;
  c.threads = threads;
  return c;
}

/// Detection and linking alone of every frame of `input`, decoded into memory first (not
/// timed), as the tracking run does them: against the run's background and polarity, frames
/// detected by `threads` threads taking them from a shared counter, linked in order after.
/// Linked without prediction (what a Brownian run ends with). Returns the wall time (s);
/// `cpu` receives the CPU time summed over threads (s).
double detectAndLink(const fs::path& input, int threads, const TrackRun& run, double& cpu) {
  FrameSource src(input.string());
  std::vector<cv::Mat> frames;
  cv::Mat f;
  for (int index = 0; src.next(f, index);) frames.push_back(f.clone());
  const TrackConfig c = defaults(threads);
  LinkOptions link = c.link;
  link.predict = Prediction::none;
  const std::clock_t cpu0 = std::clock();
  // As the tracker does it on image files (Pipeline.cpp, detectFilesInParallel): `threads`
  // workers detect frames taken from a shared counter while this thread links them in
  // frame order as they complete. With one thread: detect, then link, frame by frame.
  const double wall = seconds([&] {
    std::vector<std::vector<Detection>> found(frames.size());
    TrackLinker linker(link);
    if (threads <= 1) {
      for (std::size_t k = 0; k < frames.size(); ++k) linker.push(static_cast<int>(k), detect(frames[k], run.background, run.polarity, c.detect));
      return;
    }
    std::vector<char> done(frames.size(), 0);
    std::mutex m;
    std::condition_variable ready;
    std::atomic<std::size_t> next{0};
    auto work = [&] {
      for (std::size_t k; (k = next++) < frames.size();) {
        std::vector<Detection> d = detect(frames[k], run.background, run.polarity, c.detect);
        const std::lock_guard<std::mutex> lock(m);
        found[k] = std::move(d);
        done[k] = 1;
        ready.notify_all();
      }
    };
    std::vector<std::thread> pool;
    for (int t = 0; t < threads; ++t) pool.emplace_back(work);
    for (std::size_t k = 0; k < frames.size(); ++k) {
      std::unique_lock<std::mutex> lock(m);
      ready.wait(lock, [&] { return done[k] != 0; });
      const std::vector<Detection> d = std::move(found[k]);
      lock.unlock();
      linker.push(static_cast<int>(k), d);
    }
    for (auto& t : pool) t.join();
  });
  cpu = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  return wall;
}

/// Detection alone, one thread, `repeats` passes over every frame of `input` held in memory
/// (decoded first, not timed) against a tracking run's background and polarity: prints each
/// pass's CPU time, then the fastest. The steadier number for comparing two builds of the
/// detector on a shared machine (`--detect-only REPEATS`).
void detectOnly(const fs::path& input, int repeats) {
  TrackRun run;
  {
    FrameSource src(input.string());
    run = runTracker(src, defaults(1), true);
  }
  FrameSource src(input.string());
  std::vector<cv::Mat> frames;
  cv::Mat f;
  for (int index = 0; src.next(f, index);) frames.push_back(f.clone());
  const TrackConfig c = defaults(1);
  double best = 0;
  std::size_t found = 0;
  for (int k = 0; k < repeats; ++k) {
    found = 0;
    const std::clock_t cpu0 = std::clock();
    for (const cv::Mat& frame : frames) found += detect(frame, run.background, run.polarity, c.detect).size();
    const double cpu = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
    best = k == 0 ? cpu : std::min(best, cpu);
    std::printf("detection alone, 1 thread, pass %d: %.3f s CPU (%zu detections in %zu frames)\n", k + 1, cpu, found, frames.size());
  }
  std::printf("detection alone, 1 thread: fastest of %d passes %.3f s CPU\n", repeats, best);
}

/// A tracking run's own account: its stages' wall times and the time its threads spent decoding.
struct RunStages {
  std::vector<std::pair<std::string, double>> stages, stages_cpu;
  double decode_s = 0, outputs_s = 0, cpu_s = 0;
  double detect_link_s = 0;      ///< detection + linking alone on frames in memory (wall, same threads)
  double detect_link_cpu_s = 0;  ///< the same, CPU summed over threads
};

double track(const fs::path& input, int threads, const fs::path& out, long& decoded, long& grabbed, RunStages* stages = nullptr) {
  const std::clock_t cpu0 = std::clock();  // process CPU time, every thread
  TrackRun run;
  const double wall = seconds([&] {
    FrameSource src(input.string());
    run = runTracker(src, defaults(threads), true);
    const double outputs = seconds([&] { writeTrackOutputs(run, defaults(threads), out, nlohmann::json::object()); });
    decoded = src.decoded();
    grabbed = src.grabbed();
    if (stages) *stages = {run.stage_seconds, run.stage_cpu_seconds, src.decodeSeconds(), outputs, static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC};
  });
  if (stages) stages->detect_link_s = detectAndLink(input, threads, run, stages->detect_link_cpu_s);
  return wall;
}

/// One line: the run's stages (s), its outputs, and the decoding time summed over threads.
void printStages(const std::string& format, int threads, const RunStages& r) {
  std::printf("%-7s track-%d stages (s):", format.c_str(), threads);
  for (const auto& [name, s] : r.stages) std::printf(" %s %.3f", name.c_str(), s);
  std::printf("\n%-7s track-%d stages, CPU summed over threads (s):", "", threads);
  for (const auto& [name, s] : r.stages_cpu) std::printf(" %s %.3f", name.c_str(), s);
  std::printf("\n%-7s", "");
  std::printf(" outputs %.3f; CPU: decoding %.3f s of %.3f s (%.0f %%); detect + link alone (frames in memory): %.3f s wall, %.3f s CPU\n", r.outputs_s,
              r.decode_s, r.cpu_s, r.cpu_s > 0 ? 100 * r.decode_s / r.cpu_s : 0.0, r.detect_link_s, r.detect_link_cpu_s);
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 300, threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  fs::path root = fs::temp_directory_path() / "mmval-bench-decode";
  std::string formats = "rgba,tiff16,mp4";
  int detect_only = 0;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--frames") frames = std::atoi(argv[i + 1]);
    else if (a == "--threads") threads = std::atoi(argv[i + 1]);
    else if (a == "--dir") root = argv[i + 1];
    else if (a == "--formats") formats = argv[i + 1];
    else if (a == "--detect-only") detect_only = std::atoi(argv[i + 1]);
  }
  cv::setNumThreads(1);  // one core per tracker thread, as the tracking bench does
  if (detect_only > 0) {
    std::stringstream list(formats);
    for (std::string format; std::getline(list, format, ',');) detectOnly(inputOf(prepare(root, format, frames)), detect_only);
    return 0;
  }
  std::printf("%-7s %6s %10s %10s %10s %10s %10s %8s %9s %9s\n", "format", "frames", "decode-1", "decode-N", "track-1", "track-N", "old-1",
              "old/new", "dec.share", "decodes");
  std::printf("%-7s %6s %10s %10s %10s %10s %10s %8s %9s %9s\n", "", "", "frames/s", "frames/s", "frames/s", "frames/s", "frames/s", "1 thread",
              "1 thread", "per frame");
  std::stringstream list(formats);
  for (std::string format; std::getline(list, format, ',');) {
    const fs::path dir = prepare(root, format, frames);
    const fs::path input = inputOf(dir), out = dir / "out";
    int n = 0;
    const double dec1 = seconds([&] { n = decodeAll(input, 1); });
    const double decn = fs::is_directory(input) ? seconds([&] { decodeAll(input, threads); }) : dec1;
    const double source1 = seconds([&] {
      FrameSource src(input.string());
      cv::Mat f;
      for (int index = 0; src.next(f, index);) {
      }
    });
    long decoded1 = 0, decodedn = 0, decoded_old = 0, grabbed1 = 0, grabbedn = 0;
    const double t1 = track(input, 1, out, decoded1, grabbed1);
    RunStages stages_n;
    const double tn = track(input, threads, out, decodedn, grabbedn, &stages_n);
    // Old path: the old samplers read in order up to their last sample (background: 60
    // samples, polarity: 24) and cloned the ones they kept; everything else the runs share.
    long old_reads = 0;
    const double passes = seconds([&] {
      for (int samples : {TrackConfig{}.detect.background_samples, 24}) {
        FrameSource src(input.string());
        const int stride = std::max(1, src.count() / samples);
        const int last = std::min(src.count() - 1, (samples - 1) * stride);
        cv::Mat f;
        int index = 0;
        for (int k = 0; k <= last && src.next(f, index); ++k) ++old_reads;
      }
    });
    const double t_old = passes + t1;
    decoded_old = decoded1 + old_reads;
    std::printf("%-7s %6d %10.1f %10.1f %10.1f %10.1f %10.1f %8.2f %8.0f%% %4.2f/%4.2f\n", format.c_str(), n, n / dec1, n / decn, n / t1, n / tn,
                n / t_old, t_old / t1, 100.0 * dec1 / t1, static_cast<double>(decoded1) / n, static_cast<double>(decoded_old) / n);
    std::printf("%-7s source-1 (FrameSource decode + grey float, 1 thread): %.1f frames/s against decode-1 (cv::imread) %.1f frames/s\n", "", n / source1,
                n / dec1);
    if (fs::is_directory(input)) {
      // The tracker's own decoding with `threads` workers (FrameSource::readAt, as the
      // tracking run's workers call it): the floor of an end-to-end run's wall time.
      double cpu = 0;
      const double sourcen = seconds([&] {
        const std::clock_t c0 = std::clock();
        FrameSource src(input.string());
        cv::Mat first;
        int first_index = 0;
        src.next(first, first_index);  // fixes the frame size (and a 16-bit range), as the tracking run does
        std::atomic<int> next{1};
        auto work = [&] {
          cv::Mat f;
          int index = 0;
          for (int pos; (pos = next++) < src.count();) src.readAt(pos, f, index);
        };
        std::vector<std::thread> pool;
        for (int t = 1; t < threads; ++t) pool.emplace_back(work);
        work();
        for (auto& t : pool) t.join();
        cpu = static_cast<double>(std::clock() - c0) / CLOCKS_PER_SEC;
      });
      std::printf("%-7s source-%d (the same, %d threads): %.1f frames/s, %.3f s wall, %.3f s CPU: the pure-decoding floor of a tracking run\n", "",
                  threads, threads, n / sourcen, sourcen, cpu);
    }
    printStages(format, threads, stages_n);
    if (!fs::is_directory(input)) {
      // What a sampler's grab() saves over read(): the pixel conversion only.
      const double grab = seconds([&] {
        cv::VideoCapture cap(input.string());
        while (cap.grab()) {
        }
      });
      std::printf("%-7s grab() only: %.1f frames/s (read(): %.1f); the tracking run grabbed %.2f frames per frame besides its decodes\n", "",
                  n / grab, n / dec1, static_cast<double>(grabbed1) / n);
    }
    std::fflush(stdout);
  }
  std::printf("threads N = %d; decodes per frame: new / emulated old (full decodes, grab() not counted)\n", threads);
  return 0;
}
