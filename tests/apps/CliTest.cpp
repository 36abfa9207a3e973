// The `mmval` command as a user meets it: help, exit statuses, messages that
// name the file and line, and run folders that appear only when complete.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "RunMmval.hpp"

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include <nlohmann/json.hpp>

#include "mmval/core/Tracks.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using mmval::test::Outcome;

Outcome mmval(const std::string& args, const std::string& env = "") { return mmval::test::runMmval(args, env); }

fs::path scratch(const std::string& name) { return mmval::test::freshTestFolder("cli", name); }

TEST(Cli, HelpListsSubcommands) {
  const Outcome o = mmval("--help");
  EXPECT_EQ(o.status, 0);
  for (const char* sub : {"case-check", "case-doc", "run", "validate", "compare", "report", "peer", "track", "synth"}) EXPECT_THAT(o.output, HasSubstr(sub));
  EXPECT_EQ(mmval("run --help").status, 0);
}

TEST(Cli, UsageErrorsExitWithOne) {
  EXPECT_EQ(mmval("").status, 1);
  EXPECT_EQ(mmval("run").status, 1);
  EXPECT_EQ(mmval("no-such-command").status, 1);
}

TEST(Cli, BadCaseFileExitsWithTwoAndNamesFileLineAndKey) {
  const fs::path d = scratch("bad-case");
  std::ofstream(d / "bad.toml") << "[case]\nname = \"x\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment = \"a.csv\"\nsimulaton = \"b.csv\"\n";
  const Outcome o = mmval("case-check " + (d / "bad.toml").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("bad.toml:6"));
  EXPECT_THAT(o.output, HasSubstr("inputs.simulaton"));
  EXPECT_THAT(o.output, HasSubstr("did you mean 'inputs.simulation'"));
}

TEST(Cli, MissingTracksFileExitsWithTwo) {
  const Outcome o = mmval("compare --experiment /nonexistent/a.csv --simulation /nonexistent/b.csv --out " + scratch("missing").string() + "/out");
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("/nonexistent/a.csv"));
}

