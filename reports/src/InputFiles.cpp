#include "mmval/reports/InputFiles.hpp"

#include <algorithm>
#include <fstream>
#include <sstream>
#include <system_error>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace fs = std::filesystem;

namespace mmval::reports {

namespace {

std::string sizeText(std::uintmax_t bytes) {
  constexpr std::uintmax_t kMebibyte = std::uintmax_t{1} << 20;
  return bytes < kMebibyte ? fmt::format("{} bytes", bytes) : fmt::format("{:.1f} MiB", static_cast<double>(bytes) / kMebibyte);
}

void checkReadable(const fs::path& file, std::uintmax_t max_bytes) {
  const std::string name = file.string();
  std::error_code ec;
  const fs::file_status status = fs::status(file, ec);
  if (!fs::exists(status)) throw InputError({name, 0, 0, {}}, "no such file", {}, "a file written by mmval");
  if (fs::is_directory(status)) throw InputError({name, 0, 0, {}}, "is a folder, not a file", {}, "a file written by mmval");
  if (!fs::is_regular_file(status)) throw InputError({name, 0, 0, {}}, "not a regular file", {}, "a file written by mmval");
  const std::uintmax_t size = fs::file_size(file, ec);
  if (ec) throw InputError({name, 0, 0, {}}, "cannot read its size: " + ec.message(), {}, "a readable file");
  if (size > max_bytes)
    throw InputError({name, 0, 0, {}}, "file too large to be one mmval wrote", sizeText(size), "at most " + sizeText(max_bytes));
}

/// 1-based line of byte offset `byte` (nlohmann counts bytes read, the failing one included).
int lineOf(const std::string& text, std::size_t byte) {
  const auto end = text.begin() + static_cast<std::ptrdiff_t>(std::min(byte, text.size()));
  return 1 + static_cast<int>(std::count(text.begin(), end, '\n'));
}

}  // namespace

std::string readInputFile(const fs::path& file, std::uintmax_t max_bytes) {
  checkReadable(file, max_bytes);
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError({file.string(), 0, 0, {}}, "cannot open for reading", {}, "a file the user running mmval can read");
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

nlohmann::json readJsonFile(const fs::path& file, std::uintmax_t max_bytes) {
  const std::string text = readInputFile(file, max_bytes);
  if (text.find_first_not_of(" \t\r\n") == std::string::npos)
    throw InputError({file.string(), 0, 0, {}}, "empty file", text.empty() ? std::string("0 bytes") : fmt::format("{} bytes of white space only", text.size()),
                     "a JSON document written by mmval");
  try {
    return nlohmann::json::parse(text);
  } catch (const nlohmann::json::parse_error& e) {
    throw InputError({file.string(), lineOf(text, e.byte == 0 ? 0 : e.byte - 1), 0, {}}, std::string("not valid JSON: ") + e.what(), {},
                     "a JSON document written by mmval");
  } catch (const nlohmann::json::exception& e) {
    // The parser also throws out_of_range, e.g. for a number beyond double ("1e400"; found by fuzz_result_json).
    throw InputError({file.string(), 0, 0, {}}, std::string("not usable JSON: ") + e.what(), {}, "a JSON document written by mmval");
  }
}

}  // namespace mmval::reports
