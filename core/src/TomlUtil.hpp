// Private helpers shared by the TOML readers of mmval::core.
#pragma once
#include <string>

#include <toml++/toml.h>

namespace mmval::detail {

inline int lineOf(const toml::node& n) { return static_cast<int>(n.source().begin.line); }

/// What the user wrote, in words: "a string", "an integer", "a table", ...
inline std::string tomlTypeName(const toml::node& n) {
  switch (n.type()) {
    case toml::node_type::string: return "a string";
    case toml::node_type::integer: return "an integer";
    case toml::node_type::floating_point: return "a number";
    case toml::node_type::boolean: return "a boolean";
    case toml::node_type::table: return "a table";
    case toml::node_type::array: return "an array";
    case toml::node_type::date: return "a date";
    case toml::node_type::time: return "a time";
    case toml::node_type::date_time: return "a date-time";
    default: return "nothing";
  }
}

/// The value as the user wrote it, shortened, for messages.
inline std::string tomlValueText(const toml::node& n) {
  std::string out;
  if (auto s = n.value<std::string>()) {
    out = "\"" + *s + "\"";
  } else if (n.is_integer()) {
    out = std::to_string(*n.value<std::int64_t>());
  } else if (n.is_floating_point()) {
    char buf[64];
    std::snprintf(buf, sizeof buf, "%g", *n.value<double>());
    out = buf;
  } else if (n.is_boolean()) {
    out = *n.value<bool>() ? "true" : "false";
  } else {
    out = tomlTypeName(n);
  }
  return out;
}

}  // namespace mmval::detail
