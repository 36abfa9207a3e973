// The message of the InputError a call throws, for tests of error wording.
#pragma once
#include <functional>
#include <string>

#include "mmval/core/Error.hpp"

namespace mmval::test {

/// what() of the InputError `f` throws, or "(no InputError)" when it throws none.
inline std::string inputErrorMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

}  // namespace mmval::test
