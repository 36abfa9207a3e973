// The particles-resolved case kind (resolved immersed-boundary coupling) end to end on small scenes.
#include <gtest/gtest.h>

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>


#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/Tracks.hpp"
#include "ParticleRegistry.hpp"
#include "mmval/core/Checkpoint.hpp"
#include "mmval/particles/Kinds.hpp"
#include "mmval/particles/Micromodel.hpp"
#include "mmval/simulate/Geometry.hpp"

#include "../TestScratch.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

CaseKindRegistry& registry() { return test_support::particleRegistry(); }

/// This process's own scratch folder: test binaries of other checkouts may run at the same time.
fs::path scratch() { return mmval::test::scratch("resolved"); }

RunOutput run(const std::string& text, const std::string& name) {
  const Case c = Case::parse(text, "cases/" + name + ".toml", registry());
  const fs::path out = scratch() / name;
  fs::remove_all(out);
  fs::create_directories(out);
  RunContext ctx;
  ctx.out_dir = out;
  ctx.quiet = true;
  return registry().find("particles-resolved")->run(c, ctx);
}

constexpr const char* kSettling = R"(
[case]
name = "settling"
kind = "particles-resolved"
[channel]
length = "100 um"
width = "40 um"
[particles]
diameter = "10 um"
x = ["50 um"]
y = ["20 um"]
[physics]
gravity_x = "-9.81 m/s2"
[numerics]
cells_per_diameter = 12
max_step_fraction = 1.0
[run]
duration = "1 s"
output_interval = "0.5 s"
)";

TEST(ResolvedKind, SettlingDiskMatchesFaxenBetweenPlates) {
  // 10 um polystyrene disk midway between plates 40 um apart: Faxen's series (a/l = 0.25) gives
  // the terminal velocity; measured 1.0046 of it with 12 cells per diameter in a 100 um box.
  const RunOutput r = run(kSettling, "settling");
  EXPECT_NEAR(r.metrics.at("faxen_velocity_ratio"), 1.0, 0.01);
  EXPECT_LT(r.metrics.at("final_velocity_x"), 0.0);
  EXPECT_LT(std::abs(r.metrics.at("final_velocity_y")), 1e-3 * std::abs(r.metrics.at("final_velocity_x")));
}

TEST(ResolvedKind, MirrorPairMovesSymmetricallyAndDeterministically) {
  // Two disks placed symmetrically about the centre line of a Poiseuille flow: creeping flow keeps
  // the mirror symmetry (y1 - W/2 = -(y2 - W/2)) and neither drifts across (Stokes reversibility).
  const std::string text = R"(
[case]
name = "mirror"
kind = "particles-resolved"
[channel]
length = "100 um"
width = "40 um"
mean_velocity = "0.05 mm/s"
[particles]
diameter = "8 um"
x = ["20 um", "20 um"]
y = ["12 um", "28 um"]
[numerics]
cells_per_diameter = 8
max_step_fraction = 1.0
[run]
duration = "0.4 s"
output_interval = "0.2 s"
)";
  run(text, "mirror");
  const Tracks a = readTracksCsv(scratch() / "mirror" / "trajectories.csv");
  run(text, "mirror");
  const Tracks b = readTracksCsv(scratch() / "mirror" / "trajectories.csv");
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t k = 0; k < a.points.size(); ++k) {
    EXPECT_EQ(a.points[k].x, b.points[k].x);
    EXPECT_EQ(a.points[k].y, b.points[k].y);
  }
  // Points are sorted by particle, then frame: particle 0's frames first.
  const std::size_t n = a.points.size() / 2;
  ASSERT_EQ(n * 2, a.points.size());
  for (std::size_t k = 0; k < n; ++k) {
    const auto& p = a.points[k];
    const auto& q = a.points[n + k];
    EXPECT_NEAR(p.x, q.x, 1e-9) << "frame " << p.frame;
    EXPECT_NEAR(p.y - 20e-6, -(q.y - 20e-6), 1e-9) << "frame " << p.frame;
    EXPECT_NEAR(p.y, a.points[0].y, 0.05e-6) << "no lateral drift";
  }
  EXPECT_GT(a.points[n - 1].x, a.points[0].x + 10e-6);  // carried downstream
}

