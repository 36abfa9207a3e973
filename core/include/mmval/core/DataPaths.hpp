// Where mmval finds its own data (reference-data/ and the example cases/)
// when it runs from a build tree, from an installed prefix, or from anywhere
// with MMVAL_DATA_DIR set. The lookup order, first match wins:
//   1. $MMVAL_DATA_DIR (a folder holding reference-data/ and, usually, cases/);
//   2. <folder of the mmval executable>/../share/mmval (what `cmake --install` lays out);
//   3. the source tree, for a binary that lives inside the build tree it was built in.
// A folder counts only if it holds reference-data/.
#pragma once
#include <filesystem>
#include <string>

namespace mmval {

/// Name of the environment variable that overrides the lookup.
inline constexpr const char* kDataDirVariable = "MMVAL_DATA_DIR";

/// The data folder found by the lookup above, made absolute. Throws InputError
/// naming MMVAL_DATA_DIR when that variable is set but is not such a folder
/// (a wrong setting is not silently skipped); returns an empty path when
/// nothing is found.
std::filesystem::path dataDirectory();

/// The places dataDirectory() looks, in order, for messages ("MMVAL_DATA_DIR
/// (unset), /opt/mmval/bin/../share/mmval, ...").
std::string dataDirectorySearched();

/// dataDirectory() / "reference-data", or an empty path.
std::filesystem::path referenceDataDirectory();

/// dataDirectory() / "cases" when that folder exists, or an empty path.
std::filesystem::path exampleCasesDirectory();

/// std::filesystem::exists and is_regular_file without their throwing
/// overloads: a path the system cannot even examine (a name longer than the
/// system allows, a parent folder without permission) counts as absent, so a
/// caller reports "not found" as an InputError naming the path instead of
/// ending on an uncaught filesystem_error. Paths come from users' files.
bool pathExists(const std::filesystem::path& p) noexcept;
bool isRegularFile(const std::filesystem::path& p) noexcept;
bool isDirectory(const std::filesystem::path& p) noexcept;

}  // namespace mmval
