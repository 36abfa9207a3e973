#include "mmval/core/ReferenceData.hpp"

#include <cmath>
#include <map>
#include <memory>
#include <mutex>
#include <regex>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "mmval/core/Case.hpp"
#include "mmval/core/DataPaths.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Utf8.hpp"
#include "mmval/core/Strings.hpp"
#include "TomlUtil.hpp"

namespace mmval {

std::string toString(const AtMap& at) {
  std::vector<std::string> parts;
  for (const auto& [k, v] : at) {
    if (const double* d = std::get_if<double>(&v))
      parts.push_back(fmt::format("{} = {:g}", k, *d));
    else
      parts.push_back(fmt::format("{} = \"{}\"", k, std::get<std::string>(v)));
  }
  return "{" + join(parts, ", ") + "}";
}

bool ReferenceRow::matches(const AtMap& conditions) const {
  for (const auto& [k, v] : conditions) {
    auto it = at.find(k);
    if (it == at.end() || it->second.index() != v.index()) return false;
    if (const double* d = std::get_if<double>(&v)) {
      const double r = std::get<double>(it->second);
      if (std::abs(r - *d) > 1e-9 * std::max(std::abs(r), std::abs(*d))) return false;
    } else if (std::get<std::string>(v) != std::get<std::string>(it->second)) {
      return false;
    }
  }
  return true;
}

const ReferenceSource& ReferenceFile::source(const std::string& id) const {
  for (const auto& s : sources)
    if (s.id == id) return s;
  throw InputError({path.string(), 0, 0, "sources"}, "no source with id '" + id + "'");
}

std::vector<const ReferenceRow*> ReferenceFile::find(const std::string& quantity, const AtMap& conditions) const {
  std::vector<const ReferenceRow*> out;
  for (const auto& r : rows)
    if (r.quantity == quantity && r.matches(conditions)) out.push_back(&r);
  return out;
}

namespace {

using detail::lineOf;

[[noreturn]] void fail(const std::filesystem::path& file, int line, const std::string& key, const std::string& problem,
                       const std::string& got = {}, const std::string& expected = {}) {
  throw InputError({file.string(), line, 0, key}, problem, got, expected);
}

void checkKeys(const std::filesystem::path& file, const toml::table& t, const std::string& prefix,
               const std::vector<std::string>& allowed) {
  for (auto&& [k, v] : t) {
    const std::string key(k.str());
    bool ok = false;
    for (const auto& a : allowed) ok = ok || a == key;
    if (!ok) {
      const std::string near = nearest(key, allowed);
      fail(file, lineOf(v), prefix + key, "unknown key", key,
           near.empty() ? "one of " + join(allowed, ", ") : "'" + near + "' (nearest valid key)");
    }
  }
}

std::string requireString(const std::filesystem::path& file, const toml::table& t, const std::string& key,
                          const std::string& prefix, int parent_line) {
  const toml::node* n = t.get(key);
  if (n == nullptr) fail(file, parent_line, prefix + key, "missing required key", {}, "a string");
  if (!n->is_string()) fail(file, lineOf(*n), prefix + key, "wrong type", detail::tomlTypeName(*n), "a string");
  return std::string(*n->value<std::string>());
}

std::optional<double> optionalNumber(const std::filesystem::path& file, const toml::table& t, const std::string& key,
                                     const std::string& prefix) {
  const toml::node* n = t.get(key);
  if (n == nullptr) return std::nullopt;
  if (!n->is_number()) fail(file, lineOf(*n), prefix + key, "wrong type", "a non-number", "a number");
  const double v = *n->value<double>();
  if (!std::isfinite(v)) fail(file, lineOf(*n), prefix + key, "not a finite number", fmt::format("{}", v), "a finite number");
  return v;
}

ReferenceFile parseReferenceFile(const std::filesystem::path& path) {
  toml::table doc;
  const std::string text = readTextFile(path, 16u << 20, "reference file", "a reference-data TOML file (format mmval-reference/1)");
  checkTomlText(text, path.string());
  try {
    doc = toml::parse(text, path.string());
  } catch (const toml::parse_error& e) {
    fail(path, static_cast<int>(e.source().begin.line), {}, "TOML syntax error: " + std::string(e.description()));
  }
  ReferenceFile file;
  file.path = path;
  checkKeys(path, doc, "", {"format", "title", "description", "setup", "sources", "rows"});
  const std::string format = requireString(path, doc, "format", "", 1);
  if (format != "mmval-reference/1") fail(path, lineOf(*doc.get("format")), "format", "unsupported format", format, "\"mmval-reference/1\"");
  file.title = requireString(path, doc, "title", "", 1);
  file.description = requireString(path, doc, "description", "", 1);
  if (doc.contains("setup")) {
    file.setup = requireString(path, doc, "setup", "", 1);
    if (!std::regex_match(file.setup, std::regex("[a-z0-9]+(-[a-z0-9]+)*")))
      fail(path, lineOf(*doc.get("setup")), "setup", "bad setup name", file.setup, "lower-case words joined by '-', e.g. \"unbounded-cylinder\"");
  }

  const toml::array* sources = doc["sources"].as_array();
  if (sources == nullptr || sources->empty()) fail(path, 0, "sources", "missing or empty", {}, "at least one [[sources]] table");
  for (std::size_t i = 0; i < sources->size(); ++i) {
    const toml::table* t = (*sources)[i].as_table();
    const std::string prefix = fmt::format("sources[{}].", i);
    if (t == nullptr) fail(path, lineOf((*sources)[i]), prefix, "not a table", {}, "[[sources]] tables");
    checkKeys(path, *t, prefix, {"id", "citation", "doi", "locator"});
    ReferenceSource s;
    s.id = requireString(path, *t, "id", prefix, lineOf(*t));
    if (!std::regex_match(s.id, std::regex("[a-z0-9_]+"))) fail(path, lineOf(*t), prefix + "id", "bad id", s.id, "lower-case letters, digits and '_'");
    for (const auto& other : file.sources)
      if (other.id == s.id) fail(path, lineOf(*t), prefix + "id", "duplicate source id", s.id, "unique ids");
    s.citation = requireString(path, *t, "citation", prefix, lineOf(*t));
    if (t->contains("doi")) s.doi = requireString(path, *t, "doi", prefix, lineOf(*t));
    if (t->contains("locator")) s.locator = requireString(path, *t, "locator", prefix, lineOf(*t));
    file.sources.push_back(std::move(s));
  }

  const toml::array* rows = doc["rows"].as_array();
  if (rows == nullptr || rows->empty()) fail(path, 0, "rows", "missing or empty", {}, "at least one [[rows]] table");
  for (std::size_t i = 0; i < rows->size(); ++i) {
    const toml::table* t = (*rows)[i].as_table();
    const std::string prefix = fmt::format("rows[{}].", i);
    if (t == nullptr) fail(path, lineOf((*rows)[i]), prefix, "not a table", {}, "[[rows]] tables");
    const int line = lineOf(*t);
    checkKeys(path, *t, prefix, {"quantity", "at", "value", "uncertainty", "low", "high", "unit", "source", "note"});
    ReferenceRow r;
    r.line = line;
    r.quantity = requireString(path, *t, "quantity", prefix, line);
    if (!std::regex_match(r.quantity, std::regex("[A-Za-z0-9_]+"))) fail(path, line, prefix + "quantity", "bad metric name", r.quantity, "letters, digits and '_'");
    r.unit = requireString(path, *t, "unit", prefix, line);
    try {
      r.unit_si = parseUnit(r.unit);
    } catch (const UnitError& e) {
      fail(path, lineOf(*t->get("unit")), prefix + "unit", e.what(), r.unit, "a known unit");
    }
    r.source = requireString(path, *t, "source", prefix, line);
    bool known = false;
    for (const auto& s : file.sources) known = known || s.id == r.source;
    if (!known) fail(path, lineOf(*t->get("source")), prefix + "source", "unknown source id", r.source, "an id from [[sources]]");
    if (t->contains("note")) r.note = requireString(path, *t, "note", prefix, line);
    r.value = optionalNumber(path, *t, "value", prefix);
    r.low = optionalNumber(path, *t, "low", prefix);
    r.high = optionalNumber(path, *t, "high", prefix);
    r.uncertainty = optionalNumber(path, *t, "uncertainty", prefix);
    const bool interval = r.low.has_value() || r.high.has_value();
    if (r.value.has_value() == interval)
      fail(path, line, prefix + "value", "a row needs exactly one of 'value' or 'low' and 'high'");
    if (interval && !(r.low && r.high)) fail(path, line, prefix + (r.low ? "high" : "low"), "an interval needs both 'low' and 'high'");
    if (interval && *r.low > *r.high) fail(path, line, prefix + "low", "interval is reversed", fmt::format("[{}, {}]", *r.low, *r.high), "low <= high");
    if (r.uncertainty && (interval || *r.uncertainty < 0)) fail(path, line, prefix + "uncertainty", "uncertainty needs a point value and must be >= 0");
    if (const toml::node* at = t->get("at")) {
      const toml::table* at_t = at->as_table();
      if (at_t == nullptr) fail(path, lineOf(*at), prefix + "at", "wrong type", {}, "an inline table of conditions");
      for (auto&& [k, v] : *at_t) {
        if (v.is_number())
          r.at[std::string(k.str())] = *v.value<double>();
        else if (v.is_string())
          r.at[std::string(k.str())] = std::string(*v.value<std::string>());
        else
          fail(path, lineOf(v), prefix + "at." + std::string(k.str()), "wrong type", {}, "a number or a string");
      }
    }
    file.rows.push_back(std::move(r));
  }
  return file;
}

}  // namespace

const ReferenceFile& loadReferenceFile(const std::filesystem::path& path) {
  static std::mutex mutex;
  static std::map<std::string, std::unique_ptr<ReferenceFile>> cache;
  std::error_code ec;
  const std::filesystem::path canonical = std::filesystem::weakly_canonical(path, ec);
  const std::string key = ec ? path.string() : canonical.string();
  std::lock_guard lock(mutex);
  auto it = cache.find(key);
  if (it != cache.end()) return *it->second;
  if (!isRegularFile(path)) fail(path, 0, {}, "reference file not found", path.string(), "an existing file under reference-data/");
  auto file = std::make_unique<ReferenceFile>(parseReferenceFile(path));
  return *cache.emplace(key, std::move(file)).first->second;
}

}  // namespace mmval
