// Only replace what mmval wrote (never lose a user's data): the staged
// output folder refuses a user's folder or file, replaces only folders that
// carry mmval's marker and nothing beyond its list, normalises the path before
// any work, locks against a second writer and cleans up after a failure.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"

namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

fs::path scratch(const std::string& name) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / "output-folder" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// A complete mmval output in `dir` holding result.json with `text`.
void writeRun(const fs::path& dir, const std::string& text) {
  mmval::StagedDirectory staged(dir);
  mmval::writeFileAtomic(staged.path() / "result.json", text);
  staged.commit();
}

TEST(OutputFolder, AUsersFolderIsRefusedAndLeftAsItWas) {
  const fs::path d = scratch("user");
  std::ofstream(d / "thesis.tex") << "three years of work";
  fs::create_directories(d / "data");
  std::ofstream(d / "data" / "raw.csv") << "1,2,3";
  try {
    writeRun(d, "{}");
    FAIL() << "a folder holding a user's files was replaced";
  } catch (const mmval::InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("did not write"));
    EXPECT_THAT(e.what(), HasSubstr("nothing was changed"));
  }
  EXPECT_EQ(slurp(d / "thesis.tex"), "three years of work");
  EXPECT_EQ(slurp(d / "data" / "raw.csv"), "1,2,3");
  EXPECT_FALSE(fs::exists(d / "result.json"));
  EXPECT_FALSE(fs::exists(d.string() + ".partial"));
}

TEST(OutputFolder, ARegularFileIsRefusedAndKept) {
  const fs::path d = scratch("file");
  std::ofstream(d / "notes") << "keep me";
  EXPECT_THROW(writeRun(d / "notes", "{}"), mmval::InputError);
  ASSERT_TRUE(fs::is_regular_file(d / "notes"));
  EXPECT_EQ(slurp(d / "notes"), "keep me");
}

TEST(OutputFolder, ASymbolicLinkIsRefused) {
  const fs::path d = scratch("link");
  fs::create_directories(d / "target");
  std::ofstream(d / "target" / "f") << "x";
  fs::create_directory_symlink(d / "target", d / "out");
  EXPECT_THROW(writeRun(d / "out", "{}"), mmval::InputError);
  EXPECT_TRUE(fs::is_symlink(d / "out"));
  EXPECT_EQ(slurp(d / "target" / "f"), "x");
}

TEST(OutputFolder, AnEarlierMmvalOutputIsReplacedAndAnEmptyFolderUsed) {
  const fs::path d = scratch("replace");
  writeRun(d / "out", "first");
  ASSERT_TRUE(fs::exists(d / "out" / mmval::kOutputMarker));
  EXPECT_THAT(slurp(d / "out" / mmval::kOutputMarker), HasSubstr("result.json"));
  writeRun(d / "out", "second");
  EXPECT_EQ(slurp(d / "out" / "result.json"), "second");
  fs::create_directories(d / "empty");
  writeRun(d / "empty", "third");
  EXPECT_EQ(slurp(d / "empty" / "result.json"), "third");
  // Nothing is left beside the folder.
  int entries = 0;
  for (const auto& e : fs::directory_iterator(d)) entries += e.path().filename() == "out" || e.path().filename() == "empty" ? 0 : 1;
  EXPECT_EQ(entries, 0);
}

TEST(OutputFolder, AUsersFileAddedToAnMmvalOutputIsNotLost) {
  const fs::path d = scratch("added");
  writeRun(d / "out", "first");
  std::ofstream(d / "out" / "my-analysis.ipynb") << "notebook";
  try {
    writeRun(d / "out", "second");
    FAIL() << "an mmval folder holding a user's file was replaced";
  } catch (const mmval::InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("my-analysis.ipynb"));
  }
  EXPECT_EQ(slurp(d / "out" / "my-analysis.ipynb"), "notebook");
  EXPECT_EQ(slurp(d / "out" / "result.json"), "first");
}

TEST(OutputFolder, PathsAreNormalisedBeforeAnyWork) {
  const fs::path d = scratch("normalise");
  EXPECT_EQ(mmval::normaliseOutputPath((d / "x").string() + "/"), d / "x");
  EXPECT_EQ(mmval::normaliseOutputPath((d / "x").string() + "//"), d / "x");
  EXPECT_EQ(mmval::normaliseOutputPath("out/./x/"), fs::path("out/x"));
  EXPECT_EQ(mmval::normaliseOutputPath("."), fs::current_path());
  EXPECT_THROW(mmval::normaliseOutputPath(""), mmval::InputError);
  EXPECT_THROW(mmval::normaliseOutputPath("/"), mmval::InputError);
  // A trailing slash writes the folder itself, not a hidden ".partial" inside it.
  writeRun((d / "x").string() + "/", "r");
  EXPECT_EQ(slurp(d / "x" / "result.json"), "r");
  EXPECT_FALSE(fs::exists(d / "x" / ".partial"));
}

