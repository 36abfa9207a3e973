#include "StarterCase.hpp"

#include <map>
#include <vector>

#include <fmt/format.h>

#include "mmval/core/Strings.hpp"
#include "mmval/core/Units.hpp"

namespace mmval::app {

namespace {

std::string quoted(const std::string& s) {
  std::string out = "\"";
  for (char ch : s) {
    if (ch == '"' || ch == '\\') out += '\\';
    out += ch;
  }
  return out + "\"";
}

std::string number(double v) { return fmt::format("{:.12g}", v); }

/// A declared value written as TOML, quantities in their display unit.
std::string tomlLiteral(const KeyDecl& d, const Value& v) {
  const bool quantity = d.type == ValueType::quantity || d.type == ValueType::quantity_list;
  const auto one = [&](double x) { return quantity ? quoted(number(fromSi(x, d.unit)) + " " + d.unit) : number(x); };
  if (const auto* x = std::get_if<double>(&v)) return one(*x);
  if (const auto* i = std::get_if<std::int64_t>(&v)) return std::to_string(*i);
  if (const auto* b = std::get_if<bool>(&v)) return *b ? "true" : "false";
  if (const auto* s = std::get_if<std::string>(&v)) return quoted(*s);
  std::vector<std::string> items;
  if (const auto* xs = std::get_if<std::vector<double>>(&v))
    for (double x : *xs) items.push_back(one(x));
  if (const auto* is = std::get_if<std::vector<std::int64_t>>(&v))
    for (auto i : *is) items.push_back(std::to_string(i));
  if (const auto* ss = std::get_if<std::vector<std::string>>(&v))
    for (const auto& s : *ss) items.push_back(quoted(s));
  return "[" + join(items, ", ") + "]";
}

/// "quantity in Pa s, > 0" / "one of a, b" / "integer, >= 4".
std::string typeText(const KeyDecl& d) {
  std::string out;
  switch (d.type) {
    case ValueType::quantity: out = dimensionName(d.dim) + (d.unit == "1" ? std::string() : " in " + d.unit); break;
    case ValueType::quantity_list: out = "list of " + dimensionName(d.dim) + " values in " + d.unit; break;
    case ValueType::choice: out = "one of " + join(d.choices, ", "); break;
    case ValueType::path: out = "file path, relative to this file"; break;
    default: out = std::string(typeName(d.type)); break;
  }
  const bool quantity = d.type == ValueType::quantity || d.type == ValueType::quantity_list;
  const auto bound = [&](double b) { return quantity ? fmt::format("{:g} {}", fromSi(b, d.unit), d.unit) : fmt::format("{:g}", b); };
  if (d.min) out += std::string(d.min_exclusive ? ", > " : ", >= ") + bound(*d.min);
  if (d.max) out += std::string(d.max_exclusive ? ", < " : ", <= ") + bound(*d.max);
  return out;
}

/// Comment lines of at most ~100 characters.
std::string commentBlock(const std::string& raw) {
  std::string out, line;
  std::string text = raw;
  for (char& ch : text)
    if (ch == '\n' || ch == '\r') ch = ' ';
  for (std::size_t start = 0; start < text.size();) {
    std::size_t end = text.find(' ', start);
    if (end == std::string::npos) end = text.size();
    const std::string word = text.substr(start, end - start);
    if (!line.empty() && line.size() + 1 + word.size() > 98) {
      out += "# " + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
    start = end + 1;
  }
  if (!line.empty()) out += "# " + line + "\n";
  return out;
}

std::string keyEntry(const KeyDecl& d, const std::string& kind) {
  const std::string leaf = d.key.substr(d.key.rfind('.') + 1);
  std::string out = commentBlock(d.doc + " (" + typeText(d) + ")");
  if (d.key == "case.kind") return out + leaf + " = " + quoted(kind) + "\n";
  if (!std::holds_alternative<std::monostate>(d.def)) return out + "#" + leaf + " = " + tomlLiteral(d, d.def) + "  # default\n";
  if (d.required) return out + "#" + leaf + " =   # REQUIRED: no default, give a value and uncomment\n";
  return out + "#" + leaf + " =   # optional, no default\n";
}

}  // namespace

std::string starterCase(const Schema& schema) {
  std::string out = fmt::format(
      "# A starter case of kind '{}': {}.\n"
      "# Made by `mmval init {}` from the kind's declarations; `mmval case-doc {}` is the full reference.\n"
      "# Lines marked REQUIRED have no default: uncomment them and give a value. The other keys are\n"
      "# commented out with their default; uncomment one to change it. Quantities take units as\n"
      "# strings (\"5 um\", \"0.024 cm/min\"); bare numbers are SI. Check the file with `mmval case-check FILE`.\n",
      schema.kind(), schema.summary(), schema.kind(), schema.kind());
  // Keys grouped by table, tables in the order of their first key.
  std::vector<std::string> tables;
  std::map<std::string, std::vector<const KeyDecl*>> by_table;
  for (const auto& d : schema.keys()) {
    const auto dot = d.key.rfind('.');
    const std::string table = dot == std::string::npos ? std::string() : d.key.substr(0, dot);
    if (by_table.find(table) == by_table.end()) tables.push_back(table);
    by_table[table].push_back(&d);
  }
  // Keys outside any table must come before the first [table] header.
  if (auto it = by_table.find(""); it != by_table.end()) {
    out += "\n";
    for (const KeyDecl* d : it->second) out += keyEntry(*d, schema.kind());
  }
  for (const auto& table : tables) {
    if (table.empty()) continue;
    out += "\n[" + table + "]\n";
    for (const KeyDecl* d : by_table[table]) out += keyEntry(*d, schema.kind());
  }
  if (!schema.metrics().empty()) {
    out += "\n# Acceptance criteria (any number): a metric this kind reports, its reference (a number, a\n"
           "# quantity, or { file, quantity, at } into reference-data/), a tolerance and the reason for it.\n"
           "# The metrics of this kind:\n";
    for (const auto& m : schema.metrics())
      out += "#   " + m.name + " [" + m.unit + "]: " + m.doc + "\n";
    const MetricDecl& first = schema.metrics().front();
    const std::string name = first.family() ? first.name.substr(0, first.name.size() - 1) + "NAME" : first.name;
    out += "#[[acceptance]]\n#metric = " + quoted(name) + "\n#reference = " + (first.unit == "1" ? std::string("1") : quoted("1 " + first.unit)) +
           "\n#tolerance = \"1 %\"\n#reason = \"why this tolerance\"\n";
  }
  return out;
}

}  // namespace mmval::app
