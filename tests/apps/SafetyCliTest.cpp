// The command as a careless or hostile user meets it: output folders that
// hold the user's files, case names that try to become paths, two runs into
// one folder, reference pointers outside the project, a device as a case file.
// Each of these lost data or ran away before; now each stops with exit 2 (or
// 1 for usage) and a message that says what is wrong, and nothing is removed.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include "RunMmval.hpp"

#include <sys/wait.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <string>
#include <thread>
#include <vector>

#include "mmval/core/Tracks.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

using mmval::test::Outcome;

Outcome mmval(const std::string& args) { return mmval::test::runMmval(args); }

fs::path scratch(const std::string& name) { return mmval::test::freshTestFolder("safety", name); }

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// A quick case (compare-tracks of two identical small track files) in `d`.
fs::path quickCase(const fs::path& d, const std::string& name, const std::string& tags = "[\"default\"]") {
  mmval::Tracks t;
  for (int p = 0; p < 4; ++p)
    for (int f = 0; f < 12; ++f) t.points.push_back({f, p, 0.1 * f, 1e-6 * (10 + 3 * f), 1e-6 * (5 + 10 * p)});
  mmval::writeTracksCsv(d / "exp.csv", t);
  const fs::path file = d / (name.size() < 40 && name.find('/') == std::string::npos && !name.empty() && name[0] != '.' ? name + ".toml" : "case.toml");
  std::ofstream(file) << "[case]\nname = \"" << name << "\"\nkind = \"compare-tracks\"\ntags = " << tags
                      << "\n[inputs]\nexperiment = \"exp.csv\"\nsimulation = \"exp.csv\"\n";
  return file;
}

void writeUserFiles(const fs::path& dir) {
  fs::create_directories(dir);
  std::ofstream(dir / "thesis.tex") << "years of work";
}

TEST(SafetyCli, EveryCommandRefusesAUsersFolderAsOutputAndKeepsItsFiles) {
  const fs::path d = scratch("user-folder");
  const fs::path c = quickCase(d, "self");
  mmval::Tracks t;
  for (int f = 0; f < 10; ++f) t.points.push_back({f, 1, 0.1 * f, 1e-6 * (10 + 3 * f), 20e-6});
  mmval::writeTracksCsv(d / "a.csv", t);
  const std::vector<std::string> commands = {
      "run " + c.string() + " --quiet --out ",
      "synth --frames 3 --particles 2 --out ",
      "compare --experiment " + (d / "a.csv").string() + " --simulation " + (d / "a.csv").string() + " --out ",
      "validate --quiet --cases " + d.string() + " --out ",
      "report " + (d / "ok-report-input").string() + " --out ",
  };
  ASSERT_EQ(mmval("run " + c.string() + " --quiet --out " + (d / "ok-report-input").string()).status, 0);
  for (const auto& cmd : commands) {
    const fs::path out = d / "mine";
    writeUserFiles(out);
    const Outcome o = mmval(cmd + out.string());
    EXPECT_EQ(o.status, 2) << cmd << "\n" << o.output;
    EXPECT_THAT(o.output, HasSubstr("did not write")) << cmd;
    EXPECT_EQ(slurp(out / "thesis.tex"), "years of work") << cmd;
    EXPECT_FALSE(fs::exists(d / "mine.partial")) << cmd;
  }
  // A regular file given as --out stays a file.
  std::ofstream(d / "notes.txt") << "keep";
  const Outcome f = mmval("run " + c.string() + " --quiet --out " + (d / "notes.txt").string());
  EXPECT_EQ(f.status, 2) << f.output;
  EXPECT_THAT(f.output, HasSubstr("is not a folder"));
  EXPECT_EQ(slurp(d / "notes.txt"), "keep");
  // The same command into its own earlier output replaces it.
  ASSERT_EQ(mmval("run " + c.string() + " --quiet --out " + (d / "ok").string()).status, 0);
  const Outcome again = mmval("run " + c.string() + " --quiet --out " + (d / "ok").string());
  EXPECT_EQ(again.status, 0) << again.output;
  EXPECT_TRUE(fs::exists(d / "ok" / "result.json"));
}

TEST(SafetyCli, UnsafeCaseNamesAreRefusedByCaseCheck) {
  const fs::path d = scratch("names");
  for (const std::string& name : std::vector<std::string>{"../../../x", "/tmp/abs", "..", "", ".hidden", "a/b", "tab\\there", std::string(300, 'n')}) {
    const fs::path file = d / "case.toml";
    std::ofstream(file) << "[case]\nname = \"" << name << "\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment = \"a.csv\"\nsimulation = \"b.csv\"\n";
    const Outcome o = mmval("case-check " + file.string());
    EXPECT_EQ(o.status, 2) << name << "\n" << o.output;
    EXPECT_THAT(o.output, HasSubstr("case.name")) << name;
    EXPECT_THAT(o.output, HasSubstr("case.toml:2")) << name;
  }
  // A 2 MB name: refused in well under a second, and the message stays short.
  const fs::path big = d / "big.toml";
  std::ofstream(big) << "[case]\nname = \"" << std::string(2 << 20, 'x') << "\"\nkind = \"compare-tracks\"\n";
  const Outcome o = mmval("case-check " + big.string());
  EXPECT_EQ(o.status, 2);
  EXPECT_LT(o.output.size(), 2000u);
}

