#include "mmval/reports/JsonShape.hpp"

#include <cstdlib>
#include <string>
#include <vector>

#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Strings.hpp"

namespace mmval::reports {

namespace {

using nlohmann::json;

/// JSON types a field may have, combined with |.
enum Kind : unsigned { kNull = 1, kBoolean = 2, kNumber = 4, kString = 8, kArray = 16, kObject = 32 };

unsigned kindOf(const json& v) {
  if (v.is_null()) return kNull;
  if (v.is_boolean()) return kBoolean;
  if (v.is_number()) return kNumber;
  if (v.is_string()) return kString;
  if (v.is_array()) return kArray;
  return kObject;
}

std::string describe(unsigned kinds) {
  std::vector<std::string> names;
  if (kinds & kObject) names.emplace_back("an object");
  if (kinds & kArray) names.emplace_back("a list");
  if (kinds & kString) names.emplace_back("a string");
  if (kinds & kNumber) names.emplace_back("a number");
  if (kinds & kBoolean) names.emplace_back("true or false");
  if (kinds & kNull) names.emplace_back("null");
  return join(names, " or ");
}

/// The value as the user wrote it, cut to a line, with its JSON type.
std::string shown(const json& v) {
  constexpr std::size_t kMaxShown = 60;
  std::string text = v.dump();
  if (text.size() > kMaxShown) text = text.substr(0, kMaxShown - 3) + "...";
  return text + " (" + v.type_name() + ")";
}

std::string pathOf(const std::string& at, const std::string& key) { return at.empty() ? key : at + "." + key; }

/// Checks fields of one file and names it in every error.
class Shape {
 public:
  explicit Shape(const std::filesystem::path& file) : m_file(file.string()) {}

  const json& check(const json& v, const std::string& path, unsigned kinds) const {
    if ((kindOf(v) & kinds) == 0) fail(path, "wrong type", shown(v), describe(kinds));
    return v;
  }
  /// `parent.key` must be present with one of `kinds`.
  const json& need(const json& parent, const std::string& at, const std::string& key, unsigned kinds) const {
    const auto it = parent.find(key);
    if (it == parent.end()) fail(pathOf(at, key), "missing field", {}, describe(kinds));
    return check(*it, pathOf(at, key), kinds);
  }
  /// `parent.key` may be absent (nullptr); when present it has one of `kinds`.
  const json* maybe(const json& parent, const std::string& at, const std::string& key, unsigned kinds) const {
    const auto it = parent.find(key);
    return it == parent.end() ? nullptr : &check(*it, pathOf(at, key), kinds);
  }
  /// Every entry of the list `parent.key` (if present) has one of `kinds`.
  void eachMaybe(const json& parent, const std::string& at, const std::string& key, unsigned kinds) const {
    if (const json* list = maybe(parent, at, key, kArray))
      for (std::size_t i = 0; i < list->size(); ++i) check((*list)[i], pathOf(at, key) + "[" + std::to_string(i) + "]", kinds);
  }
  [[noreturn]] void fail(const std::string& path, const std::string& problem, const std::string& got, const std::string& expected) const {
    throw InputError({m_file, 0, 0, path}, problem, got, expected);
  }
  void schema(const json& doc, const std::string& expected) const {
    if (const json* s = maybe(doc, "", "schema", kString); s != nullptr && *s != expected)
      fail("schema", "not the file this command reads", shown(*s), "\"" + expected + "\"");
  }

