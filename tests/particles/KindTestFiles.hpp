// What the micromodel kind's end-to-end tests share (BookkeepingTest, MicromodelCaseTest,
// ParcelWeightTest): one folder per test, a grain mask written as a PGM, a file read whole, a
// case run in the test's folder and a metric read from its summary.
#pragma once
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

namespace mmval::particles::test_support {

/// build / tests / particles / `group` / <suite>.<test>: one folder per test, since ctest runs the
/// tests of a file as parallel processes.
inline std::filesystem::path kindTestDir(const std::string& group) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  return std::filesystem::path(MMVAL_BINARY_DIR) / "tests" / "particles" / group / (std::string(info->test_suite_name()) + "." + info->name());
}

/// Binary PGM (OpenCV reads it) of `cols` x `rows` pixels: 0 where `grain(c, r)` (dark), else 255.
inline void writeGrainPgm(const std::filesystem::path& file, int cols, int rows, const std::function<bool(int, int)>& grain) {
  std::filesystem::create_directories(file.parent_path());
  std::ofstream f(file, std::ios::binary);
  f << "P5\n" << cols << " " << rows << "\n255\n";
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) f.put(static_cast<char>(grain(c, r) ? 0 : 255));
}

/// The mask `name` in the test's folder of `group` (writeGrainPgm); returns its path.
inline std::filesystem::path writeTestMask(const std::string& group, const std::string& name, int cols, int rows, const std::function<bool(int, int)>& grain) {
  const std::filesystem::path file = kindTestDir(group) / name;
  writeGrainPgm(file, cols, rows, grain);
  return file;
}

/// The whole file as text.
inline std::string readText(const std::filesystem::path& f) {
  std::ifstream in(f);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Runs case texts of the particle kinds in the test's folder of `group`, quietly.
struct KindRunner {
  CaseKindRegistry reg;
  std::string group;
  explicit KindRunner(std::string g) : group(std::move(g)) { registerParticleKinds(reg); }
  RunSummary run(const std::string& text, const std::string& dir, bool resume = false) {
    const std::filesystem::path d = kindTestDir(group);
    const Case c = Case::parse(text, d / (dir + ".toml"), reg);
    return runCase(c, reg, d / dir, {.quiet = true, .resume = resume});
  }
};

/// The summary's metric `name` (a test failure, and NaN, if it has none).
inline double metricOf(const RunSummary& s, const std::string& name) {
  for (const auto& m : s.metrics)
    if (m.name == name) return m.value;
  ADD_FAILURE() << "no metric " << name;
  return NAN;
}

}  // namespace mmval::particles::test_support