TEST(SafetyCli, ValidateRefusesTwoCasesWithOneNameAndNamesBothFiles) {
  const fs::path d = scratch("duplicate");
  fs::create_directories(d / "cases");
  quickCase(d / "cases", "same");
  fs::copy_file(d / "cases" / "same.toml", d / "cases" / "other.toml");
  const Outcome o = mmval("validate --quiet --cases " + (d / "cases").string() + " --out " + (d / "out").string());
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("same name"));
  EXPECT_THAT(o.output, HasSubstr("other.toml"));
  EXPECT_THAT(o.output, HasSubstr("same.toml"));
  EXPECT_FALSE(fs::exists(d / "out" / "runs" / "same"));
}

TEST(SafetyCli, OutputPathsAreNormalisedOrRefusedBeforeAnyWork) {
  const fs::path d = scratch("paths");
  const fs::path c = quickCase(d, "self");
  const Outcome slash = mmval("run " + c.string() + " --quiet --out " + (d / "x").string() + "/");
  EXPECT_EQ(slash.status, 0) << slash.output;
  EXPECT_TRUE(fs::exists(d / "x" / "result.json"));
  EXPECT_FALSE(fs::exists(d / "x" / ".partial"));
  const Outcome empty = mmval("run " + c.string() + " --quiet --out ''");
  EXPECT_EQ(empty.status, 2) << empty.output;
  EXPECT_THAT(empty.output, HasSubstr("empty output folder"));
  // "." is the folder the command runs in: it holds the case and track files, so it is refused untouched.
  const Outcome dot = mmval("run " + c.string() + " --quiet --out .");
  (void)dot;  // run from the build's test folder: the check below runs it from d instead
  const std::string cmd = "cd " + d.string() + " && " + std::string(MMVAL_BINARY_DIR) + "/bin/mmval run self.toml --quiet --out . 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, pipe) != nullptr) out += buf;
  const int raw = pclose(pipe);
  EXPECT_EQ(WEXITSTATUS(raw), 2) << out;
  EXPECT_TRUE(fs::exists(d / "self.toml"));
  EXPECT_TRUE(fs::exists(d / "exp.csv"));
}

TEST(SafetyCli, ASecondRunIntoTheSameFolderIsRefusedWhileTheFirstRuns) {
  const fs::path d = scratch("concurrent");
  // The first run holds the folder's lock for a while: a synthetic video of many frames.
  auto first = std::async(std::launch::async, [&] { return mmval("synth --frames 400 --particles 200 --width 512 --height 512 --out " + (d / "out").string()); });
  // Wait until its staging folder exists.
  for (int i = 0; i < 200 && !fs::exists(d / "out.partial"); ++i) std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_TRUE(fs::exists(d / "out.partial"));
  const Outcome second = mmval("synth --frames 3 --particles 2 --out " + (d / "out").string());
  const Outcome one = first.get();
  EXPECT_EQ(one.status, 0) << one.output;
  EXPECT_EQ(second.status, 2) << second.output;
  EXPECT_THAT(second.output, HasSubstr("another mmval is writing"));
}

TEST(SafetyCli, ReferencePointersStayInsideTheProjectAndNameThePointer) {
  const fs::path d = scratch("pointer");
  for (const std::string& target : std::vector<std::string>{"/etc/passwd", "../../../../../../etc/hostname"}) {
    std::ofstream(d / "case.toml") << "[case]\nname = \"p\"\nkind = \"compare-tracks\"\n[inputs]\nexperiment = \"a.csv\"\nsimulation = \"b.csv\"\n"
                                      "[[acceptance]]\nmetric = \"mean_speed\"\nreference = { file = \""
                                   << target << "\", quantity = \"x\" }\ntolerance = \"1 %\"\nreason = \"test\"\n";
    const Outcome o = mmval("case-check " + (d / "case.toml").string());
    EXPECT_EQ(o.status, 2) << o.output;
    EXPECT_THAT(o.output, HasSubstr("case.toml:9"));
    EXPECT_THAT(o.output, HasSubstr("acceptance[0].reference.file"));
    EXPECT_THAT(o.output, HasSubstr("inside reference-data/"));
  }
}

TEST(SafetyCli, ADeviceOrHugeFileAsCaseFileFailsFast) {
  const auto start = std::chrono::steady_clock::now();
  const Outcome o = mmval("case-check /dev/zero");
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("not a regular file"));
  const Outcome r = mmval("run /dev/zero --out " + (scratch("dev") / "out").string());
  EXPECT_EQ(r.status, 2) << r.output;
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 20.0);
}

TEST(SafetyCli, AnUnknownSubcommandIsNamedWithTheValidOnes) {
  const Outcome o = mmval("frobnicate");
  EXPECT_EQ(o.status, 1);
  EXPECT_THAT(o.output, HasSubstr("unknown subcommand 'frobnicate'"));
  EXPECT_THAT(o.output, HasSubstr("case-check"));
  EXPECT_THAT(o.output, HasSubstr("validate"));
  const Outcome near = mmval("valdate");
  EXPECT_THAT(near.output, HasSubstr("did you mean 'validate'"));
}

}  // namespace

namespace {

TEST(SafetyCli, AnOutputFolderThatCannotBeWrittenIsAnInputErrorNotABug) {
  const fs::path d = scratch("unwritable");
  const fs::path c = quickCase(d, "self");
  // /proc cannot hold folders: the user named an impossible place.
  const Outcome o = mmval("run " + c.string() + " --quiet --out /proc/mmval-test-out");
  EXPECT_EQ(o.status, 2) << o.output;
  EXPECT_THAT(o.output, HasSubstr("/proc/mmval-test-out"));
}

}  // namespace
