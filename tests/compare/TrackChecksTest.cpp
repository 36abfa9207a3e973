// Tracks files that cannot be compared fail loudly, naming file, column and
// value: no rows, single rows, time that stands still, ids that a double
// would merge; never 0 or NaN metrics with exit 0.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <fstream>
#include <limits>

#include <fmt/format.h>

#include "../InputErrorMessage.hpp"
#include "../TestScratch.hpp"
#include "mmval/compare/Compare.hpp"
#include "mmval/compare/TrackChecks.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::compare {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

/// 2^53: the first integer above which doubles skip integers.
constexpr std::int64_t kTwoTo53 = std::int64_t{1} << 53;

fs::path writeCsv(const std::string& name, const std::string& text) {
  const fs::path file = test::scratch(name);
  std::ofstream(file) << text;
  return file;
}

/// Particles `ids` moving along x at 20, 40, ... um/s, 20 frames 0.1 s apart, 100 um apart in y.
std::string movingRows(const std::vector<std::int64_t>& ids) {
  std::string rows = "frame,particle,t_s,x_um,y_um\n";
  for (std::size_t i = 0; i < ids.size(); ++i)
    for (int f = 0; f < 20; ++f) rows += fmt::format("{},{},{:.1f},{:g},{:g}\n", f, ids[i], 0.1 * f, 20.0 * (i + 1) * 0.1 * f, 100.0 * i);
  return rows;
}

/// The message of the InputError `f` throws ("(no InputError)" when it throws none).
std::string inputErrorOf(const std::function<void()>& f) { return mmval::test::inputErrorMessage(f); }

TEST(TracksCsv, ParticleIdsAtAndAbove2To53StayDistinct) {
  const fs::path file = writeCsv("big-ids.csv", movingRows({kTwoTo53, kTwoTo53 + 1, kTwoTo53 + 2}));
  const Tracks t = readTracksCsv(file);
  ASSERT_EQ(t.points.size(), 60u);
  EXPECT_EQ(t.points.front().particle, kTwoTo53);
  EXPECT_EQ(t.points[20].particle, kTwoTo53 + 1);
  EXPECT_EQ(t.points.back().particle, kTwoTo53 + 2);
  // Three tracks at 20, 40, 60 um/s: the mean step speed is 40 um/s (merged ids gave thousands).
  const tracking::TrackStats s = tracking::analyseTracks(t, tracking::TrackOptions{});
  EXPECT_EQ(s.particles, 3);
  EXPECT_NEAR(s.mean_speed * 1e6, 40.0, 1e-6);
}

TEST(TracksCsv, LargestIdAndPandasFloatIdAreRead) {
  const std::int64_t largest = std::numeric_limits<std::int64_t>::max();
  const Tracks t = readTracksCsv(writeCsv("max-id.csv", fmt::format("frame,particle,t_s,x_um,y_um\n0,{},0,1,2\n1.0,7.0,0.1,1,2\n", largest)));
  ASSERT_EQ(t.points.size(), 2u);
  EXPECT_EQ(t.points[0].particle, 7);
  EXPECT_EQ(t.points[0].frame, 1);
  EXPECT_EQ(t.points[1].particle, largest);
}

TEST(TracksCsv, FractionalOrOverflowingIdNamesLineColumnAndValue) {
  const std::string frac = inputErrorOf([] { readTracksCsv(writeCsv("frac-id.csv", "frame,particle,t_s,x_um,y_um\n0,1.5,0,1,2\n")); });
  EXPECT_THAT(frac, HasSubstr("frac-id.csv:2:2"));
  EXPECT_THAT(frac, HasSubstr("'particle'"));
  EXPECT_THAT(frac, HasSubstr("\"1.5\""));
  EXPECT_THAT(frac, HasSubstr("64-bit integer"));
  const std::string big = inputErrorOf([] { readTracksCsv(writeCsv("huge-id.csv", "frame,particle,t_s,x_um,y_um\n0,9223372036854775808,0,1,2\n")); });
  EXPECT_THAT(big, HasSubstr("huge-id.csv:2:2"));
}

TEST(TracksCsv, NegativeFrameNamesLineAndValue) {
  const std::string m = inputErrorOf([] { readTracksCsv(writeCsv("neg-frame.csv", "frame,particle,t_s,x_um,y_um\n0,1,0,0,0\n-1,1,0.1,1,0\n")); });
  EXPECT_THAT(m, HasSubstr("neg-frame.csv:3:1"));
  EXPECT_THAT(m, HasSubstr("'frame'"));
  EXPECT_THAT(m, HasSubstr("got -1"));
  EXPECT_THAT(m, HasSubstr("0 or more"));
}

