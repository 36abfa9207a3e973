// Resuming the unsteady cylinder (cylinder-channel, mmval's BDF2 solver) after an interruption
// at a random time step, on 1 MPI rank: forces.csv of the resumed run must be byte-identical to
// the uninterrupted run's (a restart that refactorises the lagged LU instead of rebuilding
// it diverges from step 70, c_L amplitude -0.5 %). The interruption is the
// run.stop_after_steps hook, which writes the checkpoint a kill would have left behind and
// stops as if killed; `mmval run --resume` then continues from it.
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

#include "mmval/core/Checkpoint.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/Kinds.hpp"

#include "../TestScratch.hpp"
#include "FluidRegistry.hpp"

namespace fs = std::filesystem;
using namespace mmval;

namespace {

const CaseKindRegistry& registry() { return test_support::fluidRegistry(); }

std::string bytesOf(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::stringstream b;
  b << in.rdbuf();
  return b.str();
}

/// Line number (1-based) of the first difference of two texts, 0 if equal.
std::size_t firstDifferentLine(const std::string& a, const std::string& b) {
  std::istringstream ia(a), ib(b);
  std::string la, lb;
  for (std::size_t n = 1;; ++n) {
    const bool ga = static_cast<bool>(std::getline(ia, la)), gb = static_cast<bool>(std::getline(ib, lb));
    if (!ga && !gb) return 0;
    if (ga != gb || la != lb) return n;
  }
}

}  // namespace

TEST(UnsteadyResume, ForcesAreByteIdenticalAfterAStopAtARandomStep) {
  // The 2D-2 case at cells_around 16 (the validation tier's short case), 0.3 s: ~60 steps, with
  // the lagged LU refactorised a few times on the way, so a random stop falls between
  // refactorisations as often as on one. MMVAL_RESUME_SEED=<seed> replays a failure.
  Case c = Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / "fluid-schaefer-turek-2d2.toml", registry());
  c.set("numerics.cells_around", std::int64_t{16});
  c.set("numerics.end_time", 0.3);          // s
  c.set("numerics.statistics_from", 0.15);  // s
  const fs::path dir = mmval::test::scratch("mmval-unsteady-resume");
  fs::remove_all(dir);
  const RunSummary whole = runCase(c, registry(), dir / "whole", {.quiet = true});
  const long long steps = whole.result["details"]["time_steps"].get<long long>();
  ASSERT_GT(steps, 20);
  const char* env = std::getenv("MMVAL_RESUME_SEED");
  const unsigned seed = env != nullptr ? static_cast<unsigned>(std::strtoul(env, nullptr, 10)) : std::random_device{}();
  std::mt19937 gen(seed);
  const long long stop = std::uniform_int_distribution<long long>(1, steps - 1)(gen);
  std::printf("stop after step %lld of %lld (MMVAL_RESUME_SEED=%u)\n", stop, steps, seed);
  Case cut = c;
  cut.set("run.stop_after_steps", std::int64_t{stop});
  EXPECT_THROW(runCase(cut, registry(), dir / "cut", {.quiet = true}), RunStopped);
  ASSERT_TRUE(fs::exists(dir / "cut.partial" / "checkpoint.bin"));
  const RunSummary again = runCase(cut, registry(), dir / "cut", {.quiet = true, .resume = true});
  EXPECT_EQ(again.result["details"]["resumed_from_step"].get<long long>(), stop);
  EXPECT_EQ(again.result["details"]["time_steps"].get<long long>(), steps);
  const std::string a = bytesOf(dir / "whole" / "forces.csv"), b = bytesOf(dir / "cut" / "forces.csv");
  ASSERT_GT(a.size(), 1000U);
  EXPECT_EQ(a.size(), b.size());
  EXPECT_TRUE(a == b) << "forces.csv differs from line " << firstDifferentLine(a, b) << " (line 1 is the header; the stop was after step " << stop << ")";
  // The metrics come from the same history, so they are equal too (exactly, not to a tolerance).
  ASSERT_EQ(whole.metrics.size(), again.metrics.size());
  for (std::size_t k = 0; k < whole.metrics.size(); ++k) {
    EXPECT_EQ(whole.metrics[k].name, again.metrics[k].name);
    EXPECT_EQ(whole.metrics[k].value, again.metrics[k].value) << whole.metrics[k].name << ": difference " << again.metrics[k].value - whole.metrics[k].value;
  }
}

