// The parcel weight (real particles per simulated one, 1 / particles.sample_fraction with
// coupling.parcel_weighting on) and one-way coupling. The weight enters the deposit grid only
// (a deposit's volume, columns or plate layers), and a one-way run never writes that grid: its
// particles, their contacts and their straining are those of the unweighted run, byte for byte,
// whatever coupling.plate_deposits says. Four-way the same switch must change the run (so the
// comparison can fail). What does change a one-way run with the parcel count is the parcels'
// contacts with each other and with deposits, the real effect docs/validation/paper-scenes.md
// measures ("Why the short strip strains more than the full one").
//
// The scene: a 200 x 40 um channel (2 um pixels, 20 um deep) narrowing to a 4 um slot, narrower
// than the 5 um particles, so particles strain at it and the ones behind them strain on the
// deposits (a cake); particles attach only to the bottom plate (grains and deposits not sticky),
// so plate deposits are there too. Six runs, ~1 s of CPU.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>

#include "mmval/core/Case.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/particles/Kinds.hpp"

#include "KindTestFiles.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

constexpr const char* kGroup = "parcel-weight";
fs::path testDir() { return test_support::kindTestDir(kGroup); }
fs::path writePgm(const std::string& name, int cols, int rows, const std::function<bool(int, int)>& grain) {
  return test_support::writeTestMask(kGroup, name, cols, rows, grain);
}
using test_support::readText;

double metric(const RunSummary& s, const std::string& name) { return test_support::metricOf(s, name); }

struct Fixture : test_support::KindRunner {
  Fixture() : KindRunner(kGroup) {}
};

/// 100 x 20 px at 2 um; grains above and below a 2 px (4 um) slot at columns 60-69.
/// 60 particles over 3 s, sampled at 0.01 (each stands for 100 in the deposit volume when weighted).
std::string slotCase(const std::string& mode, bool weighting, const std::string& plate_deposits) {
  const fs::path mask = writePgm("slot.pgm", 100, 20, [](int c, int r) { return c >= 60 && c < 70 && (r < 9 || r >= 11); });
  return "[case]\nname = \"slot\"\nkind = \"particles-micromodel\"\n"
         "[geometry]\nmask = \"" + mask.string() + "\"\npixel_size = \"2 um\"\ndepth = \"20 um\"\n"
         "[flow]\nrate = \"5 uL/min\"\nrate_width = \"10 mm\"\n"
         "[particles]\ndiameter = \"5 um\"\ncount = 60\ninjection_time = \"3 s\"\nsample_fraction = 0.01\n"
         "[coupling]\nmode = \"" + mode + "\"\nparcel_weighting = " + (weighting ? "true" : "false") +
         "\nplate_deposits = \"" + plate_deposits + "\"\nresolve_threshold = 1e-3\n"
         "[deposition]\nstraining_time = \"0.2 s\"\nwalls = false\ndeposited = false\n"
         "[numerics]\ncells_per_pixel = 2\n"
         "[run]\nduration = \"3 s\"\noutput_interval = \"0.05 s\"\nseed = 2\ncheckpoint_every = 0\n";
}

TEST(ParcelWeight, OneWayRunIsTheSameWhateverTheWeightAndThePlateDeposits) {
  Fixture fx;
  const auto ref = fx.run(slotCase("one-way", true, "layer"), "one-way-weighted-layer");
  // Not vacuous: particles strain at the slot and on each other, so deposits are there to be weighted.
  ASSERT_GE(metric(ref, "strained"), 5.0) << "the slot no longer strains: the test needs a new scene";
  EXPECT_EQ(metric(ref, "k_over_k0"), 1.0);
  for (const auto& [weighting, plates] : {std::pair{false, "layer"}, std::pair{true, "column"}, std::pair{false, "column"}}) {
    const std::string dir = std::string("one-way-") + (weighting ? "weighted-" : "unweighted-") + plates;
    const auto other = fx.run(slotCase("one-way", weighting, plates), dir);
    EXPECT_EQ(metric(other, "strained"), metric(ref, "strained"));
    for (const char* f : {"trajectories.csv", "retention.csv", "permeability.csv"})
      EXPECT_EQ(readText(testDir() / "one-way-weighted-layer" / f), readText(testDir() / dir / f))
          << f << ": parcel_weighting = " << weighting << ", plate_deposits = " << plates;
  }
  // Four-way the weight is felt: each deposit books the volume of the particles it stands for,
  // 100 x pi d^3 / 6 weighted, one particle's unweighted (by hand: 6545.0 and 65.45 um^3), and the
  // runs part (the weighted deposit closes the slot sooner).
  const double one = M_PI * 125.0 / 6.0;  // um^3 of a 5 um sphere
  for (const auto& [dir, weight] : {std::pair{"four-way-weighted", 100.0}, std::pair{"four-way-unweighted", 1.0}}) {
    const auto s = fx.run(slotCase("four-way", weight > 1, "layer"), dir);
    const auto& cp = s.result["details"]["coupling"];
    const double deposits = cp["deposits_at_walls"].get<double>() + cp["deposits_on_plates"].get<double>();
    ASSERT_GT(deposits, 0.0) << dir;
    EXPECT_NEAR(cp["deposited_volume_um3"].get<double>() / deposits, weight * one, 1e-9 * weight * one) << dir;
  }
  EXPECT_NE(readText(testDir() / "four-way-weighted" / "trajectories.csv"), readText(testDir() / "four-way-unweighted" / "trajectories.csv"));
}

}  // namespace
}  // namespace mmval::particles
