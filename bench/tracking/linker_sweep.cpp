// Where each linker breaks down: synthetic videos (clean spots, uniform flow
// past grains) over a grid of particle densities and speeds, tracked with the
// paper's rule and with the global linker, scored after Chenouard et al.
// (2014). Prints one table row per scene. Usage: bench_tracking_linker_sweep [OUT_DIR]
// The search radius follows the speed (2 x speed + 3 px), as a user would set it.
#include <chrono>
#include <cstdio>
#include <filesystem>

#include "mmval/tracking/Pipeline.hpp"
#include "mmval/tracking/Score.hpp"
#include "mmval/tracking/Synth.hpp"

int main(int argc, char** argv) {
  using namespace mmval::tracking;
  namespace fs = std::filesystem;
  const fs::path out = argc > 1 ? argv[1] : "out/bench-linker-sweep";
  std::printf("%10s %10s %8s | %-7s %8s %8s %8s %9s\n", "particles", "per Mpx", "px/frame", "linker", "JSC", "JSC_th", "RMSE px", "link ms/f");
  for (int particles : {250, 1000, 2000, 4000}) {
    for (double speed : {2.0, 4.0, 8.0, 12.0}) {
      SynthOptions o;
      o.width = 640;
      o.height = 480;
      o.frames = 20;
      o.particles = particles;
      o.immobile = 0;
      o.deposit_fraction = 0;
      o.grains = 12;
      o.grain_radius = 20;
      o.speed = speed;
      o.snr = 10;
      o.seed = 5;
      const fs::path dir = out / ("p" + std::to_string(particles) + "-v" + std::to_string(static_cast<int>(speed)));
      fs::remove_all(dir);
      const SynthResult truth = writeSyntheticVideo(o, dir);
      for (Linker method : {Linker::paper, Linker::global}) {
        TrackConfig c;
        c.link.method = method;
        c.link.search_radius = 2 * speed + 3;
        FrameSource src((dir / "frames").string());
        const auto t0 = std::chrono::steady_clock::now();
        const TrackRun run = runTracker(src, c, true);
        const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count() / o.frames;
        const Scores s = scoreTracks(truth.truth, run.tracks);
        std::printf("%10d %10.0f %8.1f | %-7s %8.3f %8.3f %8.3f %9.2f\n", particles, particles / (o.width * o.height * 1e-6), speed,
                    method == Linker::paper ? "paper" : "global", s.jaccard_points, s.jaccard_tracks, s.rmse_px, ms);
        std::fflush(stdout);
      }
    }
  }
  return 0;
}
