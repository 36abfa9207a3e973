// Reading the files a report is built from (result.json, compare's
// metrics.json and CSVs, PNG images), which may be anything a user points at:
// missing, empty, not JSON, of the wrong shape, or far too large.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace mmval::reports {

/// Largest file a report reads whole: 256 MiB. mmval's own outputs read here
/// are a few MB at most (the largest, a force history, is ~10 MB); a larger
/// file is not one of them, and reading it would exhaust memory first.
inline constexpr std::uintmax_t kMaxInputBytes = std::uintmax_t{256} << 20;

/// The bytes of `file`. Throws InputError naming it when it is missing, not a
/// regular file, unreadable or larger than `max_bytes`.
std::string readInputFile(const std::filesystem::path& file, std::uintmax_t max_bytes = kMaxInputBytes);

/// `file` parsed as JSON. Throws InputError naming it (and the line of a
/// syntax error) when it cannot be read (see readInputFile), is empty or is not JSON.
nlohmann::json readJsonFile(const std::filesystem::path& file, std::uintmax_t max_bytes = kMaxInputBytes);

}  // namespace mmval::reports
