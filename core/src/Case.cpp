#include "mmval/core/Case.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <optional>
#include <fstream>
#include <sstream>

#include <fmt/format.h>
#include <toml++/toml.h>

#include "TomlUtil.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/DataPaths.hpp"
#include "mmval/core/JsonNumbers.hpp"
#include "mmval/core/Strings.hpp"
#include "mmval/core/Utf8.hpp"

namespace mmval {

using detail::lineOf;
using detail::tomlTypeName;
using detail::tomlValueText;

namespace {

/// Case files are small (the largest bundled one is ~15 kB); this bounds what
/// a wrong path (a video, /dev/zero) can make the reader hold.
constexpr std::uintmax_t kMaxCaseFileBytes = 4u << 20;

/// A name for display: control characters escaped, cut at 60 characters.
std::string printableName(const std::string& name) {
  std::string out = "\"";
  for (std::size_t i = 0; i < name.size() && i < 60; ++i) {
    const auto ch = static_cast<unsigned char>(name[i]);
    out += ch < 0x20 || ch == 0x7f ? fmt::format("\\x{:02x}", ch) : std::string(1, name[i]);
  }
  if (name.size() > 60) out += fmt::format("...\" ({} bytes)", name.size());
  else out += "\"";
  return out;
}

/// True when `file` (a reference pointer resolved against its case file) lies
/// in the case file's folder tree, in a reference-data/ folder beside it, or in
/// mmval's own reference-data/ (dataDirectory()): pointers never read arbitrary files.
bool insideReferenceFolders(const std::filesystem::path& file, const std::filesystem::path& case_file) {
  namespace fs = std::filesystem;
  std::error_code ec;
  const fs::path target = fs::weakly_canonical(fs::absolute(file), ec);
  if (ec) return false;
  const fs::path case_dir = fs::absolute(case_file).parent_path();
  std::vector<fs::path> roots = {case_dir, case_dir.parent_path() / "reference-data"};
  if (const fs::path data = referenceDataDirectory(); !data.empty()) roots.push_back(data);  // DataPaths.hpp
  for (const auto& r : roots) {
    const fs::path root = fs::weakly_canonical(r, ec);
    if (ec) continue;
    const auto [end, it] = std::mismatch(root.begin(), root.end(), target.begin(), target.end());
    if (end == root.end()) return true;
  }
  return false;
}

/// Reads a case file; every error names the file, the line and the key.
class CaseReader {
 public:
  /// `lines` false: the values come from the command line, so errors carry no line numbers.
  CaseReader(std::filesystem::path file, const CaseKindRegistry& registry, bool lines = true)
      : m_file(std::move(file)), m_registry(registry), m_lines(lines) {}

  [[noreturn]] void fail(int line, const std::string& key, const std::string& problem, const std::string& got = {},
                         const std::string& expected = {}) const {
    throw InputError({m_file.string(), m_lines ? line : 0, 0, key}, problem, got, expected);
  }

  std::string expectedText(const KeyDecl& d) const {
    switch (d.type) {
      case ValueType::quantity:
        return fmt::format("a {} such as \"{}\"", dimensionName(d.dim),
                           d.def_text.empty() ? "1 " + d.unit : d.def_text);
      case ValueType::quantity_list:
        return fmt::format("a list of {} values, e.g. [\"1 {}\", \"2 {}\"]", dimensionName(d.dim), d.unit, d.unit);
      case ValueType::choice: return "one of " + join(d.choices, ", ");
      case ValueType::real: return "a number";
      case ValueType::integer: return "an integer";
      case ValueType::boolean: return "true or false";
      case ValueType::string: return "a string";
      case ValueType::path: return "a file path (string)";
      case ValueType::real_list: return "a list of numbers";
      case ValueType::integer_list: return "a list of integers";
      case ValueType::string_list: return "a list of strings";
    }
    return {};
  }

  double toQuantity(const KeyDecl& d, const toml::node& n, const std::string& key) const {
    if (n.is_number()) return *n.value<double>();  // bare numbers are SI
    if (!n.is_string()) fail(lineOf(n), key, "wrong type", tomlTypeName(n), expectedText(d));
    const std::string text = *n.value<std::string>();
    Quantity q;
    try {
      q = parseQuantity(text);
    } catch (const UnitError& e) {
      fail(lineOf(n), key, e.what(), "\"" + text + "\"", expectedText(d));
    }
    if (!(q.dim == d.dim))
      fail(lineOf(n), key, "wrong dimension", fmt::format("\"{}\" ({})", text, dimensionName(q.dim)), expectedText(d));
    return q.si;
  }

  void checkRange(const KeyDecl& d, double v, int line, const std::string& key, const std::string& got) const {
    auto show = [&](double b) {
      return d.type == ValueType::quantity || d.type == ValueType::quantity_list
                 ? fmt::format("{:g} {}", fromSi(b, d.unit), d.unit)
                 : fmt::format("{:g}", b);
    };
    if (!std::isfinite(v)) fail(line, key, "not a finite value", got, "a finite value");
    if (d.min && (v < *d.min || (d.min_exclusive && v == *d.min)))
      fail(line, key, "value out of range", got, (d.min_exclusive ? "> " : ">= ") + show(*d.min));
    if (d.max && (v > *d.max || (d.max_exclusive && v == *d.max)))
      fail(line, key, "value out of range", got, (d.max_exclusive ? "< " : "<= ") + show(*d.max));
  }

