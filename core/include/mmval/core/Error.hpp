// Errors shared by every mmval library.
//
// InputError is thrown for anything a user can fix: a malformed case file, an
// unreadable image, a bad unit. Its message names the file, the line or key,
// the bad value and what was expected, so that the command line can print it
// verbatim and exit with status 2. It stays on in Release builds.
#pragma once

#include <stdexcept>
#include <string>

namespace mmval {

/// Process exit codes used by the `mmval` command.
enum class ExitCode : int {
  ok = 0,
  usage = 1,          ///< wrong command-line usage
  bad_input = 2,      ///< an input file or value is invalid (InputError)
  metric_failed = 3,  ///< a run completed but an acceptance metric failed
  internal = 4,       ///< a bug in mmval, and nothing else
  numerical = 5,      ///< the numerics failed on a valid input (diverged, gap under one cell, ...): NumericalFailure
};

/// Where in an input a problem is. Empty fields are left out of the message.
struct InputLocation {
  std::string file;  ///< path as the user gave it
  int line = 0;      ///< 1-based; 0 when unknown
  int column = 0;    ///< 1-based; 0 when unknown
  std::string key;   ///< dotted key path ("fluid.viscosity") or CSV column
};

/// A problem with user input. `what()` reads, for example:
///   cases/st.toml:12: key 'fluid.viscosity': got "1e-3 m/s"; expected a dynamic viscosity in Pa s
class InputError : public std::runtime_error {
 public:
  InputError(InputLocation where, std::string problem, std::string got = {}, std::string expected = {});

  const InputLocation& where() const noexcept { return m_where; }
  const std::string& problem() const noexcept { return m_problem; }
  const std::string& got() const noexcept { return m_got; }
  const std::string& expected() const noexcept { return m_expected; }

 private:
  InputLocation m_where;
  std::string m_problem;
  std::string m_got;
  std::string m_expected;
};

/// A run completed and wrote its results, but an acceptance metric failed
/// (exit status 3). The message summarises which.
class MetricsFailed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The input is valid but the numerics cannot handle it as set up: a flow
/// that diverged, a gap narrower than one cell, a solve that did not converge.
/// The message names the cause and `key` the case key to change (exit 5).
class NumericalFailure : public std::runtime_error {
 public:
  NumericalFailure(std::string cause, std::string key, std::string advice)
      : std::runtime_error(cause + (key.empty() ? std::string() : "; change '" + key + "'") +
                           (advice.empty() ? std::string() : ": " + advice)),
        m_key(std::move(key)) {}
  const std::string& key() const noexcept { return m_key; }

 private:
  std::string m_key;
};

/// Builds the message InputError uses; exposed for tests and for tools that
/// collect several problems before throwing.
std::string formatInputError(const InputLocation& where, const std::string& problem,
                             const std::string& got, const std::string& expected);

}  // namespace mmval
