// cases/particles-*.toml load, run and meet their own acceptance entries.
#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>

#include "mmval/core/Case.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/particles/Kinds.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

TEST(ParticleCases, ChannelCaseRunsAndPasses) {
  CaseKindRegistry reg;
  registerParticleKinds(reg);
  const Case c = Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / "particles-channel.toml", reg);
  const fs::path out = fs::path(MMVAL_BINARY_DIR) / "tests" / "particles" / "particles-channel-run";
  const RunSummary s = runCase(c, reg, out, {.quiet = true});
  for (const auto& m : s.metrics)
    std::cout << m.name << " = " << m.value << " " << m.unit << (m.pass ? (*m.pass ? "  PASS" : "  FAIL") : "") << "\n";
  std::cout << s.result["details"].dump(1).substr(0, 4000) << "\n";
  EXPECT_TRUE(s.all_pass);
  EXPECT_TRUE(fs::exists(out / "trajectories.csv"));
  EXPECT_TRUE(fs::exists(out / "retention.csv"));
}

}  // namespace
}  // namespace mmval::particles
