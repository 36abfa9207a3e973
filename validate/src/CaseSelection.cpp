#include "mmval/validate/CaseSelection.hpp"

#include <algorithm>
#include <map>

#include "mmval/core/Case.hpp"
#include "mmval/core/DataPaths.hpp"
#include "mmval/core/Error.hpp"

namespace fs = std::filesystem;

namespace mmval::validate {

namespace {
bool has(const std::vector<std::string>& tags, const std::string& tag) { return std::find(tags.begin(), tags.end(), tag) != tags.end(); }

std::vector<fs::path> caseFiles(const fs::path& dir) {
  if (!fs::is_directory(dir)) throw InputError({dir.string(), 0, 0, {}}, "cases folder not found", dir.string(), "a folder of *.toml case files (--cases)");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".toml") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}
}  // namespace

bool caseSelected(const std::vector<std::string>& case_tags, const std::string& tag, bool full) {
  if (tag == "all") return true;
  const bool is_full = has(case_tags, "full");
  if (tag == "default") return has(case_tags, "default") || (full && is_full);
  if (tag == "full") return is_full;
  return has(case_tags, tag) && (full || !is_full);
}

bool fullOnlyTag(const fs::path& dir, const std::string& tag, const CaseKindRegistry& registry) {
  for (const auto& f : caseFiles(dir)) {
    const Case c = Case::load(f, registry);
    const auto& tags = c.strings("case.tags");
    if (has(tags, tag) && has(tags, "full")) return true;
  }
  return false;
}

std::vector<fs::path> casesTagged(const fs::path& dir, const std::string& tag, bool full, const CaseKindRegistry& registry) {
  const std::vector<fs::path> files = caseFiles(dir);
  // Comparisons read other cases' outputs, so they run after everything else.
  std::vector<fs::path> out, last;
  std::map<std::string, fs::path> by_name;  // run folders are named after the case: one case per name
  for (const auto& f : files) {
    const Case c = Case::load(f, registry);
    const bool chosen = caseSelected(c.strings("case.tags"), tag, full);
    if (!chosen) continue;
    const auto [it, fresh] = by_name.emplace(c.name(), f);
    if (!fresh)
      throw InputError(c.where("case.name"), "two cases of this validation have the same name (their runs would overwrite each other)",
                       "\"" + c.name() + "\" in " + it->second.string() + " and " + f.string(), "a distinct case.name in each file");
    (c.kind() == "compare-tracks" ? last : out).push_back(f);
  }
  out.insert(out.end(), last.begin(), last.end());
  return out;
}

fs::path casesFolder(const std::string& given) {
  if (!given.empty()) return given;
  if (const fs::path dir = exampleCasesDirectory(); !dir.empty()) return dir;
  if (fs::is_directory("cases")) return "cases";
  throw InputError({"(command line)", 0, 0, "--cases"}, "no cases folder given and none found", dataDirectorySearched(),
                   "--cases DIR, or MMVAL_DATA_DIR set to a folder holding cases/ and reference-data/");
}

}  // namespace mmval::validate
