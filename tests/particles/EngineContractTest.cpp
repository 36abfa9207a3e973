// Contract tests over every particle engine: one table of the engines
// (overdamped, LIGGGHTS, resolved immersed boundary) and one set of
// parametrised tests that each must pass, after HOOMD-blue's
// hoomd/md/pytest/test_methods.py (one table of methods, parametrised tests).
//
// Each engine runs the same two scenes in its own terms:
//   settling  one free particle falling through fluid at rest: its speed against
//             the engine's single-particle reference (Stokes' sphere for the
//             3D engines, Faxen's cylinder between plates for the 2D resolved disks);
//   channel   a few particles carried along a walled channel while gravity pulls
//             them towards a wall: some deposit, some leave through the outlet.
// Contracts on the channel scene: no centre ever comes closer to a wall than a
// radius (less the engine's contact overlap), the counts balance at every
// output (injected = inside + deposited + left) and agree with the particle
// list, and two runs with the same seed are identical (a different seed
// differs, for engines with Brownian motion).
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <ostream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "ParticleRegistry.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/particles/EngineFactory.hpp"
#include "mmval/particles/FlowField.hpp"

#include "../TestScratch.hpp"
#include "ResolvedChannelCase.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------
// What the contracts look at, whatever the engine.

/// One particle still in the channel (mobile or deposited) at one output time.
struct Sample {
  std::int64_t id = 0;
  Vec3 x = Vec3::Zero();  ///< m; z = 0 for the 2D resolved engine
  bool deposited = false;
};

/// Where a particle centre may be: the walls moved in by one radius. z is unchecked for 2D engines.
struct CentreBox {
  double y0 = 0, y1 = 0;
  double z0 = 0, z1 = 0;
  bool has_z = true;
};

/// A run of the channel scene as the contracts see it.
struct ChannelRun {
  std::vector<double> times;                 ///< s, one per output
  std::vector<std::vector<Sample>> frames;   ///< per output: the particles still in the channel
  std::vector<Counts> counts;                ///< per output, as the engine reports them
  std::int64_t inserted = 0;                 ///< particles the scene put in
  CentreBox box;
};

/// The settling scene: the measured speed along gravity and its reference.
struct SettlingRun {
  double measured = 0;   ///< m/s
  double reference = 0;  ///< m/s
  double tolerance = 0;  ///< relative
  std::string reference_name;
};

/// One row of the engine table.
struct EngineEntry {
  std::string name;
  std::function<std::string()> unavailable;  ///< why it cannot run in this build; "" when it can
  std::function<SettlingRun()> settle;
  std::function<ChannelRun(std::uint64_t seed)> channel;
  bool stochastic = false;         ///< its trajectories depend on the seed (Brownian motion)
  double overlap_tolerance = 0.0;  ///< m a centre may come closer to a wall than one radius (contact model)
};

// ---------------------------------------------------------------------------
// The 3D engines (ParticleEngine through makeEngine): overdamped and LIGGGHTS.

/// 5 um spheres twice as dense as water, gravity raised 100x: the fall takes milliseconds,
/// which keeps LIGGGHTS (its step is 0.1 Rayleigh times, ~4e-8 s for this soft material) to ~1e5 steps.
SceneConfig denseSpheres(const std::string& work_name) {
  SceneConfig c;
  c.particle.diameter = 5e-6;
  c.particle.density = 2000;
  c.gravity = 981;
  c.work_dir = mmval::test::scratch("engine-contract-" + work_name);
  return c;
}

/// Stokes' terminal speed of a free sphere, 2 (rho_p - rho_f) g a^2 / (9 mu) (Stokes 1851), written
/// out here rather than taken from the library so that the reference does not share its code.
double stokesSphereSpeed(const SceneConfig& c) {
  const double a = 0.5 * c.particle.diameter;
  return 2.0 * (c.particle.density - c.fluid.density) * c.gravity * a * a / (9.0 * c.fluid.viscosity);
}

SettlingRun settleSphere(EngineKind kind, double tolerance, const std::string& tolerance_why) {
  SceneConfig c = denseSpheres(std::string(engineName(kind)) + "-settle");
  c.brownian = false;
  c.wall_hindrance = false;  // a free sphere: the plates are 30 um and more away
  c.faxen_curvature = false;
  c.attachment.capture_distance = 0;
  const double h = 60e-6;
  auto flow = std::make_shared<UniformFlow>(Vec2(0, 0), h, Bounds2{0, 100e-6, 0, 100e-6});
  auto e = makeEngine(kind, flow, c);
  e->insert({Vec3(50e-6, 50e-6, 40e-6)});
  // Measured between two times far past the particle relaxation time (tau_p = 2.8 us): the
  // start-up transient shifts both positions alike and drops out of the difference.
  e->advance(0.5e-3);
  const double t1 = e->time(), z1 = e->particles()[0].x.z();
  e->advance(2.5e-3);
  const double t2 = e->time(), z2 = e->particles()[0].x.z();
  return {(z1 - z2) / (t2 - t1), stokesSphereSpeed(c), tolerance, "Stokes' sphere (" + tolerance_why + ")"};
}