TEST(Cli, RunWritesResultJsonAndCaseDocDescribesTheKind) {
  const fs::path d = scratch("run");
  mmval::Tracks t;
  for (int p = 0; p < 5; ++p)
    for (int f = 0; f < 20; ++f) t.points.push_back({f, p, 0.1 * f, 1e-6 * (10 + 3 * f), 1e-6 * (5 + 10 * p)});
  mmval::writeTracksCsv(d / "exp.csv", t);
  mmval::writeTracksCsv(d / "sim.csv", t);
  std::ofstream(d / "case.toml") << "[case]\nname = \"self\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment = \"exp.csv\"\nsimulation = \"sim.csv\"\n";
  const Outcome o = mmval("run " + (d / "case.toml").string() + " --quiet --out " + (d / "out").string());
  EXPECT_EQ(o.status, 0) << o.output;
  ASSERT_TRUE(fs::exists(d / "out" / "result.json"));
  EXPECT_FALSE(fs::exists(d / "out.partial"));
  std::ifstream in(d / "out" / "result.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_EQ(j["case"]["name"], "self");
  EXPECT_TRUE(j["all_pass"].get<bool>());
  // Identical inputs: the mean speed is 30 um/s in both, error 0.
  bool found = false;
  for (const auto& m : j["metrics"])
    if (m["name"] == "mean_speed") {
      found = true;
      EXPECT_NEAR(m["value"].get<double>(), 30.0, 1e-6);
      EXPECT_NEAR(m["error"].get<double>(), 0.0, 1e-12);
    }
  EXPECT_TRUE(found);
  const Outcome doc = mmval("case-doc compare-tracks");
  EXPECT_EQ(doc.status, 0);
  EXPECT_THAT(doc.output, HasSubstr("`analysis.stuck_window`"));
  // The report over the run folder renders.
  const Outcome rep = mmval("report " + (d / "out").string() + " --out " + (d / "report").string());
  EXPECT_EQ(rep.status, 0) << rep.output;
  EXPECT_TRUE(fs::exists(d / "report" / "index.html"));
}

TEST(Cli, SynthThenTrackWritesEveryOutput) {
  const fs::path d = scratch("track");
  ASSERT_EQ(mmval("synth --out " + (d / "video").string() + " --frames 20 --particles 15 --immobile 0 --seed 3").status, 0);
  const Outcome o = mmval("track " + (d / "video" / "frames").string() + " --pixel-size-um 0.5 --fps 20 --quiet --truth " +
                          (d / "video" / "truth.csv").string() + " --out " + (d / "out").string());
  EXPECT_EQ(o.status, 0) << o.output;
  for (const char* f : {"detections.csv", "tracks.csv", "velocities.csv", "dispersion.csv", "retention.csv", "streamlines.png", "summary.json", "result.json"})
    EXPECT_TRUE(fs::exists(d / "out" / f)) << f;
  std::ifstream in(d / "out" / "summary.json");
  const auto j = nlohmann::json::parse(in);
  EXPECT_GT(j["scores"]["jaccard_points"].get<double>(), 0.8);
  // Headers carry units.
  std::ifstream v(d / "out" / "velocities.csv");
  std::string header;
  std::getline(v, header);
  EXPECT_THAT(header, HasSubstr("speed_um_per_s"));
  // Missing frame rate: exit 2 naming the key.
  const Outcome bad = mmval("track " + (d / "video" / "frames").string() + " --pixel-size-um 0.5 --out " + (d / "bad").string());
  EXPECT_EQ(bad.status, 2);
  EXPECT_THAT(bad.output, HasSubstr("inputs.frame_rate"));
}

TEST(Cli, EveryBundledCaseFilePassesCaseCheck) {
  // One process for all files (case-check takes several; each process start costs ~0.5 s of
  // loading shared libraries): exit 0, and an "ok" line naming each file.
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(fs::path(MMVAL_SOURCE_DIR) / "cases"))
    if (e.path().extension() == ".toml") files.push_back(e.path().string());
  ASSERT_GE(files.size(), 3U);
  std::string args = "case-check";
  for (const auto& f : files) args += " " + f;
  const Outcome o = mmval(args);
  EXPECT_EQ(o.status, 0) << o.output;
  for (const auto& f : files) EXPECT_THAT(o.output, HasSubstr(f + ": ok (kind ")) << o.output;
}

TEST(Cli, PeerRejectsAKindItCannotRun) {
  const fs::path d = scratch("peer-kind");
  mmval::Tracks t;
  t.points.push_back({0, 0, 0.0, 1e-6, 1e-6});
  mmval::writeTracksCsv(d / "a.csv", t);
  std::ofstream(d / "case.toml") << "[case]\nname = \"x\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment = \"a.csv\"\nsimulation = \"a.csv\"\n";
  const Outcome o = mmval("peer openfoam " + (d / "case.toml").string() + " --out " + (d / "out").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("does not run this kind"));
}

TEST(Cli, ValidateMarksAMissingOpenFoamPeerNotRun) {
  // A peer-tagged case on a machine without OpenFOAM (WM_PROJECT_DIR pointing
  // nowhere): our solver's numbers stand, the peer column says "not run", and
  // the validation does not fail because of the peer.
  const fs::path d = scratch("peer-missing");
  fs::create_directories(d / "cases");
  std::ofstream(d / "cases" / "array.toml")
      << "[case]\nname = \"array\"\nkind = \"periodic-array\"\ntags = [\"default\", \"peer\"]\n"
         "[geometry]\ncell = \"100 um\"\nsolid_fraction = 0.2\n[fluid]\ndensity = \"1000 kg/m3\"\nviscosity = \"1e-3 Pa s\"\n"
         "[flow]\nmean_velocity = \"1e-4 m/s\"\n[numerics]\ncells_per_side = 32\n";
  const Outcome v = mmval("validate --quiet --cases " + (d / "cases").string() + " --out " + (d / "out").string(),
                          "WM_PROJECT_DIR=" + (d / "no-openfoam").string() + " ");
  EXPECT_EQ(v.status, 0) << v.output;
  EXPECT_THAT(v.output, HasSubstr("OpenFOAM peer not run for array"));
  std::ifstream in(d / "out" / "metrics.json");
  const auto metrics = nlohmann::json::parse(in);
  bool peer_row = false;
  for (const auto& m : metrics["metrics"])
    if (m["case"] == "array-openfoam" && m["status"] == "not run") peer_row = true;
  EXPECT_TRUE(peer_row) << metrics.dump(1);

  // --resume keeps that complete run (same case file) instead of solving again.
  const Outcome again = mmval("validate --quiet --resume --cases " + (d / "cases").string() + " --out " + (d / "out").string());
  EXPECT_EQ(again.status, 0) << again.output;
  EXPECT_THAT(again.output, HasSubstr("kept the complete earlier run"));
}