  Value convert(const KeyDecl& d, const toml::node& n, const std::string& key) const {
    const int line = lineOf(n);
    const std::string got = tomlValueText(n);
    switch (d.type) {
      case ValueType::quantity: {
        const double v = toQuantity(d, n, key);
        checkRange(d, v, line, key, got);
        return v;
      }
      case ValueType::real: {
        if (!n.is_number()) fail(line, key, "wrong type", got, expectedText(d));
        const double v = *n.value<double>();
        checkRange(d, v, line, key, got);
        return v;
      }
      case ValueType::integer: {
        if (!n.is_integer()) fail(line, key, "wrong type", got, expectedText(d));
        const auto v = *n.value<std::int64_t>();
        checkRange(d, static_cast<double>(v), line, key, got);
        return v;
      }
      case ValueType::boolean:
        if (!n.is_boolean()) fail(line, key, "wrong type", got, expectedText(d));
        return *n.value<bool>();
      case ValueType::string:
      case ValueType::path:
        if (!n.is_string()) fail(line, key, "wrong type", got, expectedText(d));
        return std::string(*n.value<std::string>());
      case ValueType::choice: {
        if (!n.is_string()) fail(line, key, "wrong type", got, expectedText(d));
        const std::string s = *n.value<std::string>();
        for (const auto& c : d.choices)
          if (c == s) return s;
        const std::string near = nearest(s, d.choices);
        fail(line, key, "not an allowed value" + (near.empty() ? std::string() : "; did you mean '" + near + "'?"), got,
             expectedText(d));
      }
      case ValueType::real_list:
      case ValueType::quantity_list:
      case ValueType::integer_list:
      case ValueType::string_list: {
        const toml::array* a = n.as_array();
        if (a == nullptr) fail(line, key, "wrong type", got, expectedText(d));
        std::vector<double> reals;
        std::vector<std::int64_t> ints;
        std::vector<std::string> strings;
        for (std::size_t i = 0; i < a->size(); ++i) {
          const toml::node& item = (*a)[i];
          const std::string item_key = fmt::format("{}[{}]", key, i);
          const std::string item_got = tomlValueText(item);
          if (d.type == ValueType::quantity_list) {
            reals.push_back(toQuantity(d, item, item_key));
            checkRange(d, reals.back(), lineOf(item), item_key, item_got);
          } else if (d.type == ValueType::real_list) {
            if (!item.is_number()) fail(lineOf(item), item_key, "wrong type", item_got, "a number");
            reals.push_back(*item.value<double>());
            checkRange(d, reals.back(), lineOf(item), item_key, item_got);
          } else if (d.type == ValueType::integer_list) {
            if (!item.is_integer()) fail(lineOf(item), item_key, "wrong type", item_got, "an integer");
            ints.push_back(*item.value<std::int64_t>());
            checkRange(d, static_cast<double>(ints.back()), lineOf(item), item_key, item_got);
          } else {
            if (!item.is_string()) fail(lineOf(item), item_key, "wrong type", item_got, "a string");
            strings.push_back(*item.value<std::string>());
          }
        }
        if (d.type == ValueType::integer_list) return ints;
        if (d.type == ValueType::string_list) return strings;
        return reals;
      }
    }
    return {};
  }

  /// All declared key paths plus the tables that hold them, for suggestions.
  std::vector<std::string> candidates(const Schema& schema) const {
    std::vector<std::string> out;
    for (const auto& k : schema.keys()) {
      out.push_back(k.key);
      for (std::size_t p = k.key.find('.'); p != std::string::npos; p = k.key.find('.', p + 1))
        out.push_back(k.key.substr(0, p));
    }
    out.push_back("acceptance");
    return out;
  }

  void unknownKey(const Schema& schema, const std::string& path, int line) const {
    if (const auto* r = schema.findRenamed(path))
      fail(line, path, "renamed to '" + r->first + "' for kind '" + schema.kind() + "': " + r->second, {}, "'" + r->first + "'");
    const auto all = candidates(schema);
    std::string near = nearest(path, all);
    if (near.empty()) {
      // Try the last component against keys of the same table ("flud.viscosity" -> "fluid.viscosity").
      const std::string last = path.substr(path.rfind('.') + 1);
      std::vector<std::string> lasts;
      for (const auto& c : all) lasts.push_back(c.substr(c.rfind('.') + 1));
      const std::string near_last = nearest(last, lasts);
      for (std::size_t i = 0; i < all.size() && near.empty(); ++i)
        if (!near_last.empty() && lasts[i] == near_last) near = all[i];
    }
    fail(line, path, "unknown key for kind '" + schema.kind() + "'" +
                         (near.empty() ? std::string() : "; did you mean '" + near + "'?"),
         {}, near.empty() ? "a key listed by `mmval case-doc " + schema.kind() + "`" : std::string());
  }

  void walk(const Schema& schema, const toml::table& t, const std::string& prefix,
            std::map<std::string, const toml::node*>& found) const {
    for (auto&& [k, v] : t) {
      const std::string path = prefix.empty() ? std::string(k.str()) : prefix + "." + std::string(k.str());
      const int line = static_cast<int>(k.source().begin.line) > 0 ? static_cast<int>(k.source().begin.line) : lineOf(v);
      if (prefix.empty() && path == "acceptance") continue;
      if (const KeyDecl* d = schema.find(path)) {
        if (v.is_table()) fail(line, path, "wrong type", "a table", expectedText(*d));
        found[path] = &v;
      } else if (schema.isTable(path)) {
        if (!v.is_table()) fail(line, path, "wrong type", tomlTypeName(v), "a table [" + path + "]");
        walk(schema, *v.as_table(), path, found);
      } else {
        unknownKey(schema, path, line);
      }
    }
  }