/// The channel scene for the 3D engines: a Hele-Shaw channel 60 x 30 um, 20 um deep, mean speed
/// 5 mm/s; sticky plates and side walls (capture within 0.1 um, the defaults). Four spheres: one
/// beside each side wall, one low (it deposits), one high near the outlet (it leaves first).
ChannelRun channelSpheres(EngineKind kind, std::uint64_t seed) {
  SceneConfig c = denseSpheres(fmt::format("{}-channel-{}", engineName(kind), seed));
  c.seed = seed;
  const double L = 60e-6, W = 30e-6, h = 20e-6, a = 0.5 * c.particle.diameter;
  auto flow = std::make_shared<HeleShawChannel>(L, W, h, 5e-3);
  auto e = makeEngine(kind, flow, c);
  const std::vector<Vec3> start = {Vec3(10e-6, a + 0.3e-6, 10e-6), Vec3(45e-6, W - a - 0.3e-6, h - a - 0.5e-6), Vec3(25e-6, 15e-6, 10e-6),
                                   Vec3(5e-6, 15e-6, a + 1e-6)};
  e->insert(start);
  ChannelRun run;
  run.inserted = static_cast<std::int64_t>(start.size());
  run.box = {a, W - a, a, h - a, true};
  for (int k = 1; k <= 15; ++k) {
    e->advance(k * 1e-3);
    run.times.push_back(e->time());
    std::vector<Sample> frame;
    for (const ParticleState& p : e->particles())
      if (p.status != ParticleStatus::left) frame.push_back({p.id, p.x, p.status == ParticleStatus::deposited});
    run.frames.push_back(frame);
    run.counts.push_back(e->counts());
  }
  return run;
}

// ---------------------------------------------------------------------------
// The resolved immersed-boundary engine, through its case kind (particles-resolved):
// rigid disks in 2D creeping flow; its outputs are trajectories.csv and retention.csv.

fs::path runResolvedCase(const std::string& text, const std::string& name) {
  CaseKindRegistry& registry = test_support::particleRegistry();
  const Case c = Case::parse(text, "cases/" + name + ".toml", registry);
  const fs::path out = mmval::test::scratch("engine-contract-resolved") / name;
  fs::remove_all(out);
  fs::create_directories(out);
  RunContext ctx;
  ctx.out_dir = out;
  ctx.quiet = true;
  registry.find("particles-resolved")->run(c, ctx);
  return out;
}

/// Faxen's drag per unit length on a cylinder of radius a moving midway between plane walls 2 l
/// apart, R = 4 pi mu / (ln(l/a) - 0.9157 + 1.7244 k^2 - 1.7302 k^4 + 2.4056 k^6 - 4.5913 k^8),
/// k = a/l (Faxen's series as given by Happel & Brenner, Low Reynolds Number Hydrodynamics, 1965).
double faxenCylinderDrag(double a, double l, double mu) {
  const double k = a / l, k2 = k * k;
  return 4 * kPi * mu / (std::log(l / a) - 0.9157 + k2 * (1.7244 + k2 * (-1.7302 + k2 * (2.4056 - 4.5913 * k2))));
}

SettlingRun settleDisk() {
  // A 10 um polystyrene disk on the centre line of a closed 100 x 40 um box, falling along it.
  const fs::path out = runResolvedCase(R"(
[case]
name = "contract-settling"
kind = "particles-resolved"
[channel]
length = "100 um"
width = "40 um"
[particles]
diameter = "10 um"
density = "1.05 g/cm3"
x = ["50 um"]
y = ["20 um"]
[fluid]
viscosity = "1e-3 Pa s"
density = "998.2 kg/m3"
[physics]
gravity_x = "-9.81 m/s2"
[numerics]
cells_per_diameter = 12
max_step_fraction = 1.0
[run]
duration = "1 s"
output_interval = "0.5 s"
)",
                                       "settling");
  const Tracks t = readTracksCsv(out / "trajectories.csv");
  EXPECT_EQ(t.points.size(), 3u);
  if (t.points.size() != 3) return {};
  // Net weight per unit length over Faxen's resistance: the terminal speed of a cylinder in creeping flow.
  const double a = 5e-6, weight = (1050 - 998.2) * 9.81 * kPi * a * a;
  const double measured = -(t.points[2].x - t.points[1].x) / (t.points[2].t - t.points[1].t);
  // 12 cells per diameter put the disk within +0.5 % of Faxen's speed; the box's closed ends, 45 um
  // away, and Faxen's series truncated at k^8 (k = 0.25) are well below that: 1 %.
  return {measured, weight / faxenCylinderDrag(a, 20e-6, 1e-3), 0.01, "Faxen's cylinder midway between plates (12 cells per diameter: 1 %)"};
}

