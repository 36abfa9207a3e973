// Reading a run's JSON outputs (result.json, chip.json, sweep.json) in tests.
#pragma once
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

namespace mmval::test {

/// The whole file parsed; a missing or malformed file throws (and fails the test).
inline nlohmann::json readJson(const std::filesystem::path& p) {
  std::ifstream in(p);
  return nlohmann::json::parse(in);
}

/// The value of the metric named `name` in a result.json; NaN and a test failure when absent.
inline double metricOf(const nlohmann::json& result, const std::string& name) {
  for (const auto& m : result.at("metrics"))
    if (m.at("name") == name) return m.at("value").get<double>();
  ADD_FAILURE() << "no metric " << name;
  return std::nan("");
}

}  // namespace mmval::test
