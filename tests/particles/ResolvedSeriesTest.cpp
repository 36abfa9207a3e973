// The particles of a particles-resolved run as a ParaView time series
// (ResolvedStages: writeResolvedFiles): particles.pvd lists one
// particles/particles-NNNNN.vtp per output frame with its time, and each
// snapshot holds the particles of trajectories.csv at that frame.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "ParticleRegistry.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Checkpoint.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/core/VtkWriter.hpp"

#include "../TestScratch.hpp"
#include "ResolvedChannelCase.hpp"

namespace mmval::particles {
namespace {

namespace fs = std::filesystem;

std::string readText(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const std::string kChannel = resolvedChannelCase("resolved-series");

struct PvdEntry {
  double time_s = 0;
  std::string file;
};

std::vector<PvdEntry> readPvd(const fs::path& file) {
  const std::string text = readText(file);
  const std::regex dataset(R"re(<DataSet timestep="([^"]+)"[^>]* file="([^"]+)"/>)re");
  std::vector<PvdEntry> out;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), dataset); it != std::sregex_iterator(); ++it)
    out.push_back({std::stod((*it)[1].str()), (*it)[2].str()});
  return out;
}

TEST(ResolvedSeries, PvdListsOneSnapshotPerFrameWithItsTimeAndParticles) {
  CaseKindRegistry& registry = test_support::particleRegistry();
  const Case c = Case::parse(kChannel, "cases/resolved-series.toml", registry);
  const fs::path out = mmval::test::scratch("resolved-series");
  fs::remove_all(out);
  fs::create_directories(out);
  RunContext ctx;
  ctx.out_dir = out;
  ctx.quiet = true;
  const RunOutput r = registry.find("particles-resolved")->run(c, ctx);
  EXPECT_NE(std::find(r.files.begin(), r.files.end(), "particles.pvd"), r.files.end()) << "particles.pvd is not among the run's files";

  // The frames and their times, from the run's own tables.
  const tables::TableColumns retention = tables::parseTable(readText(out / "retention.csv"), "retention.csv");
  const std::vector<double>& times = retention.at("t_s");
  ASSERT_EQ(times.size(), 7u);  // t = 0, 0.05, ..., 0.3 s
  std::map<std::int64_t, std::vector<TrackPoint>> by_frame;
  for (const TrackPoint& p : readTracksCsv(out / "trajectories.csv").points) by_frame[p.frame].push_back(p);

  const std::vector<PvdEntry> entries = readPvd(out / "particles.pvd");
  ASSERT_EQ(entries.size(), times.size());
  for (std::size_t k = 0; k < entries.size(); ++k) {
    const PvdEntry& e = entries[k];
    SCOPED_TRACE("frame " + std::to_string(k) + ": " + e.file);
    EXPECT_EQ(e.file, "particles/particles-" + std::string(5 - std::to_string(k).size(), '0') + std::to_string(k) + ".vtp");
    // Times are written with 17 significant digits: equal to round-off.
    EXPECT_NEAR(e.time_s, times[k], 1e-12);
    const fs::path vtp = out / e.file;
    ASSERT_TRUE(fs::exists(vtp));
    const std::vector<double> time_value = vtk::readArray(vtp, "TimeValue");
    ASSERT_EQ(time_value.size(), 1u);
    EXPECT_NEAR(time_value[0], times[k], 1e-12);

    // The snapshot holds the particles in the channel at that frame, where trajectories.csv has them.
    const std::vector<TrackPoint>& want = by_frame[static_cast<std::int64_t>(k)];
    const std::vector<double> ids = vtk::readArray(vtp, "particle");
    const std::vector<double> deposited = vtk::readArray(vtp, "deposited");
    int components = 0;
    const std::vector<double> xyz = vtk::readArray(vtp, "Points", &components);
    ASSERT_EQ(components, 3);
    ASSERT_EQ(ids.size(), want.size());
    ASSERT_EQ(xyz.size(), 3 * want.size());
    EXPECT_EQ(static_cast<std::int64_t>(ids.size()), static_cast<std::int64_t>(retention.at("inside")[k] + retention.at("retained")[k]));
    for (std::size_t i = 0; i < want.size(); ++i) {
      EXPECT_EQ(static_cast<std::int64_t>(ids[i]), want[i].particle);
      EXPECT_EQ(deposited[i] == 1.0, want[i].state == "deposited");
      // trajectories.csv rounds positions to 1e-5 um (1e-11 m); the snapshot keeps full precision.
      EXPECT_NEAR(xyz[3 * i], want[i].x, 1e-11);
      EXPECT_NEAR(xyz[3 * i + 1], want[i].y, 1e-11);
      EXPECT_DOUBLE_EQ(xyz[3 * i + 2], 0.0);  // the plane of fields.vtr
    }
  }
  // The scene is built so that the series changes: both particles at first, the deposited one at the end.
  EXPECT_EQ(vtk::readArray(out / entries.front().file, "particle").size(), 2u);
  EXPECT_EQ(vtk::readArray(out / entries.back().file, "particle").size(), 1u);
}

TEST(ResolvedSeries, ResumedRunWritesTheUninterruptedSeries) {
  // Stopped after frame 2 and resumed from its checkpoint, the run's snapshots must be the
  // uninterrupted run's: the same files, times, particles and states. Positions agree to round-off
  // only (measured 6e-19 m from the first resumed frame on: the resumed run's flow solves do not
  // repeat the interrupted run's bit for bit); 1e-12 of the channel length is the round-off class.
  CaseKindRegistry& registry = test_support::particleRegistry();
  const std::string text = std::string(kChannel) + "checkpoint_every = 1\n";
  const fs::path dir = mmval::test::scratch("resolved-series-resume");
  fs::remove_all(dir);
  runCase(Case::parse(text, dir / "whole.toml", registry), registry, dir / "whole", {.quiet = true});
  EXPECT_THROW(runCase(Case::parse(text + "stop_after_frames = 2\n", dir / "cut.toml", registry), registry, dir / "cut", {.quiet = true}), RunStopped);
  const RunSummary r = runCase(Case::parse(text, dir / "cut.toml", registry), registry, dir / "cut", {.quiet = true, .resume = true});
  EXPECT_EQ(r.result["details"]["resumed_from_frame"].get<long long>(), 2);
  const std::vector<PvdEntry> entries = readPvd(dir / "whole" / "particles.pvd");
  ASSERT_EQ(entries.size(), 7u);
  EXPECT_EQ(readBinaryFile(dir / "whole" / "particles.pvd"), readBinaryFile(dir / "cut" / "particles.pvd"));
  constexpr double kRoundOff = 1e-12 * 60e-6;
  for (const PvdEntry& e : entries) {
    SCOPED_TRACE(e.file);
    for (const char* exact : {"TimeValue", "particle", "deposited"})
      EXPECT_EQ(vtk::readArray(dir / "whole" / e.file, exact), vtk::readArray(dir / "cut" / e.file, exact)) << exact;
    const std::vector<double> whole = vtk::readArray(dir / "whole" / e.file, "Points"), cut = vtk::readArray(dir / "cut" / e.file, "Points");
    ASSERT_EQ(whole.size(), cut.size());
    for (std::size_t i = 0; i < whole.size(); ++i) EXPECT_NEAR(whole[i], cut[i], kRoundOff) << "coordinate " << i;
  }
}

}  // namespace
}  // namespace mmval::particles