  ReferenceValue readReference(const toml::node& n, const std::string& key, const std::string& unit_override) const {
    ReferenceValue ref;
    const int line = lineOf(n);
    if (n.is_number()) {
      ref.value = *n.value<double>();
      ref.unit = unit_override.empty() ? "1" : unit_override;
      try {
        const Unit u = parseUnit(ref.unit);
        ref.dim = u.dim;
        ref.value *= u.to_si;
      } catch (const UnitError& e) {
        fail(line, key, e.what(), ref.unit, "a known unit");
      }
      ref.source = ref.citation = "value given in the case file";
    } else if (n.is_string()) {
      const std::string text = *n.value<std::string>();
      try {
        const Quantity q = parseQuantity(text);
        ref.value = q.si;
        ref.dim = q.dim;
        const auto space = text.find_first_of(" \t");
        ref.unit = space == std::string::npos ? "1" : text.substr(text.find_first_not_of(" \t", space));
      } catch (const UnitError& e) {
        fail(line, key, e.what(), "\"" + text + "\"", "a number or a quantity such as \"2.5 D\"");
      }
      ref.source = ref.citation = "value given in the case file";
    } else if (const toml::table* t = n.as_table()) {
      for (auto&& [k, v] : *t) {
        const std::string sub(k.str());
        if (sub != "file" && sub != "quantity" && sub != "at") {
          const std::string near = nearest(sub, {"file", "quantity", "at"});
          fail(lineOf(v), key + "." + sub, "unknown key" + (near.empty() ? std::string() : "; did you mean '" + near + "'?"), {}, "file, quantity, at");
        }
      }
      const toml::node* file = t->get("file");
      const toml::node* quantity = t->get("quantity");
      if (file == nullptr || !file->is_string()) fail(line, key + ".file", "missing or not a string", {}, "a path to a reference-data file, relative to the case file");
      if (quantity == nullptr || !quantity->is_string()) fail(line, key + ".quantity", "missing or not a string", {}, "a quantity name in that file");
      AtMap at;
      if (const toml::node* at_node = t->get("at")) {
        const toml::table* at_t = at_node->as_table();
        if (at_t == nullptr) fail(lineOf(*at_node), key + ".at", "wrong type", tomlTypeName(*at_node), "an inline table of conditions");
        for (auto&& [ak, av] : *at_t) {
          if (av.is_number()) at[std::string(ak.str())] = *av.value<double>();
          else if (av.is_string()) at[std::string(ak.str())] = std::string(*av.value<std::string>());
          else fail(lineOf(av), key + ".at." + std::string(ak.str()), "wrong type", tomlTypeName(av), "a number or a string");
        }
      }
      const std::string given = *file->value<std::string>();
      std::filesystem::path ref_path = (m_file.parent_path() / given).lexically_normal();
      // A case kept away from mmval's data (a user's folder, `mmval init`)
      // names "reference-data/<file>": the one of mmval's data folder.
      if (const auto at_data = given.rfind("reference-data/");
          !pathExists(ref_path) && at_data != std::string::npos && (at_data == 0 || given[at_data - 1] == '/'))
        if (const auto data = referenceDataDirectory(); !data.empty() && pathExists(data / given.substr(at_data + 15)))
          ref_path = (data / given.substr(at_data + 15)).lexically_normal();
      if (!insideReferenceFolders(ref_path, m_file))
        fail(lineOf(*file), key + ".file", "a reference pointer must stay inside reference-data/ or the case file's folder", "\"" + given + "\"",
             "a path such as \"../reference-data/<name>.toml\"");
      try {
        ref = lookupReference(ref_path, *quantity->value<std::string>(), at, {m_file.string(), line, 0, key});
      } catch (const InputError& e) {
        if (e.where().file == m_file.string()) throw;
        // A problem inside the reference file: name the pointer that led there too.
        fail(line, key, "the reference it points to cannot be used: " + std::string(e.what()), "\"" + given + "\"",
             "a valid reference-data file (see reference-data/README.md)");
      }
      if (!unit_override.empty()) ref.unit = unit_override;
    } else {
      fail(line, key, "wrong type", tomlTypeName(n), "a number, a quantity string, or { file, quantity, at }");
    }
    return ref;
  }

  /// The declared metric `a.metric` of `schema`; a bare-number reference takes
  /// its dimension (bare numbers are SI), any other must match it.
  void checkMetric(const Schema& schema, Acceptance& a, const toml::node& ref, bool unit_given, const std::string& prefix) const {
    if (schema.metrics().empty()) return;
    const MetricDecl* m = schema.findMetric(a.metric);
    if (m == nullptr || (m->family() && a.metric.size() < m->name.size())) {
      std::vector<std::string> names;
      for (const auto& d : schema.metrics()) names.push_back(d.name);
      const std::string near = nearest(a.metric, names);
      fail(a.where.line, prefix + ".metric",
           "unknown metric for kind '" + schema.kind() + "'" + (near.empty() ? std::string() : "; did you mean '" + near + "'?"),
           "\"" + a.metric + "\"", "one of " + join(names, ", ") + " (`mmval case-doc " + schema.kind() + "`)");
    }
    if (ref.is_number() && !unit_given) {
      a.reference.dim = m->dim;
      a.reference.unit = m->unit;  // the value stays SI; shown in the metric's unit
      return;
    }
    if (!(a.reference.dim == m->dim))
      fail(lineOf(ref), prefix + ".reference", "wrong dimension for metric '" + a.metric + "'",
           a.reference.unit + " (" + dimensionName(a.reference.dim) + ")", "a " + dimensionName(m->dim) + ", e.g. in " + m->unit);
  }

