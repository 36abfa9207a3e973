#include "mmval/core/Error.hpp"

namespace mmval {

std::string formatInputError(const InputLocation& where, const std::string& problem,
                             const std::string& got, const std::string& expected) {
  std::string msg;
  if (!where.file.empty()) {
    msg += where.file;
    if (where.line > 0) {
      msg += ":" + std::to_string(where.line);
      if (where.column > 0) msg += ":" + std::to_string(where.column);
    }
    msg += ": ";
  }
  if (!where.key.empty()) msg += "key '" + where.key + "': ";
  msg += problem;
  if (!got.empty()) msg += "; got " + got;
  if (!expected.empty()) msg += "; expected " + expected;
  return msg;
}

InputError::InputError(InputLocation where, std::string problem, std::string got, std::string expected)
    : std::runtime_error(formatInputError(where, problem, got, expected)),
      m_where(std::move(where)),
      m_problem(std::move(problem)),
      m_got(std::move(got)),
      m_expected(std::move(expected)) {}

}  // namespace mmval
