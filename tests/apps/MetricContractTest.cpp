// The metric contract over every case kind (typed metrics, one test over all kinds):
// each kind declares the metrics its runner reports, with units; every bundled
// case's [[acceptance]] entries name declared metrics with references of the
// declared dimension; bad entries are refused at load (case-check) with the
// entry's key; and every metric name a runner emits is declared.
//
// The last check scans the runners' sources for the literal metric names
// rather than running one case per kind: several kinds need data, engines or
// minutes (tracking-video a video, compare-tracks two track files, LIGGGHTS,
// unsteady cylinders), and most metrics are emitted only on some branches
// (unsteady mode, probes, engines.compare, clogging), which one cheap run would
// not reach. A scan sees every branch in milliseconds. It refuses what it cannot
// read: a metrics map filled with a computed name, or a kind missing from its
// table, fails with a message saying what to add.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "AllKinds.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Units.hpp"

namespace fs = std::filesystem;
using namespace mmval;

namespace {

const mmval::CaseKindRegistry& registry() { return mmval::test::allKinds(); }

std::vector<std::string> kindNames() { return registry().names(); }

std::vector<std::string> bundledCases() {
  std::vector<std::string> files;
  for (const auto& e : fs::directory_iterator(fs::path(MMVAL_SOURCE_DIR) / "cases"))
    if (e.path().extension() == ".toml") files.push_back(e.path().filename().string());
  std::sort(files.begin(), files.end());
  return files;
}

std::string paramName(const ::testing::TestParamInfo<std::string>& info) {
  std::string s = info.param;
  for (char& ch : s)
    if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
  return s;
}

// ---- (a) every kind declares its metrics, each with a known unit ----------

class KindMetrics : public ::testing::TestWithParam<std::string> {};

TEST_P(KindMetrics, DeclaresMetricsWithKnownUnitsAndDocs) {
  const Schema& s = registry().schema(GetParam());
  ASSERT_FALSE(s.metrics().empty()) << "kind '" << GetParam() << "' declares no metric (see its library's KindMetrics.cpp)";
  for (const auto& m : s.metrics()) {
    SCOPED_TRACE(m.name);
    EXPECT_FALSE(m.doc.empty());
    EXPECT_FALSE(m.unit.empty());
    EXPECT_NO_THROW({
      const Unit u = parseUnit(m.unit);
      EXPECT_TRUE(u.dim == m.dim);
    });
    EXPECT_EQ(s.findMetric(m.name), &m);
  }
  // case-doc lists them.
  const std::string doc = s.markdown();
  for (const auto& m : s.metrics()) EXPECT_NE(doc.find("`" + m.name + "`"), std::string::npos) << m.name;
}

INSTANTIATE_TEST_SUITE_P(EveryKind, KindMetrics, ::testing::ValuesIn(kindNames()), paramName);

// ---- (b) every bundled case's acceptance entries pass the check -----------

class BundledCase : public ::testing::TestWithParam<std::string> {};

TEST_P(BundledCase, LoadsWithItsAcceptanceEntries) {
  const fs::path file = fs::path(MMVAL_SOURCE_DIR) / "cases" / GetParam();
  try {
    const Case c = Case::load(file, registry());
    const Schema& s = registry().schema(c.kind());
    for (const auto& a : c.acceptance()) {
      const MetricDecl* m = s.findMetric(a.metric);
      ASSERT_NE(m, nullptr) << a.metric;
      EXPECT_TRUE(a.reference.dim == m->dim) << a.metric;
    }
  } catch (const InputError& e) {
    FAIL() << e.what();
  }
}

INSTANTIATE_TEST_SUITE_P(EveryCase, BundledCase, ::testing::ValuesIn(bundledCases()), paramName);

// ---- (c) bad acceptance entries are refused with the entry's key ----------

/// A plane Poiseuille case (kind channel, flow_rate_per_depth in m2/s) with one acceptance entry.
std::string channelCase(const std::string& acceptance) {
  return "[case]\nname = \"bad-acceptance\"\nkind = \"channel\"\n\n[geometry]\nwidth = \"100 um\"\n\n[numerics]\ncells = 8\n\n"
         "[[acceptance]]\n" +
         acceptance + "reason = \"test\"\n";
}

/// Loads `text`; expects an InputError whose key is `key` and whose message names the key and holds `problem`.
void expectRefused(const std::string& text, const std::string& key, const std::string& problem) {
  try {
    Case::parse(text, "bad.toml", registry());
    ADD_FAILURE() << "accepted:\n" << text;
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().key, key) << e.what();
    EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(problem), std::string::npos) << e.what();
  }
}