  Acceptance readAcceptance(const Schema& schema, const toml::table& t, std::size_t index) const {
    const std::string prefix = fmt::format("acceptance[{}]", index);
    const int line = lineOf(t);
    static const std::vector<std::string> allowed = {"metric", "reference", "tolerance", "reason", "unit", "label"};
    for (auto&& [k, v] : t) {
      const std::string key(k.str());
      if (std::find(allowed.begin(), allowed.end(), key) == allowed.end()) {
        const std::string near = nearest(key, allowed);
        fail(lineOf(v), prefix + "." + key, "unknown key" + (near.empty() ? std::string() : "; did you mean '" + near + "'?"), {}, join(allowed, ", "));
      }
    }
    auto requireString = [&](const std::string& key) {
      const toml::node* n = t.get(key);
      if (n == nullptr) fail(line, prefix + "." + key, "missing required key", {}, "a string");
      if (!n->is_string()) fail(lineOf(*n), prefix + "." + key, "wrong type", tomlTypeName(*n), "a string");
      return std::string(*n->value<std::string>());
    };
    Acceptance a;
    a.where = {m_file.string(), line, 0, prefix};
    a.metric = requireString("metric");
    if (t.contains("label")) a.label = requireString("label");
    const std::string unit = t.contains("unit") ? requireString("unit") : std::string();
    const toml::node* ref = t.get("reference");
    if (ref == nullptr) fail(line, prefix + ".reference", "missing required key", {}, "a number, a quantity string, or { file, quantity, at }");
    a.reference = readReference(*ref, prefix + ".reference", unit);
    if (!std::isfinite(a.reference.value) || (a.reference.low && !std::isfinite(*a.reference.low)) ||
        (a.reference.high && !std::isfinite(*a.reference.high)))
      fail(lineOf(*ref), prefix + ".reference", "not a finite number", tomlValueText(*ref), "a finite reference value");
    checkMetric(schema, a, *ref, !unit.empty(), prefix);
    if (!unit.empty()) {
      try {
        if (!(parseUnit(unit).dim == a.reference.dim)) fail(line, prefix + ".unit", "wrong dimension for the reference", unit, dimensionName(a.reference.dim));
      } catch (const UnitError& e) {
        fail(line, prefix + ".unit", e.what(), unit, "a known unit");
      }
    }
    a.reason = requireString("reason");
    static const std::string forms = "\"0.5 %\", an absolute quantity, \"interval\", or \"none\" (shown, not judged)";
    const toml::node* tol = t.get("tolerance");
    if (tol == nullptr) fail(line, prefix + ".tolerance", "missing required key", {}, forms);
    a.tolerance.text = tomlValueText(*tol);
    if (tol->is_string()) {
      const std::string text = *tol->value<std::string>();
      a.tolerance.text = text;
      if (text == "none") {
        a.tolerance.kind = Tolerance::Kind::none;
      } else if (text == "interval") {
        if (!a.reference.isInterval()) fail(lineOf(*tol), prefix + ".tolerance", "\"interval\" needs a reference given as an interval (low, high)", text, "a relative or absolute tolerance");
        a.tolerance.kind = Tolerance::Kind::interval;
      } else if (!text.empty() && text.back() == '%') {
        try {
          a.tolerance.kind = Tolerance::Kind::relative;
          a.tolerance.value = parseQuantity(text).si;
        } catch (const UnitError& e) {
          fail(lineOf(*tol), prefix + ".tolerance", e.what(), "\"" + text + "\"", "a percentage such as \"0.5 %\"");
        }
      } else {
        Quantity q;
        try {
          q = parseQuantity(text);
        } catch (const UnitError& e) {
          fail(lineOf(*tol), prefix + ".tolerance", e.what(), "\"" + text + "\"", forms);
        }
        if (!(q.dim == a.reference.dim))
          fail(lineOf(*tol), prefix + ".tolerance", "wrong dimension", "\"" + text + "\" (" + dimensionName(q.dim) + ")", "the reference's dimension, " + dimensionName(a.reference.dim));
        a.tolerance.kind = Tolerance::Kind::absolute;
        a.tolerance.value = q.si;
      }
    } else if (tol->is_number()) {
      if (!std::isfinite(*tol->value<double>()))
        fail(lineOf(*tol), prefix + ".tolerance", "not a finite number", a.tolerance.text, forms);
      a.tolerance.kind = Tolerance::Kind::absolute;
      // A bare tolerance is in the reference's unit as written; a bare reference is SI.
      const bool bare_reference = ref->is_number() && unit.empty();
      a.tolerance.value = *tol->value<double>() * (bare_reference ? 1.0 : parseUnit(a.reference.unit).to_si);
    } else {
      fail(lineOf(*tol), prefix + ".tolerance", "wrong type", tomlTypeName(*tol), forms);
    }
    const bool bounds = a.tolerance.kind == Tolerance::Kind::interval || a.tolerance.kind == Tolerance::Kind::none;
    if (!bounds && a.tolerance.value < 0)
      fail(lineOf(*tol), prefix + ".tolerance", "negative tolerance", a.tolerance.text, "a tolerance >= 0");
    if (!bounds && a.reference.isInterval()) {
      // A relative/absolute tolerance on an interval reference applies to its midpoint.
      a.reference.low.reset();
      a.reference.high.reset();
    }
    return a;
  }

