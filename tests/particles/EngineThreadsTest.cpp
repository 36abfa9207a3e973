// The overdamped engine on several threads (numerics.threads; OverdampedEngine.hpp, "Threads"): the
// reference is the engine on one thread. A porous scene (grains on a 10 um grid, gaps narrower
// than the particles that strain them, Brownian motion, settling, plate attachment with draws,
// deposits that later particles touch) with a few hundred particles run on 1, 2 and 3 threads
// gives the same positions, velocities and statuses bit for bit at every output time (tolerance
// zero), and the particles-channel kind writes byte-identical trajectories and retention tables
// on 1 and 2 threads. A bad thread count is an InputError naming numerics.threads.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/particles/OverdampedEngine.hpp"
#include "GridField.hpp"
#include "KindTestFiles.hpp"
#include "ParticleRegistry.hpp"

namespace mmval::particles {
namespace {

constexpr int kNx = 80, kNy = 30;  // nodes 10 um apart: 800 x 300 um
constexpr double kDepth = 30e-6, kDiameter = 12e-6;

/// Solid nodes: the side walls (rows 0 and ny - 1) and a scatter of single nodes
/// (6 % of the nodes, by a hash), none in the first and last five columns. Gaps of one node (10 um) are
/// narrower than the 12 um particles.
bool solidNode(int i, int j) {
  if (j == 0 || j == kNy - 1) return true;
  if (i < 5 || i >= kNx - 5) return false;
  const std::uint32_t h = (static_cast<std::uint32_t>(i) * 73856093u) ^ (static_cast<std::uint32_t>(j) * 19349663u);
  return (h >> 7) % 100 < 6;
}

SceneConfig scene(int threads, int substeps = 1) {
  SceneConfig c;
  c.particle.diameter = kDiameter;
  c.particle.density = 1050;
  c.max_step_fraction = 0.5;
  c.attachment.grains = false;  // held at the narrow gaps: straining, not attachment to the grains
  c.attachment.deposited = false;  // deposits only obstacles: more particles stay mobile
  c.attachment.plate_efficiency = 0.05;
  c.straining.time = 0.05;
  c.seed = 7;
  c.threads = threads;
  c.substeps = substeps;
  return c;
}

/// Particles on a lattice of the pore space (3 diameters apart in x, 2 in y, two heights) where
/// insertionProblem allows them, up to `n`.
std::vector<Vec3> startPositions(const FlowField& flow, std::size_t n) {
  return test_support::latticeStarts(flow, n, kDiameter, kDepth, {3 * kDiameter, 2 * kDiameter, 790e-6, 10e-6, 290e-6, 1e-6});
}

struct ThreadRun {
  std::vector<std::vector<ParticleState>> frames;
  EngineStats stats;
  int threads = 0;
  std::int64_t max_mobile = 0;
};

ThreadRun runScene(int threads, int substeps = 1) {
  auto flow = test_support::gridField(kNx, kNy, 400e-6, kDepth, solidNode);
  OverdampedEngine e(flow, scene(threads, substeps));
  e.insert(startPositions(*flow, 300));
  ThreadRun r;
  r.threads = e.threads();
  for (int k = 1; k <= 40; ++k) {
    r.max_mobile = std::max(r.max_mobile, e.counts().inside);
    e.advance(0.05 * k);
    r.frames.push_back(e.particles());
  }
  r.stats = e.stats();
  return r;
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expectIdentical(const ThreadRun& one, const ThreadRun& many) {
  ASSERT_EQ(one.frames.size(), many.frames.size());
  EXPECT_EQ(one.stats.steps, many.stats.steps);
  EXPECT_EQ(one.stats.particle_steps, many.stats.particle_steps);
  std::size_t differing = 0;
  for (std::size_t f = 0; f < one.frames.size(); ++f) {
    ASSERT_EQ(one.frames[f].size(), many.frames[f].size());
    for (std::size_t i = 0; i < one.frames[f].size(); ++i) {
      const ParticleState &p = one.frames[f][i], &q = many.frames[f][i];
      bool same = p.status == q.status && p.held_by == q.held_by && p.secondary == q.secondary && sameBits(p.t_event, q.t_event);
      for (int d = 0; d < 3; ++d) same = same && sameBits(p.x[d], q.x[d]) && sameBits(p.v[d], q.v[d]);
      differing += same ? 0 : 1;
    }
  }
  EXPECT_EQ(differing, 0u) << "particle states (over all frames) that differ from one thread's on " << many.threads << " threads";
}

TEST(EngineThreads, TwoAndThreeThreadsGiveOneThreadsParticlesBitForBit) {
  const ThreadRun one = runScene(1), two = runScene(2), three = runScene(3);
  EXPECT_EQ(one.threads, 1);
  EXPECT_EQ(two.threads, 2);
  EXPECT_EQ(three.threads, 3);
  // The scene exercises what threads could break: many mobile particles (the loops split), Brownian
  // draws, straining at the narrow gaps, plate attachment, particles leaving.
  EXPECT_GE(one.max_mobile, 200);
  ASSERT_GE(static_cast<std::int64_t>(OverdampedEngine::kMinParallelMobile), 1);
  std::int64_t strained = 0, attached = 0, left = 0, mobile = 0;
  for (const auto& p : one.frames.back()) {
    strained += p.status == ParticleStatus::deposited && p.held_by == Surface::strained;
    attached += p.status == ParticleStatus::deposited && p.held_by != Surface::strained;
    left += p.status == ParticleStatus::left;
    mobile += p.status == ParticleStatus::mobile;
  }
  EXPECT_GT(strained, 0);
  EXPECT_GT(attached, 0);
  EXPECT_GT(left, 0);
  // At least a quarter of the run has enough mobile particles for the loops to be split.
  int split = 0;
  for (const auto& f : one.frames)
    split += std::count_if(f.begin(), f.end(), [](const ParticleState& p) { return p.status == ParticleStatus::mobile; }) >=
             static_cast<std::ptrdiff_t>(OverdampedEngine::kMinParallelMobile);
  EXPECT_GE(split, 10);
  EXPECT_GT(mobile, 0);
  expectIdentical(one, two);
  expectIdentical(one, three);
}

// Per-particle steps (numerics.substeps = 8): each particle's substeps, its Brownian draws (taken
// before the moves, in mobile order, 3 per substep) and its checks against the places of the others
// before the step are its own, so two threads give one thread's particles bit for bit here too;
// the scene takes fewer particle steps than with one step for all.
TEST(EngineThreads, TwoThreadsGiveOneThreadsParticlesWithSubsteps) {
  const ThreadRun one = runScene(1, 8), two = runScene(2, 8), plain = runScene(1);
  EXPECT_LT(one.stats.steps, plain.stats.steps / 2);
  EXPECT_LT(one.stats.particle_steps, plain.stats.particle_steps);
  expectIdentical(one, two);
}

TEST(EngineThreads, AutoTakesTwoToEightThreads) {
  auto flow = test_support::gridField(kNx, kNy, 400e-6, kDepth, solidNode);
  ASSERT_EQ(std::getenv(kAutoThreadsVariable), nullptr) << "the test's environment sets " << kAutoThreadsVariable;
  const OverdampedEngine e(flow, scene(0));
  EXPECT_GE(e.threads(), 2);
  EXPECT_LE(e.threads(), 8);
  EXPECT_EQ(e.describe().at("threads"), e.threads());
}

// mmval sweep --jobs N gives each run its share of the cores (kAutoThreadsVariable): "auto" takes
// it when it is a whole thread count, and ignores anything else; an explicit count ignores it.
TEST(EngineThreads, AutoTakesTheShareASweepGivesItsRuns) {
  auto flow = test_support::gridField(kNx, kNy, 400e-6, kDepth, solidNode);
  const auto autoWith = [&](const char* share, int threads = 0) {
    ::setenv(kAutoThreadsVariable, share, 1);
    const int n = OverdampedEngine(flow, scene(threads)).threads();
    ::unsetenv(kAutoThreadsVariable);
    return n;
  };
  EXPECT_EQ(autoWith("1"), 1);
  EXPECT_EQ(autoWith("3"), 3);
  EXPECT_EQ(autoWith("2", 5), 5);
  const int plain = OverdampedEngine(flow, scene(0)).threads();
  for (const char* ignored : {"0", "-1", "x", "2.5", "", "65"}) EXPECT_EQ(autoWith(ignored), plain) << "'" << ignored << "'";
}

TEST(EngineThreads, ABadThreadCountIsAnInputErrorNamingTheKey) {
  auto flow = test_support::gridField(kNx, kNy, 400e-6, kDepth, solidNode);
  for (const int bad : {-1, OverdampedEngine::kMaxThreads + 1}) {
    try {
      const OverdampedEngine e(flow, scene(bad));
      ADD_FAILURE() << "threads " << bad << " accepted";
    } catch (const InputError& err) {
      EXPECT_EQ(err.where().key, "numerics.threads");
    }
  }
  // In a case file: out of range, and not an integer.
  for (const char* value : {"-2", "\"two\"", "1.5"}) {
    const std::string text = std::string("[case]\nname = \"t\"\nkind = \"particles-channel\"\n[numerics]\nthreads = ") + value + "\n";
    try {
      (void)Case::parse(text, "cases/threads-test.toml", test_support::particleRegistry());
      ADD_FAILURE() << "numerics.threads = " << value << " accepted";
    } catch (const InputError& err) {
      EXPECT_EQ(err.where().key, "numerics.threads") << value;
    }
  }
}

constexpr const char* kChannel = R"(
[case]
name = "particles-channel-threads"
kind = "particles-channel"
[channel]
length = "300 um"
width = "100 um"
[particles]
count = 64
injection_time = "0.001 s"
[run]
duration = "0.004 s"
output_interval = "0.001 s"
[numerics]
threads = )";

TEST(EngineThreads, ChannelKindWritesTheSameTablesOnOneAndTwoThreads) {
  test_support::KindRunner runner("engine_threads");
  runner.run(std::string(kChannel) + "1\n", "one");
  runner.run(std::string(kChannel) + "2\n", "two");
  const auto dir = test_support::kindTestDir("engine_threads");
  for (const char* table : {"trajectories.csv", "retention.csv"}) {
    const std::string a = test_support::readText(dir / "one" / table), b = test_support::readText(dir / "two" / table);
    EXPECT_FALSE(a.empty()) << table;
    EXPECT_TRUE(a == b) << table << " differs between 1 and 2 threads";
  }
  EXPECT_NE(test_support::readText(dir / "two" / "result.json").find("\"threads\": 2"), std::string::npos);
}

}  // namespace
}  // namespace mmval::particles
