// JSON has no NaN or infinity: a number that is not finite (a quantity that did not happen, or
// could not be computed) is written as null, and reads as absent (DetailFields.hpp). Every writer
// of result.json, chip.json, sweep.json and the tracker's summaries goes through this one rule.
#pragma once
#include <cmath>

#include <nlohmann/json.hpp>

namespace mmval {

/// v as a JSON number, or null when it is NaN or infinite.
inline nlohmann::json finiteOrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace mmval
