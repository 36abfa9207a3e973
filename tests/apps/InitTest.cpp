// The case-file commands that write or change a case for the user:
// `mmval init KIND` (a commented starter case from the kind's declarations)
// over every registered kind, and `mmval run CASE --set KEY=VALUE`.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "AllKinds.hpp"
#include "RunMmval.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Units.hpp"

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using mmval::test::Outcome;
using mmval::test::runMmval;

namespace {

const mmval::CaseKindRegistry& registry() { return mmval::test::allKinds(); }

std::string readFile(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// Values for required keys that the generic choice below would get wrong;
/// every other required key gets a minimal value of its type within its range.
const std::map<std::string, std::string>& fillTable() {
  static const std::map<std::string, std::string> t = {
      {"geometry.mask", "\"chip.png\""},
      {"inputs.video", "\"video.avi\""},
      {"inputs.experiment", "\"experiment.csv\""},
      {"inputs.simulation", "\"simulation.csv\""},
  };
  return t;
}

/// A value for `d` inside its declared range, as TOML (bare numbers are SI).
std::string minimalValue(const mmval::KeyDecl& d, const std::string& kind) {
  if (d.key == "case.name") return "\"init-" + kind + "\"";
  if (auto it = fillTable().find(d.key); it != fillTable().end()) return it->second;
  const auto inRange = [&](double unit) {
    if (d.min && d.max) return 0.5 * (*d.min + *d.max);
    double x = unit;
    if (d.min && (x < *d.min || (d.min_exclusive && x == *d.min))) x = *d.min > 0 ? 2 * *d.min : *d.min + unit;
    if (d.max && (x > *d.max || (d.max_exclusive && x == *d.max))) x = *d.max > 0 ? 0.5 * *d.max : *d.max - unit;
    return x;
  };
  const auto number = [&] {
    const double unit = d.type == mmval::ValueType::quantity || d.type == mmval::ValueType::quantity_list ? mmval::parseUnit(d.unit).to_si : 1.0;
    return fmt::format("{:.17g}", inRange(unit));
  };
  const auto integer = [&] { return std::to_string(static_cast<long long>(std::ceil(inRange(1.0)))); };
  switch (d.type) {
    case mmval::ValueType::quantity:
    case mmval::ValueType::real: return number();
    case mmval::ValueType::integer: return integer();
    case mmval::ValueType::boolean: return "false";
    case mmval::ValueType::string: return "\"x\"";
    case mmval::ValueType::choice: return "\"" + d.choices.front() + "\"";
    case mmval::ValueType::path: return "\"input.dat\"";
    case mmval::ValueType::real_list:
    case mmval::ValueType::quantity_list: return "[" + number() + "]";
    case mmval::ValueType::integer_list: return "[" + integer() + "]";
    case mmval::ValueType::string_list: return "[\"x\"]";
  }
  return "\"\"";
}

/// Uncomments the `#leaf =` line of `key` inside its [table] and gives it `value`.
bool fill(std::string& text, const std::string& key, const std::string& value) {
  const auto dot = key.rfind('.');
  const std::string header = "\n[" + key.substr(0, dot) + "]\n";
  const auto table = text.find(header);
  if (table == std::string::npos) return false;
  const auto next = text.find("\n[", table + header.size());
  const std::string line = "\n#" + key.substr(dot + 1) + " =";
  const auto at = text.find(line, table);
  if (at == std::string::npos || (next != std::string::npos && at > next)) return false;
  const auto end = text.find('\n', at + 1);
  text.replace(at, end - at, "\n" + key.substr(dot + 1) + " = " + value);
  return true;
}

TEST(Init, EveryKindsStarterCasePassesCaseCheckOnceItsRequiredKeysAreFilled) {
  const fs::path dir = mmval::test::freshTestFolder("init", "every-kind");
  ASSERT_FALSE(registry().names().empty());
  std::string filled_files;
  for (const auto& kind : registry().names()) {
    SCOPED_TRACE("kind " + kind);
    const Outcome o = runMmval("init " + kind);
    ASSERT_EQ(o.status, 0) << o.output;
    const mmval::Schema& schema = registry().schema(kind);
    std::string text = o.output;
    EXPECT_THAT(text, HasSubstr("kind = \"" + kind + "\""));
    // Every declared key is there, with its meaning; the keys without a default are marked.
    for (const auto& d : schema.keys()) {
      EXPECT_THAT(text, HasSubstr(d.key.substr(d.key.rfind('.') + 1) + " =")) << d.key;
      EXPECT_THAT(text, HasSubstr(d.doc.substr(0, 30))) << d.key;
      if (d.required && d.key != "case.kind") {
        EXPECT_THAT(text, HasSubstr("#" + d.key.substr(d.key.rfind('.') + 1) + " =   # REQUIRED")) << d.key;
      }
    }
    if (kind == "channel") {
      // As printed, the starter is refused until its required keys are given.
      std::ofstream(dir / "channel-unfilled.toml") << text;
      const Outcome unfilled = runMmval("case-check " + (dir / "channel-unfilled.toml").string());
      EXPECT_EQ(unfilled.status, 2) << unfilled.output;
      EXPECT_THAT(unfilled.output, HasSubstr("missing required key"));
    }
    for (const auto& d : schema.keys()) {
      if (d.required && d.key != "case.kind") {
        ASSERT_TRUE(fill(text, d.key, minimalValue(d, kind))) << "no '#" << d.key << " =' line under its table";
      }
    }
    const fs::path filled = dir / (kind + ".toml");
    std::ofstream(filled) << text;
    filled_files += " " + filled.string();
  }
  // case-check stops at the first bad file and names it.
  const Outcome check = runMmval("case-check" + filled_files);
  EXPECT_EQ(check.status, 0) << check.output;
  for (const auto& kind : registry().names()) EXPECT_THAT(check.output, HasSubstr("ok (kind " + kind + ", case 'init-" + kind + "'"));
}

TEST(Init, WritesANewFileOnlyAndNamesUnknownKinds) {
  const fs::path dir = mmval::test::freshTestFolder("init", "out");
  const Outcome printed = runMmval("init channel");
  ASSERT_EQ(printed.status, 0) << printed.output;
  const Outcome written = runMmval("init channel --out " + (dir / "new.toml").string());
  ASSERT_EQ(written.status, 0) << written.output;
  EXPECT_EQ(readFile(dir / "new.toml"), printed.output);

  std::ofstream(dir / "mine.toml") << "my own notes\n";
  const Outcome refused = runMmval("init channel --out " + (dir / "mine.toml").string());
  EXPECT_EQ(refused.status, 2) << refused.output;
  EXPECT_THAT(refused.output, HasSubstr("does not overwrite"));
  EXPECT_EQ(readFile(dir / "mine.toml"), "my own notes\n");

  const Outcome unknown = runMmval("init chanel");
  EXPECT_EQ(unknown.status, 2) << unknown.output;
  EXPECT_THAT(unknown.output, HasSubstr("did you mean 'channel'"));
}

// The plane Poiseuille case with its gap doubled from the command line: the
// flow rate per depth is q = G W^3 / (12 mu) = 1e4 x (2e-4)^3 / 1.2e-2
// = 6.6667e-6 m^2/s, eight times the case file's reference, so the run
// completes and its acceptance metric fails (exit 3) against the 100 um value.
TEST(RunSet, OverridesAreAppliedCheckedAndRecorded) {
  const fs::path dir = mmval::test::freshTestFolder("run-set", "poiseuille");
  const std::string case_file = std::string(MMVAL_SOURCE_DIR) + "/cases/fluid-poiseuille.toml";
  const Outcome o = runMmval("run --set \"geometry.width=200 um\" " + case_file + " --out " + (dir / "run").string() +
                             " --quiet --set \"numerics.levels=[64]\"");
  EXPECT_EQ(o.status, 3) << o.output;
  std::ifstream in(dir / "run" / "result.json");
  ASSERT_TRUE(in) << o.output;
  const nlohmann::json r = nlohmann::json::parse(in);
  EXPECT_EQ(r["case"]["overrides"], nlohmann::json::array({"geometry.width=200 um", "numerics.levels=[64]"}));
  EXPECT_EQ(r["resolved_case"]["geometry"]["width"], "200 um");
  EXPECT_EQ(r["resolved_case"]["numerics"]["levels"], nlohmann::json::array({64}));
  double q = 0;
  for (const auto& m : r["metrics"])
    if (m["name"] == "flow_rate_per_depth") q = m["value"].get<double>() * mmval::parseUnit(m["unit"].get<std::string>()).to_si;
  // Second-order grid at 64 cells: well inside 0.5 % (the case's own tolerance at 32 cells).
  EXPECT_NEAR(q, 1e4 * 8e-12 / 1.2e-2, 0.005 * 6.6667e-6);

  // A bad value names the --set and the key, before anything runs.
  const Outcome bad = runMmval("run " + case_file + " --out " + (dir / "bad").string() + " --set \"geometry.width=2 m/s\"");
  EXPECT_EQ(bad.status, 2) << bad.output;
  EXPECT_THAT(bad.output, HasSubstr("(--set geometry.width=2 m/s): key 'geometry.width': wrong dimension"));
  EXPECT_FALSE(fs::exists(dir / "bad"));
  const Outcome typo = runMmval("run " + case_file + " --out " + (dir / "typo").string() + " --set geometry.widht=1e-4");
  EXPECT_EQ(typo.status, 2) << typo.output;
  EXPECT_THAT(typo.output, HasSubstr("did you mean 'geometry.width'"));
}

}  // namespace
