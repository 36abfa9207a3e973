// Child processes of a command that runs other mmval commands (`mmval sweep --jobs N`): started
// with their stderr in a log file, waited for one at a time, never left behind.
#pragma once
#include <chrono>
#include <cstddef>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include <sys/types.h>

namespace mmval::validate::detail {

/// One child: its process, the caller's index for it, its stderr log and when it started.
struct Child {
  pid_t pid = -1;
  std::size_t index = 0;
  std::filesystem::path log;
  std::chrono::steady_clock::time_point start;
};

/// The children still running. Going out of scope (an exception on the way) it waits for each of
/// them, so that a command never leaves a child behind writing into its folder.
class Children {
 public:
  Children() = default;
  Children(const Children&) = delete;
  Children& operator=(const Children&) = delete;
  ~Children();
  std::size_t size() const { return m_running.size(); }

  /// Starts `executable` with `args` (args[0] is the name it sees), stdin and stdout on /dev/null,
  /// stderr into `child.log`. The child gets SIGTERM if its parent dies first (PR_SET_PDEATHSIG).
  void start(const std::string& executable, const std::vector<std::string>& args, Child child);

  /// Waits until a child ends; returns it and its wait status (-1: not readable).
  std::pair<Child, int> wait();

 private:
  std::vector<Child> m_running;
};

/// A file's whole text ("" when it cannot be read).
std::string fileText(const std::filesystem::path& file);

/// The message after the last `prefix` in a child's stderr, without its final newline ("" when none).
std::string messageAfter(const std::string& log, const std::string& prefix);

/// A child's wait status in words: "exit status 4 (a bug in mmval)", "killed by signal 9 (Killed)".
std::string statusText(int status);

}  // namespace mmval::validate::detail