/// compareTracks of `experiment` against a good simulation, as read from files.
std::string compareError(const std::string& name, const std::string& csv) {
  const Tracks good = readTracksCsv(writeCsv("good.csv", movingRows({1, 2, 3})));
  const Tracks bad = readTracksCsv(writeCsv(name, csv));
  return inputErrorOf([&] { compareTracks(bad, good, CompareOptions{}); });
}

TEST(CompareInput, HeaderOnlyFileIsAnError) {
  const std::string m = compareError("header-only.csv", "frame,particle,t_s,x_um,y_um\n");
  EXPECT_THAT(m, HasSubstr("header-only.csv: "));
  EXPECT_THAT(m, HasSubstr("only its header"));
  EXPECT_THAT(m, HasSubstr("got 0 rows"));
}

TEST(CompareInput, OneRowFileIsAnError) {
  const std::string m = compareError("one-row.csv", "frame,particle,t_s,x_um,y_um\n0,1,0,5,5\n");
  EXPECT_THAT(m, HasSubstr("one-row.csv: key 'particle'"));
  EXPECT_THAT(m, HasSubstr("got 1 row(s) of 1 particle(s)"));
}

TEST(CompareInput, TimeThatNeverAdvancesIsAnError) {
  std::string rows = "frame,particle,t_s,x_um,y_um\n";
  for (int f = 0; f < 10; ++f) rows += fmt::format("{},1,0.5,{},0\n", f, 3 * f);
  const std::string m = compareError("same-time.csv", rows);
  EXPECT_THAT(m, HasSubstr("same-time.csv: key 't_s'"));
  EXPECT_THAT(m, HasSubstr("got t_s = 0.5 s in every row"));
}

TEST(CompareInput, TwoRowsOfOneParticleAtOneFrameAreAnError) {
  const std::string m = compareError("duplicate.csv", "frame,particle,t_s,x_um,y_um\n0,4,0,0,0\n1,4,0.1,1,0\n1,4,0.1,9,0\n2,4,0.2,2,0\n");
  EXPECT_THAT(m, HasSubstr("duplicate.csv: key 'particle'"));
  EXPECT_THAT(m, HasSubstr("particle 4 has two rows at frame 1"));
}

TEST(CompareInput, SimulationIsCheckedToo) {
  const Tracks good = readTracksCsv(writeCsv("good.csv", movingRows({1, 2})));
  const Tracks empty = readTracksCsv(writeCsv("sim-empty.csv", "frame,particle,t_s,x_um,y_um\n"));
  EXPECT_THAT(inputErrorOf([&] { compareTracks(good, empty, CompareOptions{}); }), HasSubstr("sim-empty.csv"));
}

TEST(CompareInput, ExperimentWithoutAMovingParticleIsAnError) {
  // Two particles that jitter by 0.5 um: immobile at the 2 um default, no speed to compare against.
  std::string rows = "frame,particle,t_s,x_um,y_um\n";
  for (int p = 1; p <= 2; ++p)
    for (int f = 0; f < 10; ++f) rows += fmt::format("{},{},{:.1f},{},{}\n", f, p, 0.1 * f, 10 + 0.5 * (f % 2), 50 * p);
  const std::string m = compareError("still.csv", rows);
  EXPECT_THAT(m, HasSubstr("still.csv: no step to measure a speed from"));
  EXPECT_THAT(m, HasSubstr("2 particle(s): 2 immobile (never farther than 2 um"));
}

TEST(CompareInput, FailedMetricsAreListedByName) {
  const Tracks slow = readTracksCsv(writeCsv("slow.csv", movingRows({1, 2, 3})));
  Tracks fast = slow;
  for (auto& p : fast.points) p.x *= 2;  // every speed doubled: mean and median speed fail
  const Comparison c = compareTracks(slow, fast, CompareOptions{});
  EXPECT_THAT(failedMetrics(c), ::testing::IsSupersetOf({"mean_speed", "median_speed"}));
  EXPECT_TRUE(failedMetrics(compareTracks(slow, slow, CompareOptions{})).empty());
}

}  // namespace
}  // namespace mmval::compare
