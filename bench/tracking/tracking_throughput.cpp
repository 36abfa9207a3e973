// Tracker throughput on dense synthetic frames: detection per frame and
// global linking per frame at 2,000 particles, and the two linkers side by
// side on the same detections (ratios from one run).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <random>

#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Link.hpp"
#include "mmval/tracking/Synth.hpp"

namespace {

using namespace mmval::tracking;

const std::filesystem::path kDir = std::filesystem::temp_directory_path() / "mmval-bench-tracking";

const SynthResult& dense() {
  static const SynthResult r = [] {
    SynthOptions o;
    o.width = 1024;
    o.height = 1024;
    o.frames = 20;
    o.particles = 2000;
    o.immobile = 0;
    o.grains = 30;
    o.speed = 2;
    return writeSyntheticVideo(o, kDir);
  }();
  return r;
}

void BM_DetectFrame(benchmark::State& state) {
  dense();
  FrameSource src((kDir / "frames").string());
  const cv::Mat bg = medianBackground(src, 20);
  cv::Mat f;
  int i = 0;
  src.next(f, i);
  std::size_t n = 0;
  for (auto _ : state) n = detect(f, bg, Polarity::dark, DetectOptions{}).size();
  state.counters["particles"] = static_cast<double>(n);
  state.counters["frames_per_s"] = benchmark::Counter(1, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_DetectFrame)->Unit(benchmark::kMillisecond);

std::vector<std::vector<Detection>> detections() {
  static std::vector<std::vector<Detection>> all = [] {
    dense();
    FrameSource src((kDir / "frames").string());
    const cv::Mat bg = medianBackground(src, 20);
    std::vector<std::vector<Detection>> out;
    cv::Mat f;
    int i = 0;
    while (src.next(f, i)) out.push_back(detect(f, bg, Polarity::dark, DetectOptions{}));
    return out;
  }();
  return all;
}

void BM_Link(benchmark::State& state) {
  const auto frames = detections();
  LinkOptions o;
  o.method = state.range(0) == 0 ? Linker::global : Linker::paper;
  for (auto _ : state) {
    TrackLinker l(o);
    for (std::size_t k = 0; k < frames.size(); ++k) l.push(static_cast<int>(k), frames[k]);
    benchmark::DoNotOptimize(l.stats().links);
  }
  state.SetLabel(o.method == Linker::global ? "global" : "paper");
  state.counters["frames_per_s"] = benchmark::Counter(static_cast<double>(frames.size()), benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_Link)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
