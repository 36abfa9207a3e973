#include "mmval/validate/CaseSelection.hpp"

#include <algorithm>
#include <map>

#include "mmval/core/Case.hpp"
#include "mmval/core/DataPaths.hpp"
#include "mmval/core/Error.hpp"

namespace fs = std::filesystem;

namespace mmval::validate {

std::vector<fs::path> casesTagged(const fs::path& dir, const std::vector<std::string>& wanted, const CaseKindRegistry& registry) {
  if (!fs::is_directory(dir)) throw InputError({dir.string(), 0, 0, {}}, "cases folder not found", dir.string(), "a folder of *.toml case files (--cases)");
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().extension() == ".toml") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  // Comparisons read other cases' outputs, so they run after everything else.
  std::vector<fs::path> out, last;
  std::map<std::string, fs::path> by_name;  // run folders are named after the case: one case per name
  for (const auto& f : files) {
    const Case c = Case::load(f, registry);
    const auto& tags = c.strings("case.tags");
    const bool chosen = std::any_of(wanted.begin(), wanted.end(), [&](const std::string& tag) {
      return tag == "all" || std::find(tags.begin(), tags.end(), tag) != tags.end();
    });
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
