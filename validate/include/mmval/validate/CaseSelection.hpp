// Which case files a validation runs: the cases folder and the tag selection.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "mmval/core/CaseKind.hpp"

namespace mmval::validate {

/// Case files (*.toml) directly under `dir` whose case.tags contain one of
/// `wanted` ("all" selects every case), sorted by file name, compare-tracks
/// cases last because comparisons read the other cases' outputs. Throws
/// InputError when `dir` is not a folder, a case file is invalid, or two
/// chosen cases share a case.name (their run folders would collide).
std::vector<std::filesystem::path> casesTagged(const std::filesystem::path& dir, const std::vector<std::string>& wanted,
                                               const CaseKindRegistry& registry);

/// The cases folder a validation reads: `given` (--cases) when not empty, else
/// the example cases of mmval's data folder (core/include/mmval/core/DataPaths.hpp),
/// else ./cases. Throws InputError naming --cases when none exists.
std::filesystem::path casesFolder(const std::string& given);

}  // namespace mmval::validate
