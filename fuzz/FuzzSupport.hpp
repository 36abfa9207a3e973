// Helpers shared by the fuzz targets: a scratch folder per process, and the
// rule for what counts as a finding.
//
// A target catches the exceptions its function documents (InputError, and
// UnitError for the units parser) as the expected outcome of bad input.
// Anything else is a finding: a sanitizer report (memory error, undefined
// behaviour, leak), an assertion, a timeout, or another exception escaping,
// which libFuzzer reports as a crash through std::terminate. `mmval` would
// exit 4 ("a bug in mmval") on such an exception.
#pragma once
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

namespace mmval::fuzz {

inline std::string_view asText(const std::uint8_t* data, std::size_t size) {
  return {reinterpret_cast<const char*>(data), size};
}

/// A folder for this process's files, removed at exit.
inline const std::filesystem::path& scratchDir() {
  struct Dir {
    std::filesystem::path path;
    Dir() {
      path = std::filesystem::temp_directory_path() / ("mmval-fuzz-" + std::to_string(::getpid()));
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

inline void writeFile(const std::filesystem::path& file, std::string_view bytes) {
  std::ofstream out(file, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

}  // namespace mmval::fuzz