/// A channel 40 um wide with one grain on its centre line, creeping inflow, every surface sticky within 0.5 um.
std::string grainChannel(const std::string& length, const std::string& diameter, const std::string& xs, const std::string& ys,
                         const std::string& grain_x, const std::string& grain_d, const std::string& run_table) {
  return fmt::format(R"(
[case]
name = "grain-channel"
kind = "particles-resolved"
[channel]
length = "{}"
width = "40 um"
mean_velocity = "0.05 mm/s"
[particles]
diameter = "{}"
x = [{}]
y = [{}]
[obstacles]
x = ["{}"]
y = ["20 um"]
diameter = ["{}"]
[deposition]
capture_distance = "0.5 um"
[numerics]
cells_per_diameter = 8
max_step_fraction = 1.0
[run]
{}
)",
                     length, diameter, xs, ys, grain_x, grain_d, run_table);
}

TEST(ResolvedKind, DepositOnAnObstacleLowersThePermeability) {
  // A disk on the centre line meets a fixed obstacle and sticks in front of it: a fixed body more in
  // the flow, so the pressure drop rises (four-way coupling).
  const RunOutput r = run(grainChannel("80 um", "8 um", "\"15 um\"", "\"20 um\"", "45 um", "12 um", "duration = \"2 s\"\noutput_interval = \"0.5 s\""),
                          "deposit");
  EXPECT_EQ(r.metrics.at("deposited"), 1);
  EXPECT_EQ(r.metrics.at("inside"), 0);
  EXPECT_LT(r.metrics.at("k_over_k0"), 0.97);
  EXPECT_GT(r.metrics.at("k_over_k0"), 0.3);
}

TEST(ResolvedKind, ResumeAfterAStopEqualsTheUninterruptedRun) {
  // Three particles meet a grain and deposit between 0.5 and 0.75 s: stopped at frame 2 (0.5 s),
  // resumed from the checkpoint, the outputs must be the uninterrupted run's, byte for byte.
  const std::string text = grainChannel("120 um", "10 um", "\"15 um\", \"15 um\", \"32 um\"", "\"20.5 um\", \"33 um\", \"9 um\"", "60 um", "16 um",
                                         "duration = \"1 s\"\noutput_interval = \"0.25 s\"\ncheckpoint_every = 1");
  const fs::path dir = scratch() / "resume";
  fs::remove_all(dir);
  const Case whole = Case::parse(text, dir / "whole.toml", registry());
  runCase(whole, registry(), dir / "whole", {.quiet = true});
  const Case stopped = Case::parse(text + "stop_after_frames = 2\n", dir / "cut.toml", registry());
  EXPECT_THROW(runCase(stopped, registry(), dir / "cut", {.quiet = true}), RunStopped);
  ASSERT_TRUE(fs::exists(dir / "cut.partial" / "checkpoint.json"));
  const Case again = Case::parse(text, dir / "cut.toml", registry());
  const RunSummary r = runCase(again, registry(), dir / "cut", {.quiet = true, .resume = true});
  EXPECT_EQ(r.result["details"]["resumed_from_frame"].get<long long>(), 2);
  for (const char* f : {"trajectories.csv", "retention.csv", "permeability.csv"})
    EXPECT_EQ(readBinaryFile(dir / "whole" / f), readBinaryFile(dir / "cut" / f)) << f;
  // Deposits on both sides of the stop: fewer than 3 at frame 2, all 3 at the end.
  const std::vector<double> deposited =
      tables::parseTable(readBinaryFile(dir / "whole" / "permeability.csv"), "permeability.csv").at("deposited");
  ASSERT_EQ(deposited.size(), 5u);
  EXPECT_LT(deposited[2], 3);
  EXPECT_EQ(deposited.back(), 3);
}

