// The commit a build reports (mmval/core/BuildInfo.hpp, written at build time by
// cmake/WriteBuildInfo.cmake) is the commit of the source tree it was built
// from, reaches result.json's provenance, and is "unknown" where the sources
// are not a git checkout of their own.
#include <gtest/gtest.h>

#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "mmval/core/BuildInfo.hpp"
#include "mmval/core/Run.hpp"

namespace mmval {
namespace {

namespace fs = std::filesystem;

struct Output {
  int status = -1;
  std::string text;  ///< stdout, trailing newline removed
};

Output run(const std::string& cmd) {
  Output o;
  FILE* pipe = popen((cmd + " 2>/dev/null").c_str(), "r");
  if (pipe == nullptr) return o;
  std::array<char, 512> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe) != nullptr) o.text += buf.data();
  const int raw = pclose(pipe);
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  while (!o.text.empty() && (o.text.back() == '\n' || o.text.back() == '\r')) o.text.pop_back();
  return o;
}

const std::string kGit = MMVAL_GIT_EXECUTABLE;
const fs::path kSource = MMVAL_SOURCE_DIR;

bool haveGit() { return !kGit.empty() && kGit.find("NOTFOUND") == std::string::npos; }

/// True when the source tree is the top of a git checkout (not an export).
bool sourceIsCheckout() {
  if (!haveGit()) return false;
  const Output top = run("'" + kGit + "' -C '" + kSource.string() + "' rev-parse --show-toplevel");
  std::error_code ec;
  return top.status == 0 && fs::equivalent(top.text, kSource, ec);
}

std::string withoutDirty(std::string hash) {
  const std::string suffix = "-dirty";
  if (hash.size() > suffix.size() && hash.compare(hash.size() - suffix.size(), suffix.size(), suffix) == 0) hash.resize(hash.size() - suffix.size());
  return hash;
}

/// Runs cmake/WriteBuildInfo.cmake for `src` with `git` ("" = no git) and returns kGitHash's value.
std::string stampedHash(const fs::path& src, const std::string& git, const fs::path& out) {
  const Output o = run(std::string("'") + MMVAL_CMAKE_COMMAND + "' -DSRC='" + src.string() + "' -DOUT='" + out.string() + "' -DGIT='" + git +
                       "' -P '" + (kSource / "cmake" / "WriteBuildInfo.cmake").string() + "'");
  EXPECT_EQ(o.status, 0) << "cmake -P WriteBuildInfo.cmake for " << src;
  std::ifstream in(out);
  std::stringstream text;
  text << in.rdbuf();
  std::smatch m;
  const std::string s = text.str();
  if (!std::regex_search(s, m, std::regex("kGitHash = \"([^\"]*)\""))) return "(no kGitHash in " + out.string() + ")";
  return m[1].str();
}

fs::path freshFolder(const std::string& name) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / "build-info" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

// The hash compiled in is the source tree's HEAD now (the build stamps it at
// every build, so a tree configured at an older commit still reports this one),
// and provenanceJson (result.json) carries exactly the compiled-in value.
TEST(BuildInfo, CommitIsTheSourceTreesHead) {
  EXPECT_EQ(provenanceJson()["git_hash"].get<std::string>(), build::kGitHash);
  if (!sourceIsCheckout()) GTEST_SKIP() << kSource << " is not a git checkout (or git is missing): the build says \"" << build::kGitHash << "\"";
  const Output head = run("'" + kGit + "' -C '" + kSource.string() + "' rev-parse --short=12 HEAD");
  ASSERT_EQ(head.status, 0);
  EXPECT_EQ(withoutDirty(build::kGitHash), head.text) << "rebuild: the binary was built from another commit";
}

// An exported tree has no commit of its own: "unknown", also when it was unpacked
// inside another checkout (here the build folder, which may lie inside the source
// checkout), and when git is missing.
TEST(BuildInfo, SourcesOutsideTheirOwnCheckoutAreUnknown) {
  const fs::path work = freshFolder("unknown");
  const fs::path exported = work / "exported-sources";
  fs::create_directories(exported / "cmake");
  if (haveGit()) {
    EXPECT_EQ(stampedHash(exported, kGit, work / "nested.hpp"), "unknown");
    const fs::path outside = fs::temp_directory_path() / ("mmval-build-info-" + std::to_string(::getpid()));
    fs::create_directories(outside);
    EXPECT_EQ(stampedHash(outside, kGit, work / "outside.hpp"), "unknown");
    fs::remove_all(outside);
  }
  EXPECT_EQ(stampedHash(kSource, "", work / "no-git.hpp"), "unknown");
}

// Run on the real tree the script gives the compiled-in commit, and it does not
// rewrite a header whose text is unchanged (so an unchanged commit rebuilds nothing).
TEST(BuildInfo, StampingTheSameCommitLeavesTheHeaderAlone) {
  if (!sourceIsCheckout()) GTEST_SKIP() << kSource << " is not a git checkout (or git is missing)";
  const fs::path work = freshFolder("same");
  const fs::path out = work / "BuildInfo.hpp";
  const std::string first = stampedHash(kSource, kGit, out);
  EXPECT_EQ(withoutDirty(first), withoutDirty(build::kGitHash));
  const auto stamp = fs::last_write_time(out);
  fs::last_write_time(out, stamp - std::chrono::hours(1));  // older than anything the second run could write
  const auto aged = fs::last_write_time(out);
  const std::string second = stampedHash(kSource, kGit, out);
  if (second != first) GTEST_SKIP() << "the tree changed between the two runs (" << first << " -> " << second << ")";
  EXPECT_EQ(fs::last_write_time(out), aged);
}

}  // namespace
}  // namespace mmval
