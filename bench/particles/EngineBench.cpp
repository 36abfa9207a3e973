// Overdamped engine against LIGGGHTS on a shared window of one scene (the table
// of the cheaper model's errors against LIGGGHTS), with the overdamped
// step ladder, and the overdamped throughput at the micromodel's conditions.
//   bench_particles_engines [out.json]
#include <chrono>
#include <fstream>
#include <iostream>
#include <vector>

#include <fmt/format.h>

#include "mmval/particles/EngineComparison.hpp"
#include "mmval/particles/EngineFactory.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
#ifdef MMVAL_WITH_LIGGGHTS
#include "mmval/particles/LiggghtsEngine.hpp"
#endif

using namespace mmval::particles;

namespace {

#ifdef MMVAL_WITH_LIGGGHTS
SceneConfig comparisonScene() {
  SceneConfig c;
  c.brownian = false;           // LIGGGHTS has none: compare deterministic trajectories
  c.gravity = 9.81 * 400;       // falls ~8 um in the window: captures happen
  c.attachment.grains = false;  // sticky bottom only
  c.particle.youngs_modulus = 1e5;
  c.work_dir = std::filesystem::temp_directory_path() / "mmval-bench-liggghts";
  return c;
}
#endif

}  // namespace

int main(int argc, char** argv) {
  nlohmann::json out;
  auto flow = std::make_shared<HeleShawChannel>(400e-6, 100e-6, 20e-6, 7e-4);
#ifdef MMVAL_WITH_LIGGGHTS
  {
    const SceneConfig c = comparisonScene();
    const auto pos = sampleInlet(*flow, c.particle.radius(), 20e-6, 60e-6, 30, 17, {});
    fmt::print("Shared window: 30 particles of 5 um, Hele-Shaw channel 20 um deep, u_mean 0.7 mm/s, sticky bottom, g x400, 0.03 s\n");
    fmt::print("{:>10} {:>12} {:>12} {:>12} {:>9} {:>9} {:>12} {:>10} {:>10} {:>10}\n", "step_frac", "rms_um", "median_nm", "max_um",
               "capt_LG", "capt_OD", "dt_capt_s", "wall_LG_s", "wall_OD_s", "speedup");
    for (double frac : {0.1, 0.03, 0.01}) {
      SceneConfig od_cfg = c;
      od_cfg.max_step_fraction = frac;
      LiggghtsEngine lg(flow, c);
      OverdampedEngine od(flow, od_cfg);
      const EngineComparison r = compareEngines(lg, od, pos, 0.03, 0.003);
      fmt::print("{:>10} {:>12.4f} {:>12.2f} {:>12.4f} {:>9} {:>9} {:>12.2e} {:>10.3f} {:>10.4f} {:>10.0f}\n", frac, r.rms_position_difference * 1e6,
                 r.median_final_difference * 1e9, r.max_position_difference * 1e6, r.captured_reference, r.captured_candidate,
                 r.rms_capture_time_difference, r.wall_seconds_reference, r.wall_seconds_candidate,
                 r.wall_seconds_reference / std::max(r.wall_seconds_candidate, 1e-9));
      auto j = r.toJson();
      j["overdamped_max_step_fraction"] = frac;
      j["liggghts_dt_s"] = lg.dt();
      out["comparison"].push_back(j);
    }
  }
#else
  fmt::print("LIGGGHTS engine not built: comparison skipped\n");
#endif
  {
    // Throughput at the experiment's conditions: 5 um polystyrene, 0.72 mm/s, real
    // gravity, Brownian motion on, 200 particles in a 2 mm channel, 5 s; on 1 and 2 threads
    // (numerics.threads: the same particles bit for bit, wall time apart).
    auto chip = std::make_shared<HeleShawChannel>(2e-3, 200e-6, 20e-6, 7.2e-4);
    std::vector<ParticleState> first;
    double wall_one = 0;
    for (const int threads : {1, 2}) {
      SceneConfig c;
      c.threads = threads;
      OverdampedEngine od(chip, c);
      od.insert(sampleInlet(*chip, c.particle.radius(), 0.0, 1.5e-3, 200, 3, {}));
      od.advance(5.0);
      const auto st = od.stats();
      const auto n = od.counts();
      const auto ps = od.particles();
      bool same = true;
      if (threads == 1) first = ps, wall_one = st.wall_seconds;
      else
        for (std::size_t i = 0; i < ps.size(); ++i) same = same && ps[i].x == first[i].x && ps[i].status == first[i].status;
      fmt::print("\nOverdamped throughput (micromodel conditions, Brownian on, 200 particles, 5 s physical, {} thread(s)): {} steps, dt {:.2e} .. {:.2e} s, "
                 "{:.3g} particle-steps/s, wall {:.3f} s (x{:.2f} of one thread's){}; deposited {}, left {}, inside {}\n",
                 threads, st.steps, st.min_dt, st.max_dt, st.particle_steps / st.wall_seconds, st.wall_seconds, wall_one / st.wall_seconds,
                 same ? "" : ", PARTICLES DIFFER FROM ONE THREAD'S", n.deposited, n.left, n.inside);
      nlohmann::json j = {{"threads", threads}, {"steps", st.steps}, {"particle_steps", st.particle_steps}, {"wall_seconds", st.wall_seconds},
                          {"particle_steps_per_second", st.particle_steps / st.wall_seconds}, {"min_dt_s", st.min_dt}, {"max_dt_s", st.max_dt},
                          {"same_as_one_thread", same}};
      if (threads == 1) out["throughput"] = j;
      else out["throughput_threads"].push_back(j);
    }
  }
  if (argc > 1) std::ofstream(argv[1]) << out.dump(2) << "\n";
  return 0;
}
