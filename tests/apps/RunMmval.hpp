// Runs the built `mmval` command as a user would, for the command-line tests:
// its exit status, what it printed (stdout and stderr together), its wall
// time and, where /usr/bin/time exists, its peak memory.
#pragma once
#include <sys/wait.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <regex>
#include <string>

namespace mmval::test {

struct Outcome {
  int status = -1;
  std::string output;     ///< stdout and stderr together
  double seconds = 0;     ///< wall time
  double peak_bytes = 0;  ///< maximum resident set size; 0 when not measured
};

/// Runs `mmval ARGS`; `env` (e.g. "VAR=value ") goes in front of the command.
/// With `measure_memory`, runs it under /usr/bin/time to fill peak_bytes.
inline Outcome runMmval(const std::string& args, const std::string& env = "", bool measure_memory = false) {
  const std::string time = measure_memory ? "/usr/bin/time -f 'peak_kb=%M' " : "";
  const std::string cmd = env + time + std::string(MMVAL_BINARY_DIR) + "/bin/mmval " + args + " 2>&1";
  Outcome o;
  const auto t0 = std::chrono::steady_clock::now();
  FILE* pipe = popen(cmd.c_str(), "r");
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe) != nullptr) o.output += buf.data();
  const int raw = pclose(pipe);
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  std::smatch m;
  if (measure_memory && std::regex_search(o.output, m, std::regex("peak_kb=([0-9]+)"))) o.peak_bytes = std::stod(m[1].str()) * 1024;
  return o;
}

/// A fresh folder build/test-output/<group>/<name> for one test.
inline std::filesystem::path freshTestFolder(const std::string& group, const std::string& name) {
  const std::filesystem::path d = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / group / name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace mmval::test