TEST(OutputFolder, ASecondWriterIsRefusedWhileTheFirstRuns) {
  const fs::path d = scratch("lock");
  mmval::StagedDirectory first(d / "out");
  try {
    mmval::StagedDirectory second(d / "out");
    FAIL() << "two writers into one folder";
  } catch (const mmval::InputError& e) {
    EXPECT_THAT(e.what(), HasSubstr("another mmval is writing"));
  }
  mmval::writeFileAtomic(first.path() / "result.json", "first");
  first.commit();
  EXPECT_EQ(slurp(d / "out" / "result.json"), "first");
}

TEST(OutputFolder, AFailedRunLeavesNoPartialUnlessItHoldsACheckpoint) {
  const fs::path d = scratch("cleanup");
  {
    mmval::StagedDirectory staged(d / "a");
    mmval::writeFileAtomic(staged.path() / "half.csv", "1");
  }  // destroyed without commit, as when the runner throws
  EXPECT_FALSE(fs::exists(d / "a.partial"));
  EXPECT_FALSE(fs::exists(d / "a"));
  {
    mmval::StagedDirectory staged(d / "b");
    mmval::writeFileAtomic(staged.path() / "checkpoint.bin", "state");
  }
  EXPECT_TRUE(fs::exists(d / "b.partial" / "checkpoint.bin"));
  // --resume keeps it; a fresh run clears it (it is mmval's own staging folder).
  {
    mmval::StagedDirectory resumed(d / "b", true);
    EXPECT_TRUE(fs::exists(resumed.path() / "checkpoint.bin"));
    mmval::writeFileAtomic(resumed.path() / "result.json", "resumed");
    resumed.commit();
  }
  EXPECT_EQ(slurp(d / "b" / "result.json"), "resumed");
  EXPECT_FALSE(fs::exists(d / "b.partial"));
}

TEST(OutputFolder, AStagingNameHeldByAUsersFolderIsNotCleared) {
  const fs::path d = scratch("partial-user");
  fs::create_directories(d / "out.partial");
  std::ofstream(d / "out.partial" / "mine.txt") << "mine";
  EXPECT_THROW(writeRun(d / "out", "{}"), mmval::InputError);
  EXPECT_EQ(slurp(d / "out.partial" / "mine.txt"), "mine");
}

}  // namespace

// Under mpirun every rank runs the case; only rank 0 writes files and prints the
// metrics table (before, `mpirun -np 2 mmval run` printed it twice). The rank
// comes from the launcher's environment: Open MPI, else MPICH/PMI.
TEST(OutputFolder, OnlyTheFirstRankOfAnMpiLaunchWritesAndPrints) {
  const char* keep_ompi = std::getenv("OMPI_COMM_WORLD_RANK");
  const char* keep_pmi = std::getenv("PMI_RANK");
  const std::string ompi = keep_ompi ? keep_ompi : "", pmi = keep_pmi ? keep_pmi : "";
  ::unsetenv("OMPI_COMM_WORLD_RANK");
  ::unsetenv("PMI_RANK");
  EXPECT_TRUE(mmval::primaryRank());  // no launcher
  ::setenv("PMI_RANK", "1", 1);
  EXPECT_FALSE(mmval::primaryRank());
  ::setenv("OMPI_COMM_WORLD_RANK", "0", 1);  // Open MPI's variable is read first
  EXPECT_TRUE(mmval::primaryRank());
  ::setenv("OMPI_COMM_WORLD_RANK", "1", 1);
  const fs::path dir = fs::temp_directory_path() / "mmval-rank-test";
  fs::remove_all(dir);
  mmval::writeFileAtomic(dir / "a.txt", "x");
  EXPECT_FALSE(fs::exists(dir / "a.txt"));  // a second rank writes nothing
  if (keep_ompi) ::setenv("OMPI_COMM_WORLD_RANK", ompi.c_str(), 1); else ::unsetenv("OMPI_COMM_WORLD_RANK");
  if (keep_pmi) ::setenv("PMI_RANK", pmi.c_str(), 1); else ::unsetenv("PMI_RANK");
}
