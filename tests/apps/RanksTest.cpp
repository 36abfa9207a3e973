// Determinism and MPI ranks of the coupled micromodel scene: the same
// seed on the same ranks gives byte-identical outputs, and 2 ranks give the 1-rank
// scene. Ranks share the fluid solve (PETSc distributes its rows; the answer is the
// same to solver tolerance) and every rank moves all particles with the same random
// streams, so 2 ranks must reproduce the 1-rank trajectories up to the fluid
// solver's tolerance (measured 1e-5 um, the printed precision), not merely within
// statistical noise. The scene is the default case, shortened to 6 s.
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// Runs `cmd` with its output in `log`; "" when it exits 0, else the exit status and
/// the log's last 2000 characters, so that a failure shows its cause.
std::string shell(const std::string& cmd, const fs::path& log) {
  const int raw = std::system((cmd + " > " + log.string() + " 2>&1").c_str());
  const int code = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  if (code == 0) return "";
  const std::string text = slurp(log);
  return "exit " + std::to_string(code) + " from: " + cmd + "\n" + text.substr(text.size() > 2000 ? text.size() - 2000 : 0);
}

/// The default micromodel case with an absolute mask path and a 6 s duration.
fs::path shortScene(const fs::path& dir) {
  std::string text = slurp(fs::path(MMVAL_SOURCE_DIR) / "cases" / "particles-micromodel.toml");
  text = std::regex_replace(text, std::regex(R"(mask = "[^"]*")"), "mask = \"" + (fs::path(MMVAL_SHARED_DATA_DIR) / "pore2chip" / "grain_network.png").string() + "\"");
  text = std::regex_replace(text, std::regex(R"(duration = "[^"]*")"), "duration = \"6 s\"");
  text = std::regex_replace(text, std::regex(R"(output_interval = "[^"]*")"), "output_interval = \"0.05 s\"");
  fs::create_directories(dir);
  const fs::path f = dir / "scene.toml";
  std::ofstream(f) << text;
  return f;
}

std::vector<std::vector<std::string>> csv(const fs::path& p) {
  std::vector<std::vector<std::string>> rows;
  std::ifstream in(p);
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> r;
    std::stringstream s(line);
    std::string cell;
    while (std::getline(s, cell, ',')) r.push_back(cell);
    rows.push_back(r);
  }
  return rows;
}

TEST(Ranks, MicromodelSceneIsDeterministicAndTwoRanksGiveTheOneRankScene) {
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / "ranks";
  fs::remove_all(dir);
  const fs::path scene = shortScene(dir);
  const std::string mmval = std::string(MMVAL_BINARY_DIR) + "/bin/mmval run " + scene.string() + " --quiet --out ";
  ASSERT_EQ(shell(mmval + (dir / "a").string(), dir / "a.log"), "");
  ASSERT_EQ(shell(mmval + (dir / "b").string(), dir / "b.log"), "");
  ASSERT_EQ(shell(std::string(MMVAL_MPIEXEC) + " -n 2 --oversubscribe " + mmval + (dir / "np2").string(), dir / "np2.log"), "");
  for (const char* f : {"trajectories.csv", "retention.csv", "permeability.csv"})
    EXPECT_EQ(slurp(dir / "a" / f), slurp(dir / "b" / f)) << f << ": same seed, same ranks, different output";

  // 2 ranks: same rows (frame, particle, state), same counts, positions within 1 nm.
  const auto one = csv(dir / "a" / "trajectories.csv"), two = csv(dir / "np2" / "trajectories.csv");
  ASSERT_EQ(one.size(), two.size());
  ASSERT_GT(one.size(), 1000u);
  const auto& head = one[0];
  double worst = 0;
  for (std::size_t r = 1; r < one.size(); ++r) {
    ASSERT_EQ(one[r].size(), head.size());
    ASSERT_EQ(two[r].size(), head.size());
    for (std::size_t k = 0; k < head.size(); ++k) {
      if (head[k] == "x_um" || head[k] == "y_um" || head[k] == "z_um")
        worst = std::max(worst, std::abs(std::stod(one[r][k]) - std::stod(two[r][k])));
      else if (head[k] == "frame" || head[k] == "particle" || head[k] == "state") {
        ASSERT_EQ(one[r][k], two[r][k]) << "row " << r << " column " << head[k];
      }
    }
  }
  std::printf("1 vs 2 ranks: %zu trajectory rows, largest position difference %.3g um\n", one.size() - 1, worst);
  EXPECT_LT(worst, 1e-3);
  EXPECT_EQ(slurp(dir / "a" / "retention.csv"), slurp(dir / "np2" / "retention.csv"));
}

}  // namespace