/// The channel scene for the resolved engine: 8 um disks in a channel 60 x 30 um with creeping
/// inflow (0.1 mm/s mean) and gravity towards the wall y = 0; every surface sticky within 0.5 um.
/// The low disk deposits on the wall, the high one leaves through the open outlet. The engine has
/// no random input: `seed` only names the output folder.
ChannelRun channelDisks(std::uint64_t seed) {
  const fs::path out = runResolvedCase(resolvedChannelCase("contract-channel"),
                                       fmt::format("channel-{}", seed));
  ChannelRun run;
  run.inserted = 2;
  const double a = 4e-6, W = 30e-6;
  run.box = {a, W - a, 0, 0, false};
  std::map<std::int64_t, std::vector<Sample>> by_frame;
  std::map<std::int64_t, double> time_of;
  for (const TrackPoint& p : readTracksCsv(out / "trajectories.csv").points) {
    by_frame[p.frame].push_back({p.particle, Vec3(p.x, p.y, 0), p.state == "deposited"});
    time_of[p.frame] = p.t;
  }
  std::ifstream in(out / "retention.csv");
  std::stringstream text;
  text << in.rdbuf();
  const tables::TableColumns table = tables::parseTable(text.str(), (out / "retention.csv").string());
  const auto& frame = table.at("frame");
  for (std::size_t r = 0; r < frame.size(); ++r) {
    const auto k = static_cast<std::int64_t>(frame[r]);
    run.times.push_back(table.at("t_s")[r]);
    run.frames.push_back(by_frame[k]);
    Counts c;
    c.injected = static_cast<std::int64_t>(table.at("injected")[r]);
    c.inside = static_cast<std::int64_t>(table.at("inside")[r]);
    c.deposited = static_cast<std::int64_t>(table.at("retained")[r]);
    c.left = static_cast<std::int64_t>(table.at("left")[r]);
    run.counts.push_back(c);
  }
  return run;
}

// ---------------------------------------------------------------------------
// The table.

std::string liggghtsMissing() { return liggghtsAvailable() ? "" : "this build has no LIGGGHTS engine (MMVAL_WITH_LIGGGHTS off)"; }

const std::vector<EngineEntry>& engineTable() {
  static const std::vector<EngineEntry> table = {
      {"overdamped", [] { return std::string(); },
       // A constant drift integrated by Euler steps: exact up to round-off.
       [] { return settleSphere(EngineKind::overdamped, 1e-9, "constant drift, round-off"); },
       [](std::uint64_t seed) { return channelSpheres(EngineKind::overdamped, seed); }, true, 0.0},
      {"liggghts", liggghtsMissing,
       // Its drag integrator is exact for a constant flow (tests/particles/LiggghtsTest.cpp) and the speed is
       // taken from two positions past the transient: measured 3e-11 off; 1e-6 leaves room for round-off.
       [] { return settleSphere(EngineKind::liggghts, 1e-6, "exact drag integrator past the transient, 1e-6"); },
       [](std::uint64_t seed) { return channelSpheres(EngineKind::liggghts, seed); }, false,
       // Hertz overlap of a sphere pressed on a wall by its raised weight and the drag: ~1e-9 m; 0.01 a allowed.
       0.025e-6},
      {"resolved", [] { return std::string(); }, settleDisk, channelDisks, false, 0.0},
  };
  return table;
}

/// Test names and failure messages show the engine's name, not the entry's bytes.
void PrintTo(const EngineEntry& e, std::ostream* os) { *os << e.name; }

class EngineContract : public ::testing::TestWithParam<EngineEntry> {
 protected:
  void SetUp() override {
    if (const std::string why = GetParam().unavailable(); !why.empty()) GTEST_SKIP() << why;
  }
  /// The channel scene with seed 1, run once per engine and shared by the contracts that only read it.
  const ChannelRun& channelSeed1() {
    static std::map<std::string, ChannelRun> runs;
    auto it = runs.find(GetParam().name);
    if (it == runs.end()) it = runs.emplace(GetParam().name, GetParam().channel(1)).first;
    return it->second;
  }
};

