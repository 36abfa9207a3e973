// A case file: one TOML file describing one scene. Loading validates it
// against the kind's Schema (unknown keys with the nearest valid key, wrong
// dimensions, unknown units, missing keys, out-of-range values, TOML syntax),
// fills in defaults and converts quantities to SI. Every error is an
// InputError naming the file, line and key.
//
//   [case]
//   name = "schaefer-turek-2d1"
//   kind = "cylinder-channel"
//   [fluid]
//   viscosity = "1e-3 Pa s"
//   [[acceptance]]
//   metric = "c_D"
//   reference = { file = "../reference-data/schaefer-turek-2d.toml", quantity = "c_D", at = { case = "2D-1" } }
//   tolerance = "0.5 %"
//   reason = "grid level 3 of the ladder; John & Matthies give 11 digits"
#pragma once
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/core/Schema.hpp"

namespace mmval {

class CaseKindRegistry;

/// How far a metric may be from its reference.
struct Tolerance {
  /// none: the reference is shown next to the value with its error, and not
  /// judged (pass stays empty); the entry's reason says why.
  enum class Kind { relative, absolute, interval, none };
  Kind kind = Kind::relative;
  double value = 0.0;  ///< relative: fraction (0.005 for "0.5 %"); absolute: SI
  std::string text;    ///< as written
};

/// A reference value: a point (with optional uncertainty) or an interval, in SI.
struct ReferenceValue {
  double value = 0.0;                  ///< point value, or interval midpoint
  std::optional<double> low, high;     ///< interval bounds
  std::optional<double> uncertainty;   ///< absolute, SI
  std::string unit;                    ///< display unit ("1", "D", "m/s")
  Dimension dim;
  std::string source;                  ///< citation, locator and doi as one display string
  /// The same source as separate fields (reference-data's [[sources]] entry);
  /// a value given in the case file has only `citation`.
  std::string citation, locator, doi;
  /// The physical setting the value describes, as the reference file declares
  /// it (`setup = "unbounded-cylinder"`); empty when the file declares none.
  std::string setup;
  bool isInterval() const { return low.has_value(); }
};

/// One [[acceptance]] entry of a case.
struct Acceptance {
  std::string metric;
  std::string label;  ///< distinguishes several references of one metric ("Dennis & Chang")
  ReferenceValue reference;
  Tolerance tolerance;
  std::string reason;
  InputLocation where;
};

/// A metric evaluated against its acceptance entry (or reported without one).
struct MetricResult {
  std::string name;         ///< display name: `metric`, or "metric (label)"
  std::string metric;       ///< the declared metric name; empty means `name`
  std::string label;        ///< the acceptance entry's label, may be empty
  double value = 0.0;       ///< in `unit`
  std::string unit;         ///< display unit
  std::optional<ReferenceValue> reference;  ///< display-unit values
  double error = 0.0;       ///< relative error (relative tolerance, interval) or absolute error in `unit`
  std::string tolerance;    ///< as written, empty when informational
  std::optional<bool> pass; ///< empty when informational
  std::string reason;
  /// The declared metric name (`metric`, or `name` when a runner set only that).
  const std::string& metricName() const { return metric.empty() ? name : metric; }
  /// result.json's metric object (docs/outputs.md): "name", "metric", "label",
  /// "unit", "dimension", and for a reference "source" (display string),
  /// "source_ref" {citation, locator, doi} and "reference_setup".
  nlohmann::json toJson() const;
};

/// The rule for case names (they become folder names under a validation's
/// runs/): letters, digits, '-', '_', '.', starting with a letter or digit, at
/// most 100 characters. caseNameProblem() returns what is wrong, or "".
extern const char* const kCaseNameRule;
std::string caseNameProblem(const std::string& name);

/// Reads a regular file of at most `max_bytes` as text; InputError (naming the
/// file, `what` and `expected`) for a missing file, a device or FIFO, or a
/// larger file, so that no path makes a reader run forever.
std::string readTextFile(const std::filesystem::path& file, std::uintmax_t max_bytes, const std::string& what,
                         const std::string& expected);

/// One `--set KEY=VALUE` of the command line: a case key given a value as if
/// the case file said `KEY = VALUE`. VALUE is read as a TOML value (64, 2.5,
/// true, "5 um", [1, 2]); a text that is not one is taken as a string, so
/// `--set fluid.viscosity=2e-3 Pa s` and `--set detect.polarity=dark` need no
/// inner quotes.
struct CaseOverride {
  std::string key;
  std::string value;
  /// Splits "KEY=VALUE" at the first '='; InputError naming --set when there is
  /// no '=' or the key is not a dotted key path.
  static CaseOverride parse(std::string_view text);
  std::string text() const { return key + "=" + value; }
};

/// Compares an SI value with an acceptance entry.
MetricResult evaluateMetric(const Acceptance& acceptance, double value_si);

class Case {
 public:
  /// Loads and validates a case file; throws InputError. `overrides` replace
  /// or add keys before validation, which treats them as written in the file;
  /// their errors name the key and the `--set` that gave it.
  static Case load(const std::filesystem::path& file, const CaseKindRegistry& registry,
                   const std::vector<CaseOverride>& overrides = {});
  /// Same from text; `file` is the name used in messages and for relative paths.
  static Case parse(std::string_view toml_text, const std::filesystem::path& file,
                    const CaseKindRegistry& registry, const std::vector<CaseOverride>& overrides = {});
  /// The overrides the case was loaded with, in command-line order.
  const std::vector<CaseOverride>& overrides() const { return m_overrides; }