/// A binary PGM (OpenCV reads it like a PNG): dark (0) grains where `grain` says so.
template <class F>
void writeMask(const fs::path& file, int w, int h, F grain) {
  std::ofstream out(file, std::ios::binary);
  out << "P5\n" << w << " " << h << "\n255\n";
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) out.put(grain(x, y) ? static_cast<char>(0) : static_cast<char>(255));
}

TEST(Cli, SynthGeometryCarriesParticlesAroundAGrain) {
  // One round grain (radius 25 px) in a 240 x 120 px channel: the pore flow from
  // mmval's solver must carry particles left to right and never through the grain.
  const fs::path d = scratch("synth-geometry");
  const double cx = 120, cy = 60, r = 25;
  writeMask(d / "mask.pgm", 240, 120, [&](int x, int y) { return std::hypot(x + 0.5 - cx, y + 0.5 - cy) < r; });
  const Outcome o = mmval("synth --out " + (d / "video").string() + " --geometry " + (d / "mask.pgm").string() +
                          " --frames 20 --particles 40 --immobile 0 --speed 2 --seed 3");
  ASSERT_EQ(o.status, 0) << o.output;
  const mmval::Tracks truth = mmval::readTracksCsv(d / "video" / "truth.csv", 0);
  ASSERT_GT(truth.points.size(), 200U);
  double closest = 1e9, sum_dx = 0;
  int steps = 0;
  for (std::size_t i = 0; i < truth.points.size(); ++i) {
    const auto& p = truth.points[i];
    closest = std::min(closest, std::hypot(p.x_px - cx, p.y_px - cy));
    if (i > 0 && truth.points[i - 1].particle == p.particle && truth.points[i - 1].frame + 1 == p.frame) {
      sum_dx += p.x_px - truth.points[i - 1].x_px;
      ++steps;
    }
  }
  // Truth positions are spot centres: none inside the grain (1 px of sampling slack).
  EXPECT_GT(closest, r - 1.0);
  EXPECT_LT(closest, 60.0);  // finite pixel columns, and particles do pass the grain (gaps are 35 px)
  // The flow is scaled to a mean pore speed of 2 px/frame; tracer steps average
  // the same field over where particles are (flux-weighted), so within a factor 2.
  ASSERT_GT(steps, 100);
  EXPECT_GT(sum_dx / steps, 1.0);
  EXPECT_LT(sum_dx / steps, 4.0);
}

TEST(Cli, SynthGeometryWithoutAPorePathIsRefused) {
  const fs::path d = scratch("synth-blocked");
  writeMask(d / "mask.pgm", 120, 80, [](int x, int) { return x >= 50 && x < 60; });  // a wall across the channel
  const Outcome o = mmval("synth --out " + (d / "video").string() + " --geometry " + (d / "mask.pgm").string() + " --frames 5");
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("no pore path"));
  EXPECT_THAT(o.output, HasSubstr("mask.pgm"));
}