TEST_P(EngineContract, FreeParticleSettlesAtItsReferenceSpeed) {
  const SettlingRun s = GetParam().settle();
  ASSERT_GT(s.reference, 0);
  EXPECT_NEAR(s.measured, s.reference, s.tolerance * s.reference)
      << GetParam().name << ": " << s.measured * 1e6 << " um/s against " << s.reference_name << " " << s.reference * 1e6 << " um/s";
}

TEST_P(EngineContract, NoParticleCentreComesCloserToAWallThanItsRadius) {
  const ChannelRun& run = channelSeed1();
  const CentreBox& b = run.box;
  const double tol = GetParam().overlap_tolerance;
  int checked = 0;
  for (std::size_t k = 0; k < run.frames.size(); ++k)
    for (const Sample& s : run.frames[k]) {
      const std::string at = fmt::format("particle {} at t = {:g} s", s.id, run.times[k]);
      EXPECT_GE(s.x.y(), b.y0 - tol) << at;
      EXPECT_LE(s.x.y(), b.y1 + tol) << at;
      if (b.has_z) {
        EXPECT_GE(s.x.z(), b.z0 - tol) << at;
        EXPECT_LE(s.x.z(), b.z1 + tol) << at;
      }
      ++checked;
    }
  EXPECT_GE(checked, 4);
}

TEST_P(EngineContract, CountsBalanceAtEveryOutputAndMatchTheParticles) {
  const ChannelRun& run = channelSeed1();
  ASSERT_FALSE(run.counts.empty());
  for (std::size_t k = 0; k < run.counts.size(); ++k) {
    const Counts& c = run.counts[k];
    const std::string at = fmt::format("t = {:g} s: injected {} inside {} deposited {} left {}", run.times[k], c.injected, c.inside, c.deposited, c.left);
    EXPECT_EQ(c.injected, run.inserted) << at;
    EXPECT_EQ(c.injected, c.inside + c.deposited + c.left) << at;
    // The counts are those of the particle list: deposited and mobile ones present, the others gone.
    std::int64_t deposited = 0;
    std::set<std::int64_t> ids;
    for (const Sample& s : run.frames[k]) {
      deposited += s.deposited ? 1 : 0;
      ids.insert(s.id);
    }
    EXPECT_EQ(ids.size(), run.frames[k].size()) << at << ": a particle listed twice";
    EXPECT_EQ(deposited, c.deposited) << at;
    EXPECT_EQ(static_cast<std::int64_t>(ids.size()), c.inside + c.deposited) << at;
  }
  // The scene is built so that every way out is taken: a count that stays 0 would test nothing.
  const Counts& last = run.counts.back();
  EXPECT_GT(last.deposited, 0);
  EXPECT_GT(last.left, 0);
}

TEST_P(EngineContract, SameSeedGivesTheSameRun) {
  const ChannelRun& a = channelSeed1();
  const ChannelRun b = GetParam().channel(1);
  ASSERT_EQ(a.frames.size(), b.frames.size());
  for (std::size_t k = 0; k < a.frames.size(); ++k) {
    ASSERT_EQ(a.frames[k].size(), b.frames[k].size()) << "output " << k;
    for (std::size_t i = 0; i < a.frames[k].size(); ++i) {
      // Bit for bit: one rank, the same seed and the same operations in the same order.
      EXPECT_EQ(a.frames[k][i].id, b.frames[k][i].id);
      for (int d = 0; d < 3; ++d) EXPECT_EQ(a.frames[k][i].x[d], b.frames[k][i].x[d]) << "output " << k << " particle " << a.frames[k][i].id;
    }
  }
  if (!GetParam().stochastic) return;
  // With Brownian motion the seed must matter: another seed moves some particle elsewhere.
  const ChannelRun c = GetParam().channel(2);
  double largest = 0;
  for (std::size_t k = 0; k < std::min(a.frames.size(), c.frames.size()); ++k)
    for (std::size_t i = 0; i < std::min(a.frames[k].size(), c.frames[k].size()); ++i) largest = std::max(largest, (a.frames[k][i].x - c.frames[k][i].x).norm());
  EXPECT_GT(largest, 0.0);
}

INSTANTIATE_TEST_SUITE_P(Engines, EngineContract, ::testing::ValuesIn(engineTable()),
                         [](const ::testing::TestParamInfo<EngineEntry>& info) { return info.param.name; });

}  // namespace
}  // namespace mmval::particles