TEST(ResolvedKind, BadInputIsNamed) {
  const std::string base = R"(
[case]
name = "bad"
kind = "particles-resolved"
[channel]
length = "100 um"
width = "40 um"
[particles]
diameter = "10 um"
)";
  // Two particles overlapping.
  try {
    run(base + "x = [\"50 um\", \"55 um\"]\ny = [\"20 um\", \"20 um\"]\n", "bad1");
    FAIL() << "overlap accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("particles.x"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("overlaps"), std::string::npos) << e.what();
  }
  // A particle wider than the channel.
  try {
    run(base + "x = [\"50 um\"]\ny = [\"20 um\"]\n[numerics]\ncells_per_diameter = 4\n" , "bad-ok");
  } catch (const std::exception& e) {
    FAIL() << "a valid coarse case was refused: " << e.what();
  }
  try {
    run(R"(
[case]
name = "bad2"
kind = "particles-resolved"
[channel]
width = "10 um"
[particles]
diameter = "10 um"
y = ["5 um"]
)",
        "bad2");
    FAIL() << "a particle as wide as the channel was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("channel.width"), std::string::npos) << e.what();
  }
  // A grid the direct solver cannot hold: a 5 mm channel at 32 cells per 10 um particle.
  try {
    run(R"(
[case]
name = "bad4"
kind = "particles-resolved"
[channel]
length = "5000 um"
width = "2000 um"
[particles]
diameter = "10 um"
x = ["50 um"]
y = ["50 um"]
[numerics]
cells_per_diameter = 32
)",
        "bad4");
    FAIL() << "a 1e8-cell grid was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("numerics.cells_per_diameter"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("geometry.crop"), std::string::npos) << e.what();
  }
  // Lists of different lengths.
  try {
    run(base + "x = [\"50 um\", \"80 um\"]\ny = [\"20 um\"]\n", "bad3");
    FAIL() << "unpaired coordinates accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("particles.y"), std::string::npos) << e.what();
  }
}

std::string chipCase(const std::string& x, const std::string& y, const std::string& extra = "") {
  const fs::path mask = fs::path(MMVAL_SHARED_DATA_DIR) / "pore2chip" / "grain_network.png";
  return fmt::format(R"(
[case]
name = "chip"
kind = "particles-resolved"
[geometry]
mask = "{}"
pixel_size = "1 um"
crop = [0, 90, 180, 140]
[channel]
mean_velocity = "0.05 mm/s"
[particles]
diameter = "12 um"
x = [{}]
y = [{}]
[numerics]
cells_per_diameter = 5
max_step_fraction = 1.0
[run]
duration = "1.2 s"
output_interval = "0.1 s"
{}
)",
                     mask.string(), x, y, extra);
}

TEST(ResolvedKind, ParticlesInTheChipImageNeverEnterAGrain) {
  // Two non-sticky particles through a window of the Pore2Chip mask: one slides along a grain
  // on its way to the throat. At every output its disk must stay clear of every grain pixel
  // (by half the one-cell contact gap at least), checked against the image itself.
  run(chipCase("\"12 um\", \"12 um\"", "\"45 um\", \"70 um\""), "chip");
  const Tracks t = readTracksCsv(scratch() / "chip" / "trajectories.csv");
  auto mask = simulate::readMask(fs::path(MMVAL_SHARED_DATA_DIR) / "pore2chip" / "grain_network.png", true);
  const Eigen::Array<bool, Eigen::Dynamic, Eigen::Dynamic> win = mask.block(90, 0, 140, 180);
  const double px = 1e-6, a = 6e-6, gap = 2.4e-6;  // one cell: 12/5 um
  double worst = 1e300, moved = 0;
  for (const auto& p : t.points) {
    for (int r = 0; r < win.rows(); ++r)
      for (int c = 0; c < win.cols(); ++c) {
        if (!win(r, c)) continue;
        const double lx = c * px, ly = (win.rows() - r - 1) * px;
        const double qx = std::clamp(p.x, lx, lx + px), qy = std::clamp(p.y, ly, ly + px);
        worst = std::min(worst, std::hypot(p.x - qx, p.y - qy) - a);
      }
    moved = std::max(moved, p.x - 12e-6);
  }
  std::printf("closest approach %.3f um, moved %.1f um\n", worst * 1e6, moved * 1e6);
  EXPECT_GT(worst, 0.5 * gap) << "closest approach to a grain " << worst * 1e6 << " um";
  EXPECT_GT(moved, 30e-6) << "the particles should travel into the window";
}

TEST(ResolvedKind, ParticleInsideAGrainIsNamed) {
  try {
    run(chipCase("\"60 um\"", "\"60 um\""), "chip-bad");  // inside the lower large grain
    FAIL() << "a particle inside a grain was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("particles.x"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("grain"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace mmval::particles
