// Case-file schema: every key a case kind accepts is declared once, here in
// code, with its type, unit (hence dimension), default, allowed range or
// choices and a doc string. The same declarations validate files, fill in
// defaults and print the reference (`mmval case-doc`).
//
//   Schema s{"channel", "Pressure-driven flow between plates"};
//   s.quantity("fluid.viscosity", "Pa s", "Dynamic viscosity").def("1e-3 Pa s").positive();
//   s.integer("numerics.cells_y", "Cells across the gap").def(32).min(4);
//   s.choice("numerics.solver", {"stokes", "navier-stokes"}, "Model").def("stokes");
#pragma once
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "mmval/core/Units.hpp"

namespace mmval {

enum class ValueType {
  quantity,       ///< number (SI) or "<number> <unit>" string of a fixed dimension
  real,           ///< plain number
  integer,        ///< integer
  boolean,        ///< true / false
  string,         ///< free text
  choice,         ///< one of a fixed set of strings
  path,           ///< file path, resolved relative to the case file's folder
  real_list,      ///< array of numbers
  integer_list,   ///< array of integers
  string_list,    ///< array of strings
  quantity_list,  ///< array of numbers (SI) or quantity strings, one dimension
};

std::string_view typeName(ValueType type);

/// A stored value: SI double for quantities and reals, int64 for integers, etc.
using Value = std::variant<std::monostate, double, std::int64_t, bool, std::string,
                           std::vector<double>, std::vector<std::int64_t>, std::vector<std::string>>;

struct KeyDecl {
  std::string key;         ///< dotted path: "fluid.viscosity"
  ValueType type = ValueType::real;
  std::string unit;        ///< display unit of a quantity ("Pa s"); defines its dimension
  Dimension dim;           ///< dimension of a quantity
  std::string doc;
  Value def;               ///< default (monostate: none)
  std::string def_text;    ///< default as written ("1e-3 Pa s"), for case-doc
  bool required = true;    ///< false when it has a default or is optional
  std::optional<double> min, max;  ///< bounds in SI (quantities) or plain (reals, integers, list items)
  bool min_exclusive = false, max_exclusive = false;
  std::vector<std::string> choices;
};

/// A metric a kind's runner reports: its name, its display unit (which fixes
/// its dimension) and what it means. Acceptance entries may only name declared
/// metrics, with references and tolerances of the declared dimension. A name
/// ending in '*' declares a family ("speed_w1_*": one metric per region).
struct MetricDecl {
  std::string name;
  std::string unit;  ///< display unit ("1" for dimensionless)
  Dimension dim;
  std::string doc;
  bool family() const { return !name.empty() && name.back() == '*'; }
};

/// Fluent modifier for the declaration just added.
class KeyBuilder {
 public:
  explicit KeyBuilder(KeyDecl& decl) : m_decl(decl) {}
  KeyBuilder& def(std::string_view text);  ///< quantity "5 um", string, choice, path
  KeyBuilder& def(const char* text) { return def(std::string_view(text)); }
  KeyBuilder& def(double value);           ///< real or quantity in SI
  KeyBuilder& def(int value);              ///< integer (or real/quantity)
  KeyBuilder& def(std::int64_t value);
  KeyBuilder& def(bool value);
  KeyBuilder& def(std::vector<double> value);
  KeyBuilder& def(std::vector<std::string> value);
  KeyBuilder& optional();                  ///< may be absent, no default (check Case::has)
  KeyBuilder& min(double v, bool exclusive = false);  ///< SI
  KeyBuilder& max(double v, bool exclusive = false);  ///< SI
  KeyBuilder& positive() { return min(0.0, true); }
  KeyBuilder& nonNegative() { return min(0.0, false); }
  KeyBuilder& fraction() { return min(0.0).max(1.0); }
 private:
  KeyDecl& m_decl;
};

class Schema {
 public:
  Schema() = default;
  Schema(std::string kind, std::string summary) : m_kind(std::move(kind)), m_summary(std::move(summary)) {}

  KeyBuilder quantity(std::string key, std::string unit, std::string doc);
  KeyBuilder quantityList(std::string key, std::string unit, std::string doc);
  KeyBuilder real(std::string key, std::string doc);
  KeyBuilder integer(std::string key, std::string doc);
  KeyBuilder boolean(std::string key, std::string doc);
  KeyBuilder string(std::string key, std::string doc);
  KeyBuilder choice(std::string key, std::vector<std::string> choices, std::string doc);
  KeyBuilder path(std::string key, std::string doc);
  KeyBuilder realList(std::string key, std::string doc);
  KeyBuilder integerList(std::string key, std::string doc);
  KeyBuilder stringList(std::string key, std::string doc);

  /// Declares a metric the kind reports (see MetricDecl).
  void metric(std::string name, std::string unit, std::string doc);
  const MetricDecl* findMetric(std::string_view name) const;
  const std::deque<MetricDecl>& metrics() const { return m_metrics; }

  /// A key the kind no longer takes under this name: a file that sets `old_key` is refused with
  /// a message naming `new_key` and `why` (the meaning changed, so its value is not carried over).
  void renamed(std::string old_key, std::string new_key, std::string why);
  /// The new name and the reason for `old_key`, or nullptr when it was not renamed.
  const std::pair<std::string, std::string>* findRenamed(std::string_view old_key) const;

  const std::string& kind() const { return m_kind; }
  const std::string& summary() const { return m_summary; }
  const std::deque<KeyDecl>& keys() const { return m_keys; }
  const KeyDecl* find(std::string_view key) const;
  /// True when `prefix` names a table that holds declared keys ("fluid").
  bool isTable(std::string_view prefix) const;
  /// Markdown reference of every key (for `mmval case-doc`).
  std::string markdown() const;

 private:
  KeyBuilder add(std::string key, ValueType type, std::string doc, std::string unit = {});
  std::string m_kind, m_summary;
  std::deque<KeyDecl> m_keys;  // deque: KeyBuilder references stay valid
  std::deque<MetricDecl> m_metrics;
  std::map<std::string, std::pair<std::string, std::string>, std::less<>> m_renamed;  // old key -> (new key, why)
};

/// Keys every case has ([case] table), declared into a kind's schema by the registry.
void declareCommonKeys(Schema& schema, const std::vector<std::string>& kinds);

}  // namespace mmval