TEST(MetricContract, GoodEntryLoadsAndABareNumberTakesTheMetricsDimension) {
  const Case c = Case::parse(channelCase("metric = \"flow_rate_per_depth\"\nreference = 8.33e-7\ntolerance = \"1 %\"\n"), "ok.toml", registry());
  ASSERT_EQ(c.acceptance().size(), 1u);
  EXPECT_TRUE(c.acceptance()[0].reference.dim == parseUnit("m2/s").dim);
}

TEST(MetricContract, ReferenceOfAnotherDimensionIsRefused) {
  expectRefused(channelCase("metric = \"flow_rate_per_depth\"\nreference = \"8.33e-7 kg\"\ntolerance = \"1 %\"\n"), "acceptance[0].reference",
                "wrong dimension");
}

TEST(MetricContract, UnknownMetricIsRefusedWithTheNearestName) {
  expectRefused(channelCase("metric = \"flow_rate_per_dept\"\nreference = \"8.33e-7 m2/s\"\ntolerance = \"1 %\"\n"), "acceptance[0].metric",
                "did you mean 'flow_rate_per_depth'");
}

TEST(MetricContract, NanReferenceIsRefused) {
  expectRefused(channelCase("metric = \"flow_rate_per_depth\"\nreference = nan\ntolerance = \"1 %\"\n"), "acceptance[0].reference", "not a finite");
}

TEST(MetricContract, NanToleranceIsRefused) {
  expectRefused(channelCase("metric = \"flow_rate_per_depth\"\nreference = \"8.33e-7 m2/s\"\ntolerance = nan\n"), "acceptance[0].tolerance",
                "not a finite");
}

TEST(MetricContract, ToleranceOfAnotherDimensionIsRefused) {
  expectRefused(channelCase("metric = \"flow_rate_per_depth\"\nreference = \"8.33e-7 m2/s\"\ntolerance = \"1e-9 kg\"\n"),
                "acceptance[0].tolerance", "wrong dimension");
}

// ---- (d) every metric a runner emits is declared -------------------------

/// Part of a runner's source: [begin, end) between two markers ("" = file start / end).
struct Region {
  std::string file;
  std::string begin, end;
  /// Metric names built at run time in this region (per-height or per-band families,
  /// declared with a '*'): counted, so a new one is noticed; EveryMetricARunnerEmitsIsDeclared
  /// cannot read them, the physics-check tests run those kinds and their acceptance entries.
  std::size_t computed = 0;
};

/// Where each kind's runner fills its metrics. A file shared by kinds is cut at markers.
struct KindSources {
  std::vector<Region> regions;
};

/// The tracking kinds' scores against the truth, filled by one helper (Score.cpp).
const Region kScoreMetrics{"tracking/src/Score.cpp", "void addScoreMetrics(", "double immobileRecall("};