  const CaseKindRegistry& registry() const { return m_registry; }
  const std::filesystem::path& file() const { return m_file; }

 private:
  std::filesystem::path m_file;
  const CaseKindRegistry& m_registry;
  bool m_lines = true;
};

/// Where an override's errors point: the case file and the --set that gave the value.
std::string overrideLabel(const std::filesystem::path& file, const CaseOverride& o) {
  return file.string() + " (--set " + o.text() + ")";
}

/// Puts `o` into the parsed case file, creating tables on the way, as if the
/// file had said `key = value` in its table.
void applyOverride(toml::table& doc, const CaseOverride& o, const CaseReader& cmd) {
  checkTomlText(o.value, cmd.file().string());
  std::optional<toml::table> parsed;
  try {
    parsed = toml::parse("v = " + o.value, cmd.file().string());
  } catch (const toml::parse_error&) {
    parsed.reset();  // not a TOML value: a bare string such as 5 um or dark
  }
  std::vector<std::string> parts;
  for (std::size_t start = 0;;) {
    const std::size_t dot = o.key.find('.', start);
    parts.push_back(o.key.substr(start, dot - start));
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  toml::table* t = &doc;
  std::string prefix;
  for (std::size_t i = 0; i + 1 < parts.size(); ++i) {
    prefix += (i ? "." : "") + parts[i];
    toml::node* child = t->get(parts[i]);
    if (child == nullptr) {
      t->insert(parts[i], toml::table{});
      child = t->get(parts[i]);
    }
    if (!child->is_table()) cmd.fail(0, o.key, "'" + prefix + "' is a value in the case file, not a table", tomlTypeName(*child), "a key of a table");
    t = child->as_table();
  }
  if (parsed && parsed->size() == 1 && parsed->contains("v"))
    t->insert_or_assign(parts.back(), *parsed->get("v"));
  else
    t->insert_or_assign(parts.back(), o.value);
}

}  // namespace

CaseOverride CaseOverride::parse(std::string_view text) {
  const std::size_t eq = text.find('=');
  const auto bad = [&](const std::string& problem) {
    throw InputError({"(command line)", 0, 0, "--set"}, problem, "\"" + std::string(text) + "\"",
                     "KEY=VALUE with a dotted case key, e.g. --set numerics.cells=64 or --set fluid.viscosity=\"2e-3 Pa s\"");
  };
  if (eq == std::string_view::npos) bad("no '=' between key and value");
  CaseOverride o{std::string(text.substr(0, eq)), std::string(text.substr(eq + 1))};
  while (!o.key.empty() && o.key.back() == ' ') o.key.pop_back();
  while (!o.value.empty() && o.value.front() == ' ') o.value.erase(0, 1);
  bool part_empty = true;
  for (char ch : o.key) {
    if (ch == '.') {
      if (part_empty) bad("empty part in the key");
      part_empty = true;
    } else if (std::isalnum(static_cast<unsigned char>(ch)) || ch == '_' || ch == '-') {
      part_empty = false;
    } else {
      bad("a key is letters, digits, '_' and '-' in parts joined by '.'");
    }
  }
  if (part_empty) bad(o.key.empty() ? "no key before '='" : "empty part in the key");
  if (o.key == "acceptance" || o.key.rfind("acceptance.", 0) == 0) bad("[[acceptance]] entries cannot be set from the command line");
  return o;
}

const char* const kCaseNameRule = "1 to 100 characters from A-Z a-z 0-9 - _ . starting with a letter or digit (it names the run's folder)";

std::string caseNameProblem(const std::string& name) {
  if (name.empty()) return "empty case name";
  if (name.size() > 100) return "case name too long";
  const auto ok = [](char ch) { return std::isalnum(static_cast<unsigned char>(ch)) || ch == '-' || ch == '_' || ch == '.'; };
  if (!std::isalnum(static_cast<unsigned char>(name.front()))) return "case name must start with a letter or digit";
  for (char ch : name)
    if (!ok(ch)) return "case name has a character that cannot be part of a folder name";
  return {};
}

std::string readTextFile(const std::filesystem::path& file, std::uintmax_t max_bytes, const std::string& what, const std::string& expected) {
  std::error_code ec;
  const auto status = std::filesystem::status(file, ec);
  if (ec || !std::filesystem::exists(status)) throw InputError({file.string(), 0, 0, {}}, what + " not found", {}, expected);
  if (!std::filesystem::is_regular_file(status))
    throw InputError({file.string(), 0, 0, {}}, what + " is not a regular file", {}, expected);
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  if (!ec && size > max_bytes)
    throw InputError({file.string(), 0, 0, {}}, fmt::format("{} too large ({} bytes)", what, size), {},
                     fmt::format("{} of at most {} bytes", expected, max_bytes));
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError({file.string(), 0, 0, {}}, "cannot open " + what, {}, expected);
  std::string text(static_cast<std::size_t>(std::min(size, max_bytes)), '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<std::size_t>(in.gcount()));
  if (in.peek() != std::char_traits<char>::eof())
    throw InputError({file.string(), 0, 0, {}}, what + " grew while being read or is larger than it says", {},
                     fmt::format("{} of at most {} bytes", expected, max_bytes));
  return text;
}

Case Case::load(const std::filesystem::path& file, const CaseKindRegistry& registry, const std::vector<CaseOverride>& overrides) {
  return parse(readTextFile(file, kMaxCaseFileBytes, "case file", "a TOML case file"), file, registry, overrides);
}

Case Case::parse(std::string_view toml_text, const std::filesystem::path& file, const CaseKindRegistry& registry,
                 const std::vector<CaseOverride>& overrides) {
  CaseReader reader(file, registry);
  checkTomlText(toml_text, file.string());  // toml++ 3.3.0: malformed UTF-8 and non-ASCII it mishandles (see Utf8.hpp)
  toml::table doc;
  try {
    doc = toml::parse(toml_text, file.string());
  } catch (const toml::parse_error& e) {
    reader.fail(static_cast<int>(e.source().begin.line), {}, "TOML syntax error: " + std::string(e.description()));
  }
  for (const auto& o : overrides) applyOverride(doc, o, CaseReader(overrideLabel(file, o), registry, false));
  // The kind decides the schema, so read it first.
  const toml::node* kind_node = doc.at_path("case.kind").node();
  const auto names = registry.names();
  if (kind_node == nullptr)
    reader.fail(doc.contains("case") ? lineOf(*doc.get("case")) : 1, "case.kind", "missing required key", {},
                "one of " + join(names, ", "));
  if (!kind_node->is_string()) reader.fail(lineOf(*kind_node), "case.kind", "wrong type", tomlTypeName(*kind_node), "a string");
  const std::string kind = *kind_node->value<std::string>();
  if (registry.find(kind) == nullptr) {
    const std::string near = nearest(kind, names);
    reader.fail(lineOf(*kind_node), "case.kind",
                "unknown case kind" + (near.empty() ? std::string() : "; did you mean '" + near + "'?"), "\"" + kind + "\"",
                "one of " + join(names, ", "));
  }
  const Schema& schema = registry.schema(kind);
  // Each override is checked on its own first, so that its errors name the --set.
  for (const auto& o : overrides) {
    const CaseReader cmd(overrideLabel(file, o), registry, false);
    if (const KeyDecl* d = schema.find(o.key))
      cmd.convert(*d, *doc.at_path(o.key).node(), o.key);
    else if (schema.isTable(o.key))
      cmd.fail(0, o.key, "a table, not a key", {}, "a key inside [" + o.key + "] (`mmval case-doc " + kind + "`)");
    else
      cmd.unknownKey(schema, o.key, 0);
  }

  std::map<std::string, const toml::node*> found;
  reader.walk(schema, doc, "", found);

  Case c;
  c.m_file = file;
  c.m_schema = &schema;
  for (const auto& d : schema.keys()) {
    auto it = found.find(d.key);
    if (it != found.end()) {
      c.m_values[d.key] = reader.convert(d, *it->second, d.key);
      c.m_where[d.key] = {file.string(), lineOf(*it->second), 0, d.key};
    } else if (d.required) {
      // Point at the table the key belongs in, when it exists.
      int line = 1;
      const std::string table = d.key.substr(0, d.key.rfind('.'));
      if (const toml::node* t = doc.at_path(table).node()) line = lineOf(*t);
      reader.fail(line, d.key, "missing required key", {}, reader.expectedText(d) + " (" + d.doc + ")");
    } else if (!std::holds_alternative<std::monostate>(d.def)) {
      c.m_values[d.key] = d.def;
      c.m_where[d.key] = {file.string(), 0, 0, d.key};
    }
  }
  for (const auto& o : overrides) c.m_where[o.key] = {overrideLabel(file, o), 0, 0, o.key};
  c.m_overrides = overrides;
  c.m_name = std::get<std::string>(c.m_values.at("case.name"));
  if (const std::string problem = caseNameProblem(c.m_name); !problem.empty())
    reader.fail(c.m_where["case.name"].line, "case.name", problem, printableName(c.m_name), kCaseNameRule);
  c.m_kind = kind;
  c.m_description = std::get<std::string>(c.m_values.at("case.description"));

  if (const toml::node* acc = doc.get("acceptance")) {
    const toml::array* arr = acc->as_array();
    if (arr == nullptr) reader.fail(lineOf(*acc), "acceptance", "wrong type", tomlTypeName(*acc), "[[acceptance]] tables");
    for (std::size_t i = 0; i < arr->size(); ++i) {
      const toml::table* t = (*arr)[i].as_table();
      if (t == nullptr) reader.fail(lineOf((*arr)[i]), fmt::format("acceptance[{}]", i), "not a table", {}, "[[acceptance]] tables");
      c.m_acceptance.push_back(reader.readAcceptance(schema, *t, i));
      for (std::size_t j = 0; j + 1 < c.m_acceptance.size(); ++j)
        if (c.m_acceptance[j].metric == c.m_acceptance.back().metric && c.m_acceptance[j].label == c.m_acceptance.back().label)
          reader.fail(c.m_acceptance.back().where.line, fmt::format("acceptance[{}].metric", i), "metric listed twice with the same label",
                      c.m_acceptance.back().metric, "a distinct 'label' for each reference of the same metric");
    }
  }
  return c;
}

const Value& Case::value(std::string_view key, ValueType expected) const {
  const KeyDecl* d = m_schema->find(key);
  if (d == nullptr) throw std::logic_error("case kind '" + m_kind + "' declares no key '" + std::string(key) + "'");
  const bool compatible = d->type == expected || (expected == ValueType::string && (d->type == ValueType::choice || d->type == ValueType::path)) ||
                          (expected == ValueType::real && d->type == ValueType::quantity) ||
                          (expected == ValueType::real_list && d->type == ValueType::quantity_list);
  if (!compatible)
    throw std::logic_error(fmt::format("key '{}' is a {}, read as a {}", key, typeName(d->type), typeName(expected)));
  auto it = m_values.find(key);
  if (it == m_values.end())
    throw std::logic_error("optional key '" + std::string(key) + "' read without checking Case::has()");
  return it->second;
}

double Case::quantity(std::string_view key) const { return std::get<double>(value(key, ValueType::quantity)); }
double Case::real(std::string_view key) const { return std::get<double>(value(key, ValueType::real)); }
std::int64_t Case::integer(std::string_view key) const { return std::get<std::int64_t>(value(key, ValueType::integer)); }
bool Case::flag(std::string_view key) const { return std::get<bool>(value(key, ValueType::boolean)); }
const std::string& Case::text(std::string_view key) const { return std::get<std::string>(value(key, ValueType::string)); }
std::filesystem::path Case::path(std::string_view key) const {
  const std::filesystem::path p = std::get<std::string>(value(key, ValueType::path));
  return p.is_absolute() ? p : m_file.parent_path() / p;
}
const std::vector<double>& Case::reals(std::string_view key) const {
  return std::get<std::vector<double>>(value(key, ValueType::real_list));
}
const std::vector<std::int64_t>& Case::integers(std::string_view key) const {
  return std::get<std::vector<std::int64_t>>(value(key, ValueType::integer_list));
}
const std::vector<std::string>& Case::strings(std::string_view key) const {
  return std::get<std::vector<std::string>>(value(key, ValueType::string_list));
}
bool Case::has(std::string_view key) const { return m_values.find(key) != m_values.end(); }

InputLocation Case::where(std::string_view key) const {
  auto it = m_where.find(key);
  if (it != m_where.end()) return it->second;
  return {m_file.string(), 0, 0, std::string(key)};
}

const Acceptance* Case::acceptanceFor(std::string_view metric) const {
  for (const auto& a : m_acceptance)
    if (a.metric == metric) return &a;
  return nullptr;
}

void Case::set(std::string_view key, Value v) {
  const KeyDecl* d = m_schema->find(key);
  if (d == nullptr) throw std::logic_error("case kind '" + m_kind + "' declares no key '" + std::string(key) + "'");
  if (const double* x = std::get_if<double>(&v)) {
    if (!std::isfinite(*x)) throw InputError(where(key), "not a finite number", fmt::format("{:g}", *x), "a finite value");
    if ((d->min && *x < *d->min) || (d->max && *x > *d->max))
      throw InputError(where(key), "value out of range", fmt::format("{:g}", *x), "within the declared range");
  }
  m_values[std::string(key)] = std::move(v);
  m_where[std::string(key)] = {"(set by command line)", 0, 0, std::string(key)};
}

namespace {
nlohmann::json referenceJson(const ReferenceValue& r) {
  nlohmann::json j;
  const double f = parseUnit(r.unit).to_si;
  if (r.isInterval())
    j["interval"] = {*r.low / f, *r.high / f};
  else
    j["value"] = r.value / f;
  if (r.uncertainty) j["uncertainty"] = *r.uncertainty / f;
  j["unit"] = r.unit;
  j["source"] = r.source;
  return j;
}
}  // namespace

nlohmann::json Case::resolvedJson() const {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& d : m_schema->keys()) {
    auto it = m_values.find(d.key);
    if (it == m_values.end()) continue;
    nlohmann::json v;
    std::visit(
        [&](const auto& x) {
          using T = std::decay_t<decltype(x)>;
          if constexpr (std::is_same_v<T, std::monostate>) {
            v = nullptr;
          } else if constexpr (std::is_same_v<T, double>) {
            if (d.type == ValueType::quantity)
              v = fmt::format("{:.12g} {}", fromSi(x, d.unit), d.unit);
            else
              v = x;
          } else if constexpr (std::is_same_v<T, std::vector<double>>) {
            v = nlohmann::json::array();
            for (double e : x)
              v.push_back(d.type == ValueType::quantity_list ? nlohmann::json(fmt::format("{:.12g} {}", fromSi(e, d.unit), d.unit))
                                                             : nlohmann::json(e));
          } else {
            v = x;
          }
        },
        it->second);
    j[nlohmann::json::json_pointer("/" + [&] {
      std::string p = d.key;
      for (auto& ch : p)
        if (ch == '.') ch = '/';
      return p;
    }())] = v;
  }
  nlohmann::json acc = nlohmann::json::array();
  for (const auto& a : m_acceptance)
    acc.push_back({{"metric", a.metric}, {"label", a.label}, {"reference", referenceJson(a.reference)}, {"tolerance", a.tolerance.text}, {"reason", a.reason}});
  j["acceptance"] = acc;
  return j;
}

std::string Case::hash() const {
  const std::string text = resolvedJson().dump();
  std::uint64_t h = 1469598103934665603ULL;  // FNV-1a 64
  for (unsigned char ch : text) {
    h ^= ch;
    h *= 1099511628211ULL;
  }
  return fmt::format("{:016x}", h);
}

ReferenceValue lookupReference(const std::filesystem::path& file, std::string_view quantity, const AtMap& at,
                               const InputLocation& where) {
  if (!isRegularFile(file))
    throw InputError(where, "reference file not found", file.string(), "a path relative to the case file, e.g. \"../reference-data/<name>.toml\"");
  const ReferenceFile& ref = loadReferenceFile(file);
  const auto rows = ref.find(std::string(quantity), at);
  if (rows.size() != 1) {
    std::vector<std::string> options;
    for (const auto& r : ref.rows)
      if (r.quantity == quantity) options.push_back(toString(r.at));
    std::vector<std::string> quantities;
    for (const auto& r : ref.rows)
      if (std::find(quantities.begin(), quantities.end(), r.quantity) == quantities.end()) quantities.push_back(r.quantity);
    if (options.empty())
      throw InputError(where, fmt::format("no quantity '{}' in {}", quantity, file.string()), std::string(quantity), "one of " + join(quantities, ", "));
    throw InputError(where, fmt::format("{} rows of '{}' in {} match {}", rows.size(), quantity, file.string(), toString(at)), toString(at),
                     "conditions selecting exactly one of " + join(options, "; "));
  }
  const ReferenceRow& row = *rows.front();
  ReferenceValue v;
  const double f = row.unit_si.to_si;
  v.unit = row.unit;
  v.dim = row.unit_si.dim;
  if (row.value) {
    v.value = *row.value * f;
  } else {
    v.low = *row.low * f;
    v.high = *row.high * f;
    v.value = 0.5 * (*v.low + *v.high);
  }
  if (row.uncertainty) v.uncertainty = *row.uncertainty * f;
  const ReferenceSource& s = ref.source(row.source);
  v.source = s.citation + (s.locator.empty() ? "" : ", " + s.locator) + (s.doi.empty() ? "" : ", doi:" + s.doi);
  v.citation = s.citation;
  v.locator = s.locator;
  v.doi = s.doi;
  v.setup = ref.setup;
  return v;
}

MetricResult evaluateMetric(const Acceptance& a, double value_si) {
  MetricResult m;
  m.name = a.label.empty() ? a.metric : a.metric + " (" + a.label + ")";
  m.metric = a.metric;
  m.label = a.label;
  m.unit = a.reference.unit;
  const double f = parseUnit(m.unit).to_si;
  m.value = value_si / f;
  ReferenceValue shown = a.reference;
  shown.value /= f;
  if (shown.low) shown.low = *shown.low / f;
  if (shown.high) shown.high = *shown.high / f;
  if (shown.uncertainty) shown.uncertainty = *shown.uncertainty / f;
  m.reference = shown;
  m.tolerance = a.tolerance.text;
  m.reason = a.reason;
  const double ref = a.reference.value;
  switch (a.tolerance.kind) {
    case Tolerance::Kind::relative:
      // Signed: negative when the value is below the reference.
      m.error = ref != 0.0 ? (value_si - ref) / std::abs(ref) : value_si;
      m.pass = std::isfinite(value_si) && std::abs(m.error) <= a.tolerance.value * (1 + 1e-12);
      break;
    case Tolerance::Kind::absolute:
      m.error = (value_si - ref) / f;
      m.pass = std::isfinite(value_si) && std::abs(value_si - ref) <= a.tolerance.value * (1 + 1e-12);
      break;
    case Tolerance::Kind::interval:
    case Tolerance::Kind::none: {
      if (a.reference.isInterval()) {
        const double lo = *a.reference.low, hi = *a.reference.high;
        const bool inside = value_si >= lo && value_si <= hi;
        const double bound = value_si < lo ? lo : hi;
        m.error = inside ? 0.0 : (value_si - bound) / std::max(std::abs(bound), 1e-300);
        if (a.tolerance.kind == Tolerance::Kind::interval) m.pass = std::isfinite(value_si) && inside;
      } else {
        m.error = ref != 0.0 ? (value_si - ref) / std::abs(ref) : value_si;  // "none" on a point value
      }
      break;
    }
  }
  return m;
}

nlohmann::json MetricResult::toJson() const {
  nlohmann::json j = {{"name", name}, {"metric", metricName()}, {"label", label}, {"unit", unit}};
  try {
    j["dimension"] = parseUnit(unit).dim.siString();
  } catch (const UnitError&) {
    j["dimension"] = nullptr;  // a runner's free-text unit; the report shows it as written
  }
  j["value"] = finiteOrNull(value);
  if (reference) {
    if (reference->isInterval())
      j["reference"] = {*reference->low, *reference->high};
    else
      j["reference"] = reference->value;
    if (reference->uncertainty) j["reference_uncertainty"] = *reference->uncertainty;
    j["source"] = reference->source;
    j["source_ref"] = {{"citation", reference->citation.empty() ? reference->source : reference->citation},
                       {"locator", reference->locator},
                       {"doi", reference->doi}};
    j["reference_setup"] = reference->setup;
  } else {
    j["reference"] = nullptr;
  }
  j["error"] = reference ? nlohmann::json(error) : nlohmann::json(nullptr);
  j["error_kind"] = tolerance.empty() || tolerance.back() == '%' || tolerance == "interval" || tolerance == "none" ? "relative" : "absolute";
  j["tolerance"] = tolerance.empty() ? nlohmann::json(nullptr) : nlohmann::json(tolerance);
  j["pass"] = pass ? nlohmann::json(*pass) : nlohmann::json(nullptr);
  if (!reason.empty()) j["reason"] = reason;
  return j;
}

}  // namespace mmval
