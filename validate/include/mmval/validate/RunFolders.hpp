// Output folders that hold several runs (validate, sweep): how an earlier
// complete run is recognised, and which folders such a command may write into.
#pragma once
#include <filesystem>
#include <optional>

#include <nlohmann/json.hpp>

#include "mmval/core/Case.hpp"

namespace mmval::validate {

/// A complete earlier run of the same case (same hash, overrides included) in
/// `dir`: its result.json, or nothing when there is none, it does not parse or
/// its case hash differs.
std::optional<nlohmann::json> earlierRun(const Case& c, const std::filesystem::path& dir);

/// Commands that keep earlier runs in their --out folder write into it rather
/// than replacing it, so the folder must be new, empty or mmval's own; throws
/// InputError (checkReplaceable's message) otherwise.
void requireOwnedFolder(const std::filesystem::path& out);

}  // namespace mmval::validate