  const std::string& name() const { return m_name; }
  const std::string& kind() const { return m_kind; }
  const std::string& description() const { return m_description; }
  const std::filesystem::path& file() const { return m_file; }
  /// The kind's schema: its keys and the metrics its runner reports.
  const Schema& schema() const { return *m_schema; }

  double quantity(std::string_view key) const;  ///< SI
  double real(std::string_view key) const;
  std::int64_t integer(std::string_view key) const;
  bool flag(std::string_view key) const;
  const std::string& text(std::string_view key) const;  ///< string or choice
  std::filesystem::path path(std::string_view key) const;  ///< resolved against the case file folder
  const std::vector<double>& reals(std::string_view key) const;  ///< real_list, quantity_list (SI)
  const std::vector<std::int64_t>& integers(std::string_view key) const;
  const std::vector<std::string>& strings(std::string_view key) const;
  /// False only for optional keys without a value.
  bool has(std::string_view key) const;
  /// Where the key was written (line 0 when it came from a default).
  InputLocation where(std::string_view key) const;

  const std::vector<Acceptance>& acceptance() const { return m_acceptance; }
  const Acceptance* acceptanceFor(std::string_view metric) const;

  /// Every declared key with its value (defaults filled in), quantities in their
  /// display unit, plus the acceptance entries: what result.json records.
  nlohmann::json resolvedJson() const;
  /// FNV-1a 64-bit hash of resolvedJson(), 16 hex digits.
  std::string hash() const;

  /// Programmatic override for ladders and tests: sets a key and re-checks its range.
  void set(std::string_view key, Value value);

 private:
  const Value& value(std::string_view key, ValueType expected) const;
  std::string m_name, m_kind, m_description;
  std::filesystem::path m_file;
  const Schema* m_schema = nullptr;
  std::map<std::string, Value, std::less<>> m_values;
  std::map<std::string, InputLocation, std::less<>> m_where;
  std::vector<Acceptance> m_acceptance;
  std::vector<CaseOverride> m_overrides;
};

/// Resolves a reference pointer { file, quantity, at } against reference-data.
/// `where` names the case file location for errors.
ReferenceValue lookupReference(const std::filesystem::path& file, std::string_view quantity,
                               const AtMap& at, const InputLocation& where);

}  // namespace mmval
