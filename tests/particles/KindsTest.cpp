// The particles-channel case kind end to end on a small scene.
#include <gtest/gtest.h>

#include <filesystem>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/particles/Kinds.hpp"
#include "ParticleRegistry.hpp"

#include "../TestScratch.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

CaseKindRegistry& registry() { return test_support::particleRegistry(); }

constexpr const char* kCase = R"(
[case]
name = "particles-channel-test"
kind = "particles-channel"
[channel]
length = "300 um"
width = "100 um"
[particles]
count = 30
injection_time = "0.2 s"
[run]
duration = "0.6 s"
output_interval = "0.02 s"
)";

TEST(ParticleKinds, ChannelRunWritesTrajectoriesRetentionAndBalancedCounts) {
  const Case c = Case::parse(kCase, "cases/particles-channel-test.toml", registry());
  const fs::path out = mmval::test::scratch("mmval-particles-kind-test");
  fs::remove_all(out);
  fs::create_directories(out);
  RunContext ctx;
  ctx.out_dir = out;
  ctx.quiet = true;
  const RunOutput r = registry().find("particles-channel")->run(c, ctx);
  EXPECT_EQ(r.details["engine"], "overdamped");
  EXPECT_NE(r.details["engine_reason"].get<std::string>().find("St = "), std::string::npos);
  EXPECT_EQ(r.metrics.at("injected"), 30);
  EXPECT_EQ(r.metrics.at("count_balance_error"), 0);
  EXPECT_TRUE(fs::exists(out / "retention.csv"));
  const Tracks t = readTracksCsv(out / "trajectories.csv");
  EXPECT_GT(t.points.size(), 30u);
  EXPECT_TRUE(std::isfinite(t.points.front().z));
  // Particles spread over the depth move at the depth-averaged profile speed;
  // settling (0.7 um/s) and Brownian motion change it by < 5 % in 0.6 s.
  EXPECT_NEAR(r.metrics.at("mean_speed_ratio"), 1.0, 0.05);
}

TEST(ParticleKinds, ParticlesLargerThanTheDepthAreAnInputError) {
  Case c = Case::parse(kCase, "cases/particles-channel-test.toml", registry());
  c.set("particles.diameter", 25e-6);
  RunContext ctx;
  ctx.out_dir = mmval::test::scratch("mmval-particles-kind-test-bad");
  fs::create_directories(ctx.out_dir);
  EXPECT_THROW(registry().find("particles-channel")->run(c, ctx), InputError);
}

}  // namespace
}  // namespace mmval::particles
