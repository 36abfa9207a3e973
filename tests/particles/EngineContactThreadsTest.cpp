// The overdamped engine's contact step on several threads (OverdampedEngine.hpp, "Threads"): after
// the contact sweeps each particle's undo of a push into a grain, its back-out of deposits, its
// attachment (dlvo rule: arrival draws, secondary-minimum wells, release distances) and its straining
// clock run on the threads; only the overlap check of new deposits stays in mobile order. The
// reference is the engine on one thread: a porous scene where particles attach to grains and plates,
// touch deposits, translate in secondary minima, strain at gaps no wider than themselves and cross a
// patch shallower than a diameter (where the plates' clamp of the contact sweeps moves them), run
// on 1, 2 and 3 threads, gives the same particle states bit for bit at every output time (tolerance
// zero). A relative change of 1e-15 in x on threads other than the first after the contact sweeps
// makes 9,585-11,999 of the 12,000 particle states differ (checked 2026-12-06).
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <vector>

#include "mmval/particles/OverdampedEngine.hpp"
#include "GridField.hpp"

namespace mmval::particles {
namespace {

constexpr int kNx = 60, kNy = 24;  // nodes 10 um apart: 600 x 240 um
constexpr double kDepth = 24e-6, kDiameter = 10e-6;

/// Side walls (rows 0 and ny - 1) and 8 % of the other nodes solid (a hash), none in the first and
/// last five columns: one-node gaps (10 um) are no wider than the particles.
bool solidNode(int i, int j) {
  if (j == 0 || j == kNy - 1) return true;
  if (i < 5 || i >= kNx - 5) return false;
  const std::uint32_t h = (static_cast<std::uint32_t>(i) * 2654435761u) ^ (static_cast<std::uint32_t>(j) * 40503u);
  return (h >> 9) % 100 < 8;
}

/// The grid with a patch of nodes 9 um deep (below the 10 um diameter) in the middle of the strip.
std::shared_ptr<GriddedFlow> field() {
  auto g = test_support::gridField(kNx, kNy, 300e-6, kDepth, solidNode);
  const auto n = static_cast<std::size_t>(kNx) * kNy;
  std::vector<double> u(n), v(n, 0.0), h(n, kDepth);
  std::vector<std::uint8_t> s(n, 0);
  for (int j = 0; j < kNy; ++j)
    for (int i = 0; i < kNx; ++i) {
      const auto k = static_cast<std::size_t>(j) * kNx + i;
      s[k] = solidNode(i, j) ? 1 : 0;
      u[k] = s[k] ? 0.0 : 300e-6;
      if (i >= 30 && i <= 31 && j >= 10 && j <= 12) h[k] = 9e-6;
    }
  g->update(u, v, h, s);
  return g;
}

SceneConfig scene(int threads) {
  SceneConfig c;
  c.particle.diameter = kDiameter;
  c.particle.density = 1050;
  c.max_step_fraction = 0.5;
  // DLVO attachment at 30 mM: a secondary minimum that catches some arrivals, which then translate
  // along the surface until the shear lets the well hold them; primary attachment for a few.
  c.attachment.rule = AttachmentModel::Rule::dlvo;
  c.attachment.chemistry.electrolyte.ionic_strength = 30.0;
  c.attachment.chemistry.electrolyte.temperature = c.fluid.temperature;
  c.attachment.favourable_fraction = 0.03;
  c.straining.time = 0.05;
  c.seed = 11;
  c.threads = threads;
  return c;
}

/// Particles on a lattice of the pore space (2.5 diameters apart in x, 1.5 in y, two heights) where
/// insertionProblem allows them, up to `n`.
std::vector<Vec3> startPositions(const FlowField& flow, std::size_t n) {
  return test_support::latticeStarts(flow, n, kDiameter, kDepth, {2.5 * kDiameter, 1.5 * kDiameter, 590e-6, 10e-6, 230e-6, 0.5e-6});
}

struct SceneRun {
  std::vector<std::vector<ParticleState>> frames;
  EngineStats stats;
  int threads = 0;
  std::int64_t split_frames = 0;  ///< frames with enough mobile particles for the loops to be split
  std::int64_t translating = 0;   ///< mobile particles in a secondary well, summed over the frames
  std::int64_t touching = 0;      ///< mobile particles in contact with a deposit, summed over the frames
};

SceneRun runScene(int threads) {
  const auto flow = field();
  OverdampedEngine e(flow, scene(threads));
  e.insert(startPositions(*flow, 400));
  SceneRun r;
  r.threads = e.threads();
  for (int k = 1; k <= 30; ++k) {
    e.advance(0.04 * k);
    r.frames.push_back(e.particles());
    std::int64_t mobile = 0;
    for (const auto& p : r.frames.back())
      if (p.status == ParticleStatus::mobile) {
        ++mobile;
        r.translating += p.secondary ? 1 : 0;
      }
    r.split_frames += mobile >= static_cast<std::int64_t>(OverdampedEngine::kMinParallelMobile);
    const auto& f = r.frames.back();
    for (const auto& p : f) {
      if (p.status != ParticleStatus::mobile) continue;
      r.touching += std::any_of(f.begin(), f.end(), [&](const ParticleState& q) {
        return q.status == ParticleStatus::deposited && (q.x - p.x).norm() < 1.01 * kDiameter;
      });
    }
  }
  r.stats = e.stats();
  return r;
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void expectIdentical(const SceneRun& one, const SceneRun& many) {
  ASSERT_EQ(one.frames.size(), many.frames.size());
  EXPECT_EQ(one.stats.steps, many.stats.steps);
  EXPECT_EQ(one.stats.particle_steps, many.stats.particle_steps);
  std::size_t differing = 0;
  for (std::size_t f = 0; f < one.frames.size(); ++f) {
    ASSERT_EQ(one.frames[f].size(), many.frames[f].size());
    for (std::size_t i = 0; i < one.frames[f].size(); ++i) {
      const ParticleState &p = one.frames[f][i], &q = many.frames[f][i];
      bool same = p.status == q.status && p.held_by == q.held_by && p.secondary == q.secondary && p.arrivals == q.arrivals &&
                  p.rejected == q.rejected && sameBits(p.t_event, q.t_event) && sameBits(p.pinned_since, q.pinned_since);
      for (int d = 0; d < 3; ++d) same = same && sameBits(p.x[d], q.x[d]) && sameBits(p.v[d], q.v[d]);
      differing += same ? 0 : 1;
    }
  }
  EXPECT_EQ(differing, 0u) << "particle states (over all frames) that differ from one thread's on " << many.threads << " threads";
}

TEST(EngineContactThreads, AttachmentStrainingAndContactsOnTwoAndThreeThreadsAreOneThreadsBitForBit) {
  const SceneRun one = runScene(1), two = runScene(2), three = runScene(3);
  EXPECT_EQ(two.threads, 2);
  EXPECT_EQ(three.threads, 3);
  // What the scene must exercise for the comparison to mean something.
  std::int64_t strained = 0, on_glass = 0, left = 0, shallow = 0;
  for (const auto& p : one.frames.back()) {
    strained += p.status == ParticleStatus::deposited && p.held_by == Surface::strained;
    on_glass += p.status == ParticleStatus::deposited && (p.held_by == Surface::grain || p.held_by == Surface::bottom || p.held_by == Surface::top);
    left += p.status == ParticleStatus::left;
  }
  for (const auto& f : one.frames)
    for (const auto& p : f) shallow += p.status != ParticleStatus::left && p.x.x() > 295e-6 && p.x.x() < 315e-6 && p.x.y() > 95e-6 && p.x.y() < 125e-6;
  EXPECT_GT(strained, 0);
  EXPECT_GT(one.touching, 0) << "no mobile particle touching a deposit: contacts with deposits not exercised";
  EXPECT_GT(on_glass, 0);
  EXPECT_GT(left, 0);
  EXPECT_GT(one.translating, 0) << "no particle translating in a secondary minimum";
  EXPECT_GT(shallow, 0) << "no particle over the patch shallower than a diameter";
  EXPECT_GE(one.split_frames, 10);
  expectIdentical(one, two);
  expectIdentical(one, three);
}

}  // namespace
}  // namespace mmval::particles
