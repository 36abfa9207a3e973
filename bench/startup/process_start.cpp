// Process start of the mmval command: what every invocation pays before it does
// anything (the dynamic loader mapping and relocating the shared libraries mmval
// needs, their constructors, mmval's own registration of case kinds and commands).
// `mmval --version` does nothing else; `mmval track --help` also builds the command
// line of one subcommand. `true` is the floor: starting any process on this machine.
// Never asserts on time.
//
//   libraries    shared libraries the loader maps for mmval (LD_TRACE_LOADED_OBJECTS, as ldd)
//   wall         median and fastest wall time of one run, ms
//   cpu          median user + system CPU time of one run (the child's rusage), ms
//
// The machine's load changes wall times; CPU time is the steadier measure. Quote
// ratios from one run.
//
// Usage: bench_process_start [--runs N] [MMVAL]   (MMVAL: the mmval executable to start;
// default: the one built beside this benchmark)
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

extern char** environ;

namespace {

struct Timing {
  double wall_ms = 0;
  double cpu_ms = 0;
};

/// Starts `args` with stdout and stderr to /dev/null (plus `extra_env`), waits for it.
/// Throws nothing: a program that cannot start reports a negative time.
Timing runOnce(const std::vector<std::string>& args, const std::vector<std::string>& extra_env, std::string* output = nullptr) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  std::vector<std::string> env_store(extra_env);
  for (char** e = environ; *e != nullptr; ++e) env_store.emplace_back(*e);
  std::vector<char*> envp;
  for (auto& e : env_store) envp.push_back(e.data());
  envp.push_back(nullptr);
  int pipe_fds[2] = {-1, -1};
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (output != nullptr && pipe(pipe_fds) == 0) {
    posix_spawn_file_actions_adddup2(&actions, pipe_fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, pipe_fds[0]);
  } else {
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  }
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, "/dev/null", O_WRONLY, 0);
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int spawned = posix_spawnp(&pid, argv[0], &actions, nullptr, argv.data(), envp.data());
  posix_spawn_file_actions_destroy(&actions);
  if (pipe_fds[1] >= 0) close(pipe_fds[1]);
  if (spawned != 0) {
    if (pipe_fds[0] >= 0) close(pipe_fds[0]);
    return {-1, -1};
  }
  if (output != nullptr && pipe_fds[0] >= 0) {
    char buf[4096];
    ssize_t n = 0;
    while ((n = read(pipe_fds[0], buf, sizeof buf)) > 0) output->append(buf, static_cast<std::size_t>(n));
    close(pipe_fds[0]);
  }
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  const auto t1 = std::chrono::steady_clock::now();
  auto ms = [](const timeval& t) { return 1e3 * static_cast<double>(t.tv_sec) + 1e-3 * static_cast<double>(t.tv_usec); };
  return {std::chrono::duration<double, std::milli>(t1 - t0).count(), ms(usage.ru_utime) + ms(usage.ru_stime)};
}

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : (v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]));
}

void report(const char* label, const std::vector<std::string>& args, int runs) {
  runOnce(args, {});  // warms the page cache
  std::vector<double> wall, cpu;
  for (int i = 0; i < runs; ++i) {
    const Timing t = runOnce(args, {});
    wall.push_back(t.wall_ms);
    cpu.push_back(t.cpu_ms);
  }
  std::printf("%-22s %10.1f %10.1f %10.1f\n", label, median(wall), *std::min_element(wall.begin(), wall.end()), median(cpu));
}

}  // namespace

int main(int argc, char** argv) {
  int runs = 20;
  std::string mmval = MMVAL_EXE;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--runs") == 0 && i + 1 < argc)
      runs = std::max(1, std::atoi(argv[++i]));
    else
      mmval = argv[i];
  }
  std::string listing;
  runOnce({mmval, "--version"}, {"LD_TRACE_LOADED_OBJECTS=1"}, &listing);
  int objects = 0;
  for (std::size_t p = listing.find("=>"); p != std::string::npos; p = listing.find("=>", p + 2)) ++objects;
  std::printf("mmval: %s\nshared libraries loaded: %d\nruns: %d\n\n", mmval.c_str(), objects, runs);
  std::printf("%-22s %10s %10s %10s\n", "command", "wall ms", "fastest ms", "cpu ms");
  report("true", {"true"}, runs);
  report("mmval --version", {mmval, "--version"}, runs);
  report("mmval track --help", {mmval, "track", "--help"}, runs);
  return 0;
}
