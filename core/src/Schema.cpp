#include "mmval/core/Schema.hpp"

#include <cmath>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/core/Strings.hpp"
#include "mmval/core/SchemaBlocks.hpp"

namespace mmval {

std::string_view typeName(ValueType type) {
  switch (type) {
    case ValueType::quantity: return "quantity";
    case ValueType::real: return "number";
    case ValueType::integer: return "integer";
    case ValueType::boolean: return "boolean";
    case ValueType::string: return "string";
    case ValueType::choice: return "choice";
    case ValueType::path: return "path";
    case ValueType::real_list: return "list of numbers";
    case ValueType::integer_list: return "list of integers";
    case ValueType::string_list: return "list of strings";
    case ValueType::quantity_list: return "list of quantities";
  }
  return "?";
}

namespace {
// Declarations are programmer input: a bad one is a bug, reported loudly.
[[noreturn]] void declarationBug(const KeyDecl& decl, const std::string& what) {
  throw std::logic_error("schema declaration of '" + decl.key + "': " + what);
}
}  // namespace

KeyBuilder& KeyBuilder::def(std::string_view text) {
  m_decl.def_text = std::string(text);
  m_decl.required = false;
  switch (m_decl.type) {
    case ValueType::quantity: {
      const Quantity q = parseQuantity(text);
      if (!(q.dim == m_decl.dim)) declarationBug(m_decl, "default has the wrong dimension");
      m_decl.def = q.si;
      break;
    }
    case ValueType::string:
    case ValueType::path:
      m_decl.def = std::string(text);
      break;
    case ValueType::choice: {
      bool found = false;
      for (const auto& c : m_decl.choices) found = found || c == text;
      if (!found) declarationBug(m_decl, "default is not one of the choices");
      m_decl.def = std::string(text);
      break;
    }
    default:
      declarationBug(m_decl, "text default for a non-text key");
  }
  return *this;
}

KeyBuilder& KeyBuilder::def(double value) {
  if (m_decl.type != ValueType::real && m_decl.type != ValueType::quantity)
    declarationBug(m_decl, "number default for a non-number key");
  m_decl.def = value;
  m_decl.def_text = m_decl.type == ValueType::quantity
                        ? fmt::format("{:g} {}", fromSi(value, m_decl.unit), m_decl.unit)
                        : fmt::format("{:g}", value);
  m_decl.required = false;
  return *this;
}

KeyBuilder& KeyBuilder::def(int value) {
  if (m_decl.type == ValueType::integer) return def(static_cast<std::int64_t>(value));
  return def(static_cast<double>(value));
}

KeyBuilder& KeyBuilder::def(std::int64_t value) {
  if (m_decl.type != ValueType::integer) declarationBug(m_decl, "integer default for a non-integer key");
  m_decl.def = value;
  m_decl.def_text = std::to_string(value);
  m_decl.required = false;
  return *this;
}

KeyBuilder& KeyBuilder::def(bool value) {
  if (m_decl.type != ValueType::boolean) declarationBug(m_decl, "boolean default for a non-boolean key");
  m_decl.def = value;
  m_decl.def_text = value ? "true" : "false";
  m_decl.required = false;
  return *this;
}

KeyBuilder& KeyBuilder::def(std::vector<double> value) {
  if (m_decl.type != ValueType::real_list && m_decl.type != ValueType::quantity_list)
    declarationBug(m_decl, "list default for a non-list key");
  std::vector<std::string> parts;
  for (double v : value)
    parts.push_back(m_decl.type == ValueType::quantity_list ? fmt::format("{:g}", fromSi(v, m_decl.unit))
                                                            : fmt::format("{:g}", v));
  m_decl.def_text = "[" + join(parts, ", ") + "]" +
                    (m_decl.type == ValueType::quantity_list ? " " + m_decl.unit : std::string());
  m_decl.def = std::move(value);
  m_decl.required = false;
  return *this;
}

KeyBuilder& KeyBuilder::def(std::vector<std::string> value) {
  if (m_decl.type != ValueType::string_list) declarationBug(m_decl, "string-list default for another key type");
  m_decl.def_text = "[" + join(value, ", ") + "]";
  m_decl.def = std::move(value);
  m_decl.required = false;
  return *this;
}

KeyBuilder& KeyBuilder::optional() {
  m_decl.required = false;
  return *this;
}

KeyBuilder& KeyBuilder::min(double v, bool exclusive) {
  m_decl.min = v;
  m_decl.min_exclusive = exclusive;
  return *this;
}

KeyBuilder& KeyBuilder::max(double v, bool exclusive) {
  m_decl.max = v;
  m_decl.max_exclusive = exclusive;
  return *this;
}

KeyBuilder Schema::add(std::string key, ValueType type, std::string doc, std::string unit) {
  if (find(key) != nullptr) throw std::logic_error("schema '" + m_kind + "': key '" + key + "' declared twice");
  KeyDecl decl;
  decl.key = std::move(key);
  decl.type = type;
  decl.doc = std::move(doc);
  if (!unit.empty()) {
    decl.dim = parseUnit(unit).dim;
    decl.unit = std::move(unit);
  }
  m_keys.push_back(std::move(decl));
  return KeyBuilder(m_keys.back());
}

KeyBuilder Schema::quantity(std::string key, std::string unit, std::string doc) {
  return add(std::move(key), ValueType::quantity, std::move(doc), std::move(unit));
}
KeyBuilder Schema::quantityList(std::string key, std::string unit, std::string doc) {
  return add(std::move(key), ValueType::quantity_list, std::move(doc), std::move(unit));
}
KeyBuilder Schema::real(std::string key, std::string doc) { return add(std::move(key), ValueType::real, std::move(doc)); }
KeyBuilder Schema::integer(std::string key, std::string doc) {
  return add(std::move(key), ValueType::integer, std::move(doc));
}
KeyBuilder Schema::boolean(std::string key, std::string doc) {
  return add(std::move(key), ValueType::boolean, std::move(doc));
}
KeyBuilder Schema::string(std::string key, std::string doc) {
  return add(std::move(key), ValueType::string, std::move(doc));
}
KeyBuilder Schema::choice(std::string key, std::vector<std::string> choices, std::string doc) {
  KeyBuilder b = add(std::move(key), ValueType::choice, std::move(doc));
  m_keys.back().choices = std::move(choices);
  return b;
}
KeyBuilder Schema::path(std::string key, std::string doc) { return add(std::move(key), ValueType::path, std::move(doc)); }
KeyBuilder Schema::realList(std::string key, std::string doc) {
  return add(std::move(key), ValueType::real_list, std::move(doc));
}
KeyBuilder Schema::integerList(std::string key, std::string doc) {
  return add(std::move(key), ValueType::integer_list, std::move(doc));
}
KeyBuilder Schema::stringList(std::string key, std::string doc) {
  return add(std::move(key), ValueType::string_list, std::move(doc));
}

const KeyDecl* Schema::find(std::string_view key) const {
  for (const auto& k : m_keys)
    if (k.key == key) return &k;
  return nullptr;
}

bool Schema::isTable(std::string_view prefix) const {
  for (const auto& k : m_keys)
    if (k.key.size() > prefix.size() && k.key.compare(0, prefix.size(), prefix) == 0 && k.key[prefix.size()] == '.')
      return true;
  return false;
}

namespace {
std::string rangeText(const KeyDecl& k) {
  auto show = [&](double v) {
    return k.type == ValueType::quantity || k.type == ValueType::quantity_list
               ? fmt::format("{:g} {}", fromSi(v, k.unit), k.unit)
               : fmt::format("{:g}", v);
  };
  std::string out;
  if (k.min) out += (k.min_exclusive ? "> " : ">= ") + show(*k.min);
  if (k.max) out += (out.empty() ? "" : ", ") + std::string(k.max_exclusive ? "< " : "<= ") + show(*k.max);
  if (!k.choices.empty()) out += "one of " + join(k.choices, ", ");
  return out;
}
}  // namespace

void Schema::metric(std::string name, std::string unit, std::string doc) {
  if (name.empty()) throw std::logic_error("schema '" + m_kind + "': a metric without a name");
  for (const auto& m : m_metrics)
    if (m.name == name) throw std::logic_error("schema '" + m_kind + "': metric '" + name + "' declared twice");
  MetricDecl decl;
  decl.dim = parseUnit(unit).dim;
  decl.name = std::move(name);
  decl.unit = unit.empty() ? "1" : std::move(unit);
  decl.doc = std::move(doc);
  m_metrics.push_back(std::move(decl));
}

void Schema::renamed(std::string old_key, std::string new_key, std::string why) {
  m_renamed[std::move(old_key)] = {std::move(new_key), std::move(why)};
}

const std::pair<std::string, std::string>* Schema::findRenamed(std::string_view old_key) const {
  const auto it = m_renamed.find(old_key);
  return it == m_renamed.end() ? nullptr : &it->second;
}

const MetricDecl* Schema::findMetric(std::string_view name) const {
  for (const auto& m : m_metrics)
    if (m.name == name) return &m;
  for (const auto& m : m_metrics)
    if (m.family() && name.size() >= m.name.size() && name.substr(0, m.name.size() - 1) == std::string_view(m.name).substr(0, m.name.size() - 1))
      return &m;
  return nullptr;
}

std::string Schema::markdown() const {
  std::string out = fmt::format("## kind `{}`\n\n{}\n\n| key | type | unit | default | allowed | meaning |\n|---|---|---|---|---|---|\n",
                                m_kind, m_summary);
  for (const auto& k : m_keys) {
    const std::string unit = k.unit.empty() ? "" : k.unit + " (" + dimensionName(k.dim) + ")";
    const std::string def = k.required ? "**required**" : (k.def_text.empty() ? "optional" : "`" + k.def_text + "`");
    out += fmt::format("| `{}` | {} | {} | {} | {} | {} |\n", k.key, typeName(k.type), unit, def, rangeText(k), k.doc);
  }
  if (!m_metrics.empty()) {
    out += "\nMetrics this kind reports (the names `[[acceptance]]` entries may use):\n\n| metric | unit | meaning |\n|---|---|---|\n";
    for (const auto& m : m_metrics) out += fmt::format("| `{}` | {} | {} |\n", m.name, m.unit == "1" ? "1 (dimensionless)" : m.unit, m.doc);
  }
  out += "\nAcceptance entries: `[[acceptance]]` with `metric`, `reference` (number, quantity string, or "
         "`{ file, quantity, at }` into reference-data/), `tolerance` (\"0.5 %\" relative, a quantity for an "
         "absolute bound, \"interval\", or \"none\" to show a reference without judging the value), `reason`, and `label` when one metric is checked against several references.\n";
  return out;
}

void declareCommonKeys(Schema& schema, const std::vector<std::string>& kinds) {
  schema.string("case.name", "Name of the case, used in reports and output folders");
  schema.choice("case.kind", kinds, "What kind of scene this is; selects the runner and the keys below");
  schema.string("case.description", "One or two sentences for the report").def("");
  schema.stringList("case.tags", "Labels such as 'default' (run by `mmval validate`) or 'full'")
      .def(std::vector<std::string>{});
  schema.quantity("run.max_memory", "GB",
                  "Memory the run may plan to use; a run whose estimate (grid, image, particles x outputs) is larger stops "
                  "before it starts, naming the key to change. Default: half of this machine's physical memory")
      .optional()
      .positive();
}

void declareFluid(Schema& schema, const FluidBlock& block) {
  schema.quantity("fluid.viscosity", "Pa s", "Dynamic viscosity").def(block.viscosity).positive();
  if (block.with_density) schema.quantity("fluid.density", "kg/m3", "Fluid density").def(block.density).positive();
  if (block.with_temperature) schema.quantity("fluid.temperature", "K", "Temperature (Brownian motion)").def(block.temperature).positive();
}

const std::vector<std::string>& grainChoices() {
  static const std::vector<std::string> choices = {"dark", "bright", "light"};
  return choices;
}

void declareMask(Schema& schema, const MaskBlock& block) {
  auto mask = schema.path("geometry.mask", block.mask_doc + " (PNG, TIFF; a path relative to the case file)");
  auto pixel = schema.quantity("geometry.pixel_size", "um", "Size of one image pixel (the image carries no scale)");
  if (block.optional) mask.optional();
  if (!block.pixel_default.empty())
    pixel.def(std::string_view(block.pixel_default));
  else if (block.optional)
    pixel.optional();
  pixel.positive();
  schema.choice("geometry.grains", grainChoices(), "Which pixels are grains: dark or bright (\"light\" is an older spelling of \"bright\")").def("dark");
}

}  // namespace mmval
