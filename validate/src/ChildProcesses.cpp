#include "ChildProcesses.hpp"

#include <cerrno>
#include <csignal>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <fcntl.h>
#include <sys/prctl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace fs = std::filesystem;

namespace mmval::validate::detail {

Children::~Children() {
  for (const Child& c : m_running) {
    int status = 0;
    while (::waitpid(c.pid, &status, 0) < 0 && errno == EINTR) {
    }
  }
}

void Children::start(const std::string& executable, const std::vector<std::string>& args, Child child) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  const int log_fd = ::open(child.log.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (log_fd < 0) throw std::runtime_error("cannot write " + child.log.string() + ": " + std::strerror(errno));
  const int null_fd = ::open("/dev/null", O_RDWR | O_CLOEXEC);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid == 0) {
    // Only async-signal-safe calls between fork and exec.
    ::prctl(PR_SET_PDEATHSIG, SIGTERM);
    if (::getppid() != parent) ::_exit(127);
    if (null_fd >= 0) {
      ::dup2(null_fd, STDIN_FILENO);
      ::dup2(null_fd, STDOUT_FILENO);
    }
    ::dup2(log_fd, STDERR_FILENO);
    ::execv(executable.c_str(), argv.data());
    const char message[] = "mmval: cannot start a child process (execv failed)\n";
    [[maybe_unused]] const ssize_t written = ::write(STDERR_FILENO, message, sizeof message - 1);
    ::_exit(127);
  }
  const int fork_errno = errno;
  ::close(log_fd);
  if (null_fd >= 0) ::close(null_fd);
  if (pid < 0) throw std::runtime_error(std::string("cannot start a child process: ") + std::strerror(fork_errno));
  child.pid = pid;
  m_running.push_back(std::move(child));
}

std::pair<Child, int> Children::wait() {
  for (;;) {
    for (std::size_t i = 0; i < m_running.size(); ++i) {
      int status = 0;
      const pid_t got = ::waitpid(m_running[i].pid, &status, WNOHANG);
      if (got == m_running[i].pid || (got < 0 && errno == ECHILD)) {
        Child c = std::move(m_running[i]);
        m_running.erase(m_running.begin() + static_cast<std::ptrdiff_t>(i));
        return {std::move(c), got < 0 ? -1 : status};
      }
    }
    // Polling (not waitpid(-1)) so that only these children are reaped.
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

std::string fileText(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string messageAfter(const std::string& log, const std::string& prefix) {
  const std::size_t at = log.rfind(prefix);
  if (at == std::string::npos) return {};
  std::string m = log.substr(at + prefix.size());
  while (!m.empty() && (m.back() == '\n' || m.back() == '\r')) m.pop_back();
  return m;
}

std::string statusText(int status) {
  if (status < 0) return "an exit status that could not be read";
  if (WIFSIGNALED(status)) return fmt::format("killed by signal {} ({})", WTERMSIG(status), strsignal(WTERMSIG(status)));
  const int code = WEXITSTATUS(status);
  const char* meaning = code == static_cast<int>(ExitCode::usage)       ? "wrong command-line usage"
                        : code == static_cast<int>(ExitCode::bad_input) ? "invalid input"
                        : code == static_cast<int>(ExitCode::internal)  ? "a bug in mmval"
                        : code == 127                                   ? "the process could not start"
                                                                        : "not one of mmval's exit statuses";
  return fmt::format("exit status {} ({})", code, meaning);
}

}  // namespace mmval::validate::detail