const std::map<std::string, KindSources>& sources() {
  static const std::map<std::string, KindSources> s = {
      {"channel", {{{"simulate/src/Kinds.cpp", "", ""}}}},
      {"periodic-array", {{{"simulate/src/KindsPorous.cpp", "CaseKind periodicArrayKind()", "CaseKind imagePermeabilityKind()"}}}},
      {"chip-generator", {{{"simulate/src/KindsChip.cpp", "", ""}}}},
      {"cylinder-channel", {{{"simulate/src/KindsCylinder.cpp", "", ""}, {"simulate/src/KindsCylinderUnsteady.cpp", "", ""}}}},
      {"image-permeability",
       {{{"simulate/src/KindsPorous.cpp", "", "CaseKind periodicArrayKind()"}, {"simulate/src/KindsPorous.cpp", "CaseKind imagePermeabilityKind()", ""}}}},
      {"tracking-video", {{{"tracking/src/Kinds.cpp", "RunOutput runTrackingVideo(", "void registerTrackingKinds("}, kScoreMetrics}}},
      {"tracking-synthetic", {{{"tracking/src/Kinds.cpp", "k.name = \"tracking-synthetic\"", ""}, kScoreMetrics}}},
      {"tracking-rendered", {{{"tracking/src/KindRendered.cpp", "", ""}, kScoreMetrics}}},
      {"particles-channel", {{{"simulate/particles/src/Kinds.cpp", "", ""}}}},
      {"particles-micromodel", {{{"simulate/particles/src/Micromodel.cpp", "", ""}}}},
      {"particles-resolved", {{{"simulate/particles/src/Resolved.cpp", "", ""}, {"simulate/particles/src/ResolvedStages.cpp", "", ""}}}},
      {"compare-tracks", {{{"compare/src/Compare.cpp", "", ""}, {"compare/src/Scene.cpp", "", ""}}}},
      {"physics-sedimentation", {{{"simulate/particles/src/checks/WallChecks.cpp", "RunOutput runSedimentation(", "void sedimentationMetrics("}}}},
      {"physics-hindered-diffusion",
       {{{"simulate/particles/src/checks/WallChecks.cpp", "RunOutput runHinderedDiffusion(", "void hinderedDiffusionMetrics(", 4}}}},
      {"physics-blocking", {{{"simulate/particles/src/checks/WallChecks.cpp", "RunOutput runBlocking(", "void blockingMetrics(", 1}}}},
      {"physics-settling-slit", {{{"simulate/particles/src/checks/SlitChecks.cpp", "RunOutput runSettling(", "void declareDiffusion("}}}},
      {"physics-diffusion-slit", {{{"simulate/particles/src/checks/SlitChecks.cpp", "RunOutput runDiffusion(", "", 2}}}},
      {"physics-collector-interception", {{{"simulate/particles/src/checks/CollectorCheck.cpp", "RunOutput runInterception(", "void interceptionMetrics("}}}},
      {"physics-collector-diffusion", {{{"simulate/particles/src/checks/CollectorDiffusion.cpp", "RunOutput runDiffusion(", "void diffusionMetrics("}}}},
      {"physics-dlvo", {{{"simulate/particles/src/checks/DlvoChecks.cpp", "void profileStage(", "void registerDlvoChecks(", 2}}}},
      {"physics-near-wall-shear", {{{"simulate/particles/src/checks/ShearCheck.cpp", "RunOutput runShear(", "void registerShearChecks(", 1}}}},
  };
  return s;
}

/// The OpenFOAM peer runs these kinds through one function (addMetrics): each
/// name it emits must be declared by at least one of them.
const char* const kPeerFile = "simulate/openfoam/src/Kinds.cpp";
const std::vector<std::string> kPeerKinds = {"cylinder-channel", "periodic-array", "image-permeability"};

