#include "mmval/core/DataPaths.hpp"

#include <algorithm>
#include <cstdlib>
#include <optional>
#include <vector>

#include "mmval/core/Error.hpp"

namespace fs = std::filesystem;

namespace mmval {

namespace {

bool holdsData(const fs::path& dir) {
  std::error_code ec;
  return fs::is_directory(dir / "reference-data", ec);
}

/// The running executable (Linux: /proc/self/exe); empty when unknown.
fs::path executablePath() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  return ec ? fs::path() : exe;
}

/// True when `inner` lies inside `outer` (both made canonical where they exist).
bool inside(const fs::path& inner, const fs::path& outer) {
  std::error_code ec;
  const fs::path a = fs::weakly_canonical(inner, ec);
  if (ec) return false;
  const fs::path b = fs::weakly_canonical(outer, ec);
  if (ec || b.empty()) return false;
  const auto [end, it] = std::mismatch(b.begin(), b.end(), a.begin(), a.end());
  (void)it;
  return end == b.end();
}

/// The candidates of steps 2 and 3 of the lookup, in order.
std::vector<fs::path> builtInCandidates() {
  std::vector<fs::path> out;
  const fs::path exe = executablePath();
  if (!exe.empty()) out.push_back((exe.parent_path() / ".." / "share" / "mmval").lexically_normal());
#if defined(MMVAL_SOURCE_DIR) && defined(MMVAL_BINARY_DIR)
  // Only a binary of this build tree falls back to its sources: an installed
  // copy must not read a checkout that happens to still exist.
  if (exe.empty() || inside(exe, MMVAL_BINARY_DIR)) out.emplace_back(MMVAL_SOURCE_DIR);
#endif
  return out;
}

}  // namespace

fs::path dataDirectory() {
  if (const char* env = std::getenv(kDataDirVariable); env != nullptr && *env != '\0') {
    const fs::path dir = fs::absolute(env);
    if (!holdsData(dir))
      throw InputError({"(environment)", 0, 0, kDataDirVariable}, "not a folder holding mmval's reference-data/", env,
                       "the share/mmval folder of an installation or an mmval checkout, or unset it");
    return dir;
  }
  for (const auto& dir : builtInCandidates())
    if (holdsData(dir)) return fs::absolute(dir);
  return {};
}

std::string dataDirectorySearched() {
  const char* env = std::getenv(kDataDirVariable);
  std::string out = std::string(kDataDirVariable) + (env != nullptr && *env != '\0' ? " (" + std::string(env) + ")" : " (unset)");
  for (const auto& dir : builtInCandidates()) out += ", " + dir.string();
  return out;
}

fs::path referenceDataDirectory() {
  const fs::path dir = dataDirectory();
  return dir.empty() ? dir : dir / "reference-data";
}

fs::path exampleCasesDirectory() {
  const fs::path dir = dataDirectory();
  std::error_code ec;
  return !dir.empty() && fs::is_directory(dir / "cases", ec) ? dir / "cases" : fs::path();
}

bool pathExists(const fs::path& p) noexcept {
  std::error_code ec;
  return fs::exists(p, ec) && !ec;
}

bool isRegularFile(const fs::path& p) noexcept {
  std::error_code ec;
  return fs::is_regular_file(p, ec) && !ec;
}

bool isDirectory(const fs::path& p) noexcept {
  std::error_code ec;
  return fs::is_directory(p, ec) && !ec;
}

}  // namespace mmval
