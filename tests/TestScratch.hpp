// Scratch paths for tests, one folder per test process: test binaries of
// another checkout (or another ctest job) may run at the same time, and fixed
// names under the temporary folder made them overwrite each other's files.
#pragma once
#include <filesystem>
#include <string>

#include <unistd.h>

namespace mmval::test {

/// temp / "mmval-test-<pid>" / name; the folder is created, `name` is not.
inline std::filesystem::path scratch(const std::string& name) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("mmval-test-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  return dir / name;
}

}  // namespace mmval::test