 private:
  std::string m_file;
};

/// A relative tolerance ("20 %") is read back as a number by the diff.
void checkTolerance(const Shape& s, const json& tolerance, const std::string& path) {
  if (!tolerance.is_string()) return;
  const std::string& t = tolerance.get_ref<const std::string&>();
  if (t.empty() || t.back() != '%') return;
  char* end = nullptr;
  std::strtod(t.c_str(), &end);
  if (end == t.c_str()) s.fail(path, "a relative tolerance that is not a number", shown(tolerance), "a percentage such as \"20 %\"");
}

/// Which fields of a metric the reader uses.
enum class MetricUse { report, diff };

void checkMetric(const Shape& s, const json& m, const std::string& at, MetricUse use) {
  s.check(m, at, kObject);
  s.need(m, at, "name", kString);
  s.need(m, at, "value", kNumber | kNull);
  s.need(m, at, "pass", kBoolean | kNull);
  checkTolerance(s, s.need(m, at, "tolerance", kString | kNull), pathOf(at, "tolerance"));
  s.maybe(m, at, "case", kString);
  if (use == MetricUse::diff) return;
  s.maybe(m, at, "unit", kString);
  s.need(m, at, "error", kNumber | kNull);
  s.maybe(m, at, "error_kind", kString);
  s.maybe(m, at, "source", kString);
  // The typed fields (docs/outputs.md); optional, as result.json files written
  // before them have only "name" and "source".
  s.maybe(m, at, "metric", kString);
  s.maybe(m, at, "label", kString);
  s.maybe(m, at, "dimension", kString | kNull);
  s.maybe(m, at, "reference_setup", kString);
  if (const json* ref = s.maybe(m, at, "source_ref", kObject))
    for (const char* key : {"citation", "locator", "doi"}) s.need(*ref, pathOf(at, "source_ref"), key, kString);
  s.maybe(m, at, "reference_uncertainty", kNumber);
  const json& reference = s.need(m, at, "reference", kNumber | kNull | kArray);
  if (reference.is_array()) {
    if (reference.size() != 2) s.fail(pathOf(at, "reference"), "an interval has two ends", shown(reference), "[low, high]");
    for (std::size_t i = 0; i < 2; ++i) s.check(reference[i], pathOf(at, "reference") + "[" + std::to_string(i) + "]", kNumber);
  }
}

void checkMetrics(const Shape& s, const json& doc, MetricUse use) {
  const json& list = s.need(doc, "", "metrics", kArray);
  for (std::size_t i = 0; i < list.size(); ++i) checkMetric(s, list[i], "metrics[" + std::to_string(i) + "]", use);
}

void checkNumbers(const Shape& s, const json& parent, const std::string& at, const std::vector<const char*>& keys, bool required) {
  for (const char* key : keys) required ? (void)s.need(parent, at, key, kNumber) : (void)s.maybe(parent, at, key, kNumber);
}

void checkRegions(const Shape& s, const json& g) {
  s.maybe(g, "regions", "rule", kString);
  for (const char* side : {"experiment", "simulation"}) {
    const std::string at = std::string("regions.") + side;
    const json& speeds = s.need(g, "regions", side, kObject);
    for (const char* key : {"pore_body_mean_speed_um_per_s", "throat_mean_speed_um_per_s", "pore_body_steps", "throat_steps"})
      s.need(speeds, at, key, kNumber | kNull);
  }
  checkNumbers(s, g, "regions", {"speed_pore_bodies_relative_difference", "speed_throats_relative_difference"}, false);
}

void checkAlignment(const Shape& s, const json& a) {
  s.maybe(a, "alignment", "method", kString);
  if (!a.contains("dx_px")) return;
  checkNumbers(s, a, "alignment", {"dx_px", "dy_px", "rotation_deg", "ecc_correlation", "rms_residual"}, true);
  checkNumbers(s, a, "alignment", {"dx_um", "dy_um", "scale", "overlap_fraction"}, false);
}

}  // namespace

std::vector<std::string> checkResultShape(const json& doc, const std::filesystem::path& file) {
  const Shape s(file);
  s.check(doc, "", kObject);
  s.schema(doc, "mmval-result/1");
  const json& c = s.need(doc, "", "case", kObject);
  for (const char* key : {"name", "kind", "hash"}) s.need(c, "case", key, kString);
  s.maybe(c, "case", "file", kString);
  checkMetrics(s, doc, MetricUse::report);
  s.need(doc, "", "all_pass", kBoolean);
  checkNumbers(s, s.need(doc, "", "cost", kObject), "cost", {"wall_seconds", "peak_memory_bytes"}, true);
  const json& p = s.need(doc, "", "provenance", kObject);
  for (const char* key : {"mmval_version", "git_hash", "compiler", "build_type", "host"}) s.need(p, "provenance", key, kString);
  s.eachMaybe(doc, "", "files", kString);
  // Every declared details field present has its declared type (mmval/core/DetailFields.hpp);
  // other keys are the kinds' informational ones, allowed and returned.
  return checkDetails(s.need(doc, "", "details", kNull | kBoolean | kNumber | kString | kArray | kObject), file.string());
}

void checkCompareShape(const json& doc, const std::filesystem::path& file) {
  const Shape s(file);
  s.check(doc, "", kObject);
  s.schema(doc, "mmval-compare/1");
  checkMetrics(s, doc, MetricUse::report);
  s.need(doc, "", "all_pass", kBoolean);
  if (const json* g = s.maybe(doc, "", "regions", kObject)) checkRegions(s, *g);
  if (const json* a = s.maybe(doc, "", "alignment", kObject)) checkAlignment(s, *a);
}

void checkSweepShape(const json& doc, const std::filesystem::path& file) {
  const Shape s(file);
  s.check(doc, "", kObject);
  s.need(doc, "", "schema", kString);
  s.schema(doc, "mmval-sweep/1");
  s.need(s.need(doc, "", "case", kObject), "case", "name", kString);
  const json& axes = s.need(doc, "", "axes", kArray);
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const std::string at = "axes[" + std::to_string(i) + "]";
    s.need(s.check(axes[i], at, kObject), at, "key", kString);
    s.eachMaybe(axes[i], at, "values", kString);
  }
  const json& groups = s.need(doc, "", "groups", kArray);
  for (std::size_t i = 0; i < groups.size(); ++i) {
    const std::string at = "groups[" + std::to_string(i) + "]";
    s.check(groups[i], at, kObject);
    for (const auto& [key, value] : s.need(groups[i], at, "setting", kObject).items()) s.check(value, at + ".setting." + key, kString);
    for (const auto& [name, stats] : s.need(groups[i], at, "metrics", kObject).items()) {
      s.check(stats, at + ".metrics." + name, kObject);
      s.need(stats, at + ".metrics." + name, "n", kNumber);
      for (const char* key : {"mean", "se"}) s.need(stats, at + ".metrics." + name, key, kNumber | kNull);
    }
  }
  s.eachMaybe(doc, "", "metrics_shown", kString);
  if (const json* d = s.maybe(doc, "", "discretisation", kObject))
    for (const char* axis : {"grid", "step"})
      if (const json* a = s.maybe(*d, "discretisation", axis, kObject | kNull); a != nullptr && a->is_object())
        s.need(*a, std::string("discretisation.") + axis, "key", kString);
  if (const json* u = s.maybe(doc, "", "uncertainty", kObject))
    for (const auto& [name, m] : u->items()) {
      const std::string at = "uncertainty." + name;
      s.check(m, at, kObject);
      s.need(m, at, "unit", kString);
      const json& list = s.need(m, at, "settings", kArray);
      for (std::size_t i = 0; i < list.size(); ++i) {
        const std::string e = at + ".settings[" + std::to_string(i) + "]";
        s.check(list[i], e, kObject);
        for (const char* key : {"value", "seed_se", "combined"}) s.need(list[i], e, key, kNumber | kNull);
        s.need(list[i], e, "n", kNumber);
        for (const char* key : {"setting", "at"}) s.need(list[i], e, key, kObject);
        s.need(list[i], e, "verdict", kString);
        s.need(list[i], e, "converged", kBoolean | kNull);
        for (const char* axis : {"grid", "step"}) {
          const json& p = s.need(list[i], e, axis, kObject | kNull);
          if (p.is_null()) continue;
          const std::string pa = e + "." + axis;
          for (const char* key : {"key", "method", "note"}) s.need(p, pa, key, kString);
          for (const char* key : {"part", "difference", "difference_se", "observed_order"}) s.need(p, pa, key, kNumber | kNull);
          s.need(p, pa, "resolved", kBoolean);
          s.need(p, pa, "levels", kArray);
        }
      }
    }
}

void checkMetricsListShape(const json& doc, const std::filesystem::path& file) {
  const Shape s(file);
  s.check(doc, "", kObject);
  checkMetrics(s, doc, MetricUse::diff);
}

}  // namespace mmval::reports
