// Which case files a validation runs: the cases folder and the tag selection.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include "mmval/core/CaseKind.hpp"

namespace mmval::validate {

/// Whether a case with tags `case_tags` runs under `--tag tag` (with `--full` when `full`):
///  - "all" selects every case;
///  - "default" (plain `mmval validate`) selects the cases tagged "default", and with --full also
///    every case tagged "full" (the longer campaign);
///  - any other tag T selects the cases tagged T that are not tagged "full", and with --full also
///    those tagged both T and "full" (so `--tag paper --full` adds the paper's full-length scenes,
///    not every full case). `--tag full` selects the cases tagged "full".
bool caseSelected(const std::vector<std::string>& case_tags, const std::string& tag, bool full);

/// Case files (*.toml) directly under `dir` selected by caseSelected(tags, tag, full), sorted by
/// file name, compare-tracks cases last because comparisons read the other cases' outputs.
/// Throws InputError when `dir` is not a folder, a case file is invalid, or two chosen cases
/// share a case.name (their run folders would collide).
std::vector<std::filesystem::path> casesTagged(const std::filesystem::path& dir, const std::string& tag, bool full,
                                               const CaseKindRegistry& registry);

/// True when some case under `dir` carries `tag` and "full" (what --full would add to a selection that found nothing).
bool fullOnlyTag(const std::filesystem::path& dir, const std::string& tag, const CaseKindRegistry& registry);

/// The cases folder a validation reads: `given` (--cases) when not empty, else
/// the example cases of mmval's data folder (core/include/mmval/core/DataPaths.hpp),
/// else ./cases. Throws InputError naming --cases when none exists.
std::filesystem::path casesFolder(const std::string& given);

}  // namespace mmval::validate