TEST(Cli, RenderedTrajectoriesAreTrackedAndComparedThroughRunNames) {
  // Ten particles (11 px apart) crossing an empty 160 x 120 px channel at 2 px per step (10 um px,
  // 0.05 s steps: 400 um/s), written as a simulation would; rendered, tracked, then
  // compared through the run names validate uses. The tracker must recover the
  // speed of a clean video to 2 %.
  const fs::path d = scratch("rendered");
  writeMask(d / "mask.pgm", 160, 120, [](int, int) { return false; });
  mmval::Tracks sim;
  for (int p = 0; p < 10; ++p)
    for (int f = 0; f < 60; ++f) {
      mmval::TrackPoint q;
      q.frame = f;
      q.particle = p;
      q.t = 0.05 * f;
      q.x_px = 20.37 + 2.0 * f + 3.0 * p;  // off the occupancy cells' edges
      q.y_px = 6.41 + 11.0 * p;
      q.x = q.x_px * 10e-6;
      q.y = q.y_px * 10e-6;
      sim.points.push_back(q);
    }
  fs::create_directories(d / "runs" / "scene");
  mmval::writeTracksCsv(d / "runs" / "scene" / "trajectories.csv", sim, 10e-6);
  std::ofstream(d / "render.toml") << "[case]\nname = \"render\"\nkind = \"tracking-rendered\"\n[inputs]\ntrajectories_run = \"scene\"\n"
                                      "[geometry]\nmask = \"mask.pgm\"\npixel_size = \"10 um\"\n[render]\nsnr = 10\n[detect]\npolarity = \"dark\"\n";
  const Outcome r = mmval("run --quiet " + (d / "render.toml").string() + " --out " + (d / "runs" / "render").string());
  ASSERT_EQ(r.status, 0) << r.output;
  std::ifstream rin(d / "runs" / "render" / "result.json");
  const auto rj = nlohmann::json::parse(rin);
  EXPECT_GT(rj["details"]["scores"]["jaccard_points"].get<double>(), 0.95) << rj["details"].dump(1);
  EXPECT_LT(rj["details"]["scores"]["rmse_px"].get<double>(), 0.3);
  std::ofstream(d / "compare.toml") << "[case]\nname = \"cmp\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment_run = \"render\"\n"
                                       "simulation_run = \"scene\"\n[tolerances]\nspeed = 0.02\n[analysis]\noccupancy_cell = \"20 um\"\n";
  const Outcome c = mmval("run --quiet " + (d / "compare.toml").string() + " --out " + (d / "runs" / "cmp").string());
  EXPECT_EQ(c.status, 0) << c.output;
  EXPECT_THAT(c.output, HasSubstr("mean_speed"));
  // A geometry crop outside the mask is refused with the key named.
  writeMask(d / "grain.pgm", 160, 120, [](int x, int y) { return std::hypot(x - 80.0, y - 60.0) < 20; });
  std::ofstream(d / "crop.toml") << "[case]\nname = \"crop\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment_run = \"render\"\n"
                                    "simulation_run = \"scene\"\n[geometry]\nmask = \"grain.pgm\"\npixel_size = \"10 um\"\ncrop = [100, 0, 100, 50]\n";
  const Outcome k = mmval("run --quiet " + (d / "crop.toml").string() + " --out " + (d / "runs" / "crop").string());
  EXPECT_EQ(k.status, 2) << k.output;
  EXPECT_THAT(k.output, HasSubstr("crop"));
  // A run name that did not run is named in the message.
  std::ofstream(d / "bad.toml") << "[case]\nname = \"bad\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment_run = \"nothing\"\nsimulation_run = \"scene\"\n";
  const Outcome b = mmval("run --quiet " + (d / "bad.toml").string() + " --out " + (d / "runs" / "bad").string());
  EXPECT_EQ(b.status, 2) << b.output;
  EXPECT_THAT(b.output, HasSubstr("nothing"));
}