// An image-permeability ladder stopped after two of its three levels (run.stop_after_levels, as a
// kill or an out-of-memory finest level would leave it) and resumed: the two finished levels are
// taken from checkpoint-levels.json, only the third is solved, and the result equals the
// uninterrupted run's to the last bit. A changed numerical key refuses the checkpoint; a changed
// linear solver (which changes no level's answer beyond numerics.residual) does not.
TEST(LadderResume, AStoppedLadderKeepsItsLevelsAndEndsAsTheWholeRun) {
  Case c = Case::load(fs::path(MMVAL_SOURCE_DIR) / "cases" / "fluid-chip2-peer.toml", registry());
  c.set("numerics.cells_per_pixel_levels", std::vector<double>{0.5, 0.75, 1.0});
  const fs::path dir = mmval::test::scratch("mmval-ladder-resume");
  fs::remove_all(dir);
  const RunSummary whole = runCase(c, registry(), dir / "whole", {.quiet = true});
  EXPECT_FALSE(fs::exists(dir / "whole" / "checkpoint-levels.json"));
  EXPECT_EQ(whole.result["details"]["resumed_levels"].get<int>(), 0);

  Case cut = c;
  cut.set("run.stop_after_levels", std::int64_t{2});
  EXPECT_THROW(runCase(cut, registry(), dir / "cut", {.quiet = true}), RunStopped);
  ASSERT_TRUE(fs::exists(dir / "cut.partial" / "checkpoint-levels.json"));

  Case other = cut;  // a key that changes the answers: the checkpoint is refused, and kept
  other.set("numerics.residual", 1e-7);
  try {
    runCase(other, registry(), dir / "cut", {.quiet = true, .resume = true});
    ADD_FAILURE() << "a checkpoint of another version of the case was resumed";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("another version"), std::string::npos) << e.what();
  }
  ASSERT_TRUE(fs::exists(dir / "cut.partial" / "checkpoint-levels.json"));

  const RunSummary again = runCase(cut, registry(), dir / "cut", {.quiet = true, .resume = true});
  EXPECT_EQ(again.result["details"]["resumed_levels"].get<int>(), 2);
  EXPECT_FALSE(fs::exists(dir / "cut" / "checkpoint-levels.json"));
  const auto& a = whole.result["details"]["ladder"];
  const auto& b = again.result["details"]["ladder"];
  ASSERT_EQ(a.size(), 3U);
  ASSERT_EQ(b.size(), 3U);
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(a[i]["value"].get<double>(), b[i]["value"].get<double>()) << "level " << i;
    EXPECT_EQ(a[i]["level"], b[i]["level"]);
  }
  EXPECT_EQ(whole.result["details"]["grid_convergence"].dump(), again.result["details"]["grid_convergence"].dump());
  ASSERT_EQ(whole.metrics.size(), again.metrics.size());
  for (std::size_t i = 0; i < whole.metrics.size(); ++i) EXPECT_EQ(whole.metrics[i].value, again.metrics[i].value) << whole.metrics[i].name;

  // The linear-solver key may change between the stop and the resume ("auto" picks the direct
  // solve at this size, so the answer stays the same to the bit; the iterative solve takes ~600
  // iterations on this chip's 3 px throats, too slow for a test).
  EXPECT_THROW(runCase(cut, registry(), dir / "solver", {.quiet = true}), RunStopped);
  Case direct = cut;
  direct.set("numerics.linear_solver", std::string("direct"));
  const RunSummary switched = runCase(direct, registry(), dir / "solver", {.quiet = true, .resume = true});
  EXPECT_EQ(switched.result["details"]["resumed_levels"].get<int>(), 2);
  EXPECT_EQ(switched.metrics[0].value, whole.metrics[0].value);
  fs::remove_all(dir);
}
