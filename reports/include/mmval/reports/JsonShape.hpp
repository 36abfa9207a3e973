// The shapes of the JSON files a report reads, checked before any field is
// used: a field missing or of the wrong type is named with its file and path
// ("metrics[2].pass") instead of surfacing as a JSON type error in a figure.
// Only the fields the report and the diff read are checked (details: every
// declared field); others are free.
#pragma once
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace mmval::reports {

/// result.json of `mmval run` (schema mmval-result/1): case name, kind and
/// hash, metrics, all_pass, cost, provenance, files, and every declared
/// details field present (mmval/core/DetailFields.hpp: type, array length,
/// members). Throws InputError naming `file` and the field. Returns the keys
/// of details that no declaration names: allowed (the kinds' informational
/// keys, which no reader takes apart), sorted.
std::vector<std::string> checkResultShape(const nlohmann::json& doc, const std::filesystem::path& file);

/// metrics.json of `mmval compare` (schema mmval-compare/1): metrics,
/// all_pass, regions and alignment. Throws InputError naming `file` and the field.
void checkCompareShape(const nlohmann::json& doc, const std::filesystem::path& file);

/// sweep.json of `mmval sweep` (schema mmval-sweep/1): case name, axes, groups
/// (setting and per-metric statistics) and, when present, discretisation and
/// uncertainty (per metric: unit and settings). Throws InputError naming `file`
/// and the field.
void checkSweepShape(const nlohmann::json& doc, const std::filesystem::path& file);

/// A document `report --diff` reads: an object with a "metrics" list whose
/// entries have name, value, pass and tolerance (and optionally case), as the
/// report's metrics.json, compare's metrics.json and result.json do. A
/// relative tolerance must read as a number ("20 %"). Throws InputError.
void checkMetricsListShape(const nlohmann::json& doc, const std::filesystem::path& file);

}  // namespace mmval::reports