TEST(Cli, ResumeRunsAgainACaseWhoseInputRunWasRunAgain) {
  // A rendered-tracking case reads the trajectories of a micromodel run of the same validation.
  // When --resume runs the micromodel again (its case changed), the kept tracking run would
  // describe the old trajectories: it must be run again too; unchanged, both are kept.
  const fs::path d = scratch("resume-inputs");
  fs::create_directories(d / "cases");
  writeMask(d / "cases" / "mask.pgm", 60, 40, [](int x, int y) { return std::hypot(x + 0.5 - 30, y + 0.5 - 20) < 8; });
  const auto writeScene = [&](int seed) {
    std::ofstream(d / "cases" / "mm.toml")
        << "[case]\nname = \"mm\"\nkind = \"particles-micromodel\"\ntags = [\"default\"]\n"
           "[geometry]\nmask = \"mask.pgm\"\npixel_size = \"10 um\"\ndepth = \"20 um\"\n"
           "[flow]\ndarcy_velocity = \"0.5 mm/s\"\n[particles]\ndiameter = \"5 um\"\ncount = 20\ninjection_time = \"0.5 s\"\n"
           "[run]\nduration = \"1 s\"\noutput_interval = \"0.05 s\"\nseed = "
        << seed << "\n";
  };
  writeScene(1);
  std::ofstream(d / "cases" / "tr.toml") << "[case]\nname = \"tr\"\nkind = \"tracking-rendered\"\ntags = [\"default\"]\n"
                                            "[inputs]\ntrajectories_run = \"mm\"\n[geometry]\nmask = \"mask.pgm\"\npixel_size = \"10 um\"\n";
  const std::string args = "validate --quiet --cases " + (d / "cases").string() + " --out " + (d / "out").string();
  const Outcome first = mmval(args);
  ASSERT_NE(first.status, 4) << first.output;
  ASSERT_TRUE(fs::exists(d / "out" / "runs" / "tr" / "result.json")) << first.output;

  const Outcome same = mmval(args + " --resume");
  EXPECT_NE(same.status, 4) << same.output;
  EXPECT_THAT(same.output, HasSubstr("kept the complete earlier run in " + (d / "out" / "runs" / "tr").string())) << same.output;
  EXPECT_THAT(same.output, ::testing::Not(HasSubstr("run again"))) << same.output;

  writeScene(2);
  const Outcome changed = mmval(args + " --resume");
  EXPECT_NE(changed.status, 4) << changed.output;
  EXPECT_THAT(changed.output, HasSubstr("run again: its input run mm was run again")) << changed.output;
  EXPECT_THAT(changed.output, ::testing::Not(HasSubstr("kept the complete earlier run in " + (d / "out" / "runs" / "tr").string())))
      << changed.output;
}

TEST(Cli, MicromodelRunShowsItsProgressAndQuietSilencesIt) {
  // A micromodel run of many minutes said nothing until its metrics table. Off a terminal the
  // progress is one line per tenth of the output frames (Progress), then a final "took" line.
  const fs::path d = scratch("micromodel-progress");
  const fs::path c = fs::path(MMVAL_SOURCE_DIR) / "cases" / "particles-micromodel.toml";
  const Outcome o = mmval("run " + c.string() + " --set run.duration=1s --out " + (d / "loud").string());
  ASSERT_EQ(o.status, 0) << o.output;
  std::size_t lines = 0;
  for (std::size_t at = o.output.find("(output frames)"); at != std::string::npos; at = o.output.find("(output frames)", at + 1)) ++lines;
  EXPECT_GE(lines, 11U) << o.output;  // one per tenth, and the final line
  EXPECT_THAT(o.output, HasSubstr("particles-micromodel (output frames) [##############################]")) << o.output;
  EXPECT_THAT(o.output, HasSubstr(" took ")) << o.output;
  const Outcome q = mmval("run " + c.string() + " --quiet --set run.duration=1s --out " + (d / "quiet").string());
  ASSERT_EQ(q.status, 0) << q.output;
  EXPECT_THAT(q.output, ::testing::Not(HasSubstr("(output frames)"))) << q.output;
}

}  // namespace