std::string readSource(const std::string& rel) {
  std::ifstream in(fs::path(MMVAL_SOURCE_DIR) / rel);
  if (!in) throw std::runtime_error("cannot read " + rel);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string regionText(const Region& r) {
  const std::string text = readSource(r.file);
  std::size_t b = 0, e = text.size();
  if (!r.begin.empty()) {
    b = text.find(r.begin);
    if (b == std::string::npos) throw std::runtime_error(r.file + ": marker '" + r.begin + "' not found; update sources() in MetricContractTest.cpp");
  }
  if (!r.end.empty()) {
    e = text.find(r.end, b);
    if (e == std::string::npos) throw std::runtime_error(r.file + ": marker '" + r.end + "' not found; update sources() in MetricContractTest.cpp");
  }
  return text.substr(b, e - b);
}

/// Literal metric names in `text`: metrics["x"] and the helpers that fill metric lists
/// (OpenFOAM put, comparator against / info / region / add, and a hand-built Acceptance).
std::set<std::string> emittedNames(const std::string& text) {
  static const std::regex name_re(
      R"re((?:metrics\[|\bput\(|\bagainst\(|\binfo\(|\bregion\(|\badd\(|a\.metric = )"([A-Za-z_][A-Za-z0-9_]*)")re");
  std::set<std::string> names;
  for (auto it = std::sregex_iterator(text.begin(), text.end(), name_re); it != std::sregex_iterator(); ++it) names.insert((*it)[1]);
  return names;
}

/// `metrics[` with something else than a string literal: a name the scan cannot see.
std::size_t computedNames(const std::string& text) {
  static const std::regex computed_re(R"(metrics\[[^"])");
  return static_cast<std::size_t>(std::distance(std::sregex_iterator(text.begin(), text.end(), computed_re), std::sregex_iterator()));
}

TEST(MetricContract, EveryKindHasItsRunnerSourcesInTheScan) {
  for (const auto& k : kindNames()) EXPECT_TRUE(sources().count(k)) << "kind '" << k << "': add its runner's files to sources() in MetricContractTest.cpp";
}

TEST(MetricContract, EveryMetricARunnerEmitsIsDeclared) {
  for (const auto& [kind, src] : sources()) {
    SCOPED_TRACE(kind);
    ASSERT_NE(registry().find(kind), nullptr) << "no kind '" << kind << "' registered";
    const Schema& s = registry().schema(kind);
    std::size_t found = 0;
    for (const auto& r : src.regions) {
      const std::string text = regionText(r);
      EXPECT_EQ(computedNames(text), r.computed) << r.file << " fills a metrics map with a computed name: the scan cannot check it";
      for (const auto& name : emittedNames(text)) {
        ++found;
        EXPECT_NE(s.findMetric(name), nullptr) << r.file << " emits '" << name << "', which kind '" << kind << "' does not declare";
      }
    }
    EXPECT_GT(found, 0u) << "no metric found in the sources of '" << kind << "'";
  }
}

TEST(MetricContract, EveryMetricThePeerEmitsIsDeclaredByAPeerKind) {
  const std::string text = readSource(kPeerFile);
  // Its one computed name is addMetrics' put(name, ...) helper, whose callers the scan reads.
  EXPECT_EQ(computedNames(text), 1u) << kPeerFile << " fills a metrics map other than through put(\"name\", ...)";
  const std::set<std::string> names = emittedNames(text);
  EXPECT_FALSE(names.empty());
  for (const auto& name : names) {
    bool declared = false;
    for (const auto& k : kPeerKinds) declared = declared || registry().schema(k).findMetric(name) != nullptr;
    EXPECT_TRUE(declared) << kPeerFile << " emits '" << name << "', which no fluid kind declares";
  }
}

TEST(MetricContract, EveryDeclaredMetricIsEmittedSomewhere) {
  // The other direction: no declaration outlives the code that reported it.
  for (const auto& [kind, src] : sources()) {
    SCOPED_TRACE(kind);
    std::set<std::string> names;
    for (const auto& r : src.regions) names.merge(emittedNames(regionText(r)));
    if (std::find(kPeerKinds.begin(), kPeerKinds.end(), kind) != kPeerKinds.end()) names.merge(emittedNames(readSource(kPeerFile)));
    for (const auto& m : registry().schema(kind).metrics()) {
      if (m.family()) continue;
      EXPECT_TRUE(names.count(m.name)) << "kind '" << kind << "' declares '" << m.name << "', which none of its runners emits";
    }
  }
}

}  // namespace
