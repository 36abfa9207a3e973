// docs/outputs.md against the writers. Every section "### `file`" of the page with a
// `column | unit | meaning` table lists exactly the columns, in order, of a file that
// the file's writer wrote here; every `field | unit | meaning` table of a JSON file
// lists the top-level keys the writer writes. The tables are read from the page, so the
// page and the code cannot drift apart; a new table needs its writer in this test. The
// writers run in-process where that is cheap, else through `mmval` on small cases.
// (`tracks.csv` and `trajectories.csv` share a section of optional columns, found by
// name: core/include/mmval/core/Tracks.hpp and its tests hold that schema.)
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/compare/Compare.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/reports/Report.hpp"
#include "mmval/simulate/ForceHistory.hpp"
#include "mmval/tracking/Pipeline.hpp"

#include "../TestScratch.hpp"
#include "RunMmval.hpp"

namespace mmval {
namespace {

namespace fs = std::filesystem;

std::string slurp(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// A table of docs/outputs.md: the file its section names, whether it lists columns
/// (CSV) or fields (JSON), and the names in its first column, in order.
struct DocTable {
  std::string file;
  bool fields = false;
  std::vector<std::string> names;
};

/// Every "### `file`" (optionally followed by " (...)") section with a
/// `column | unit | meaning` or `field | unit | meaning` table.
std::map<std::string, DocTable> documentedTables() {
  std::istringstream in(slurp(fs::path(MMVAL_SOURCE_DIR) / "docs" / "outputs.md"));
  const std::regex heading(R"(^### `([^`]+)`( \(.*\))?$)");
  const std::regex name("`([^`]+)`");
  std::map<std::string, DocTable> out;
  std::string line, file;
  bool in_table = false, fields = false;
  while (std::getline(in, line)) {
    std::smatch m;
    if (line.starts_with("#")) {
      file = std::regex_match(line, m, heading) ? m[1].str() : std::string();
      in_table = false;
      continue;
    }
    if (file.empty()) continue;
    if (line == "| column | unit | meaning |" || line == "| field | unit | meaning |") {
      fields = line.starts_with("| field");
      in_table = true;
      out[file] = {file, fields, {}};
      continue;
    }
    if (in_table && line.starts_with("|---")) continue;
    if (!in_table || !line.starts_with("| ")) {
      in_table = false;
      continue;
    }
    const std::string first = line.substr(2, line.find(" |", 2) - 2);
    for (auto it = std::sregex_iterator(first.begin(), first.end(), name); it != std::sregex_iterator(); ++it) out[file].names.push_back((*it)[1]);
  }
  return out;
}

const DocTable& documented(const std::string& file) {
  static const std::map<std::string, DocTable> tables = documentedTables();
  static const DocTable none;
  const auto it = tables.find(file);
  return it == tables.end() ? none : it->second;
}

/// The cells of a CSV line, empty ones (a trailing one too) kept.
std::vector<std::string> split(const std::string& line) {
  std::vector<std::string> out(1);
  for (char ch : line)
    if (ch == ',')
      out.emplace_back();
    else
      out.back() += ch;
  return out;
}

/// The header of a written CSV is the documented column list.
void expectColumns(const fs::path& csv) {
  const std::string file = csv.filename().string();
  const DocTable& doc = documented(file);
  ASSERT_FALSE(doc.names.empty()) << file << ": no `column | unit | meaning` table under \"### `" << file << "`\" in docs/outputs.md";
  ASSERT_TRUE(fs::exists(csv)) << csv;
  const std::string text = slurp(csv);
  EXPECT_EQ(split(text.substr(0, text.find('\n'))), doc.names) << csv << ": header against docs/outputs.md";
}

/// The top-level keys of JSON documents the writer wrote against the documented fields:
/// every written key is documented, and every documented key is written by one of `docs`
/// or is one of `conditional` (written only in situations the test does not set up).
void expectFields(const std::string& file, const std::vector<nlohmann::json>& docs, const std::set<std::string>& conditional = {}) {
  const DocTable& doc = documented(file);
  ASSERT_TRUE(doc.fields && !doc.names.empty()) << file << ": no `field | unit | meaning` table in docs/outputs.md";
  const std::set<std::string> listed(doc.names.begin(), doc.names.end());
  std::set<std::string> written;
  for (const auto& j : docs)
    for (const auto& [key, value] : j.items()) {
      written.insert(key);
      EXPECT_TRUE(listed.count(key)) << file << ": key '" << key << "' is written but not in docs/outputs.md";
    }
  for (const auto& key : listed) EXPECT_TRUE(written.count(key) || conditional.count(key)) << file << ": '" << key << "' is documented but not written";
}

/// Numeric columns of a CSV by name; empty cells read as NaN.
std::map<std::string, std::vector<double>> columns(const fs::path& csv) {
  std::istringstream in(slurp(csv));
  std::string line;
  std::getline(in, line);
  const auto names = split(line);
  std::map<std::string, std::vector<double>> out;
  while (std::getline(in, line)) {
    const auto cells = split(line);
    for (std::size_t i = 0; i < names.size(); ++i) {
      const std::string cell = i < cells.size() ? cells[i] : "";
      out[names[i]].push_back(cell.empty() ? std::nan("") : std::strtod(cell.c_str(), nullptr));
    }
  }
  return out;
}

TrackPoint point(std::int64_t id, int frame, double fps, double x_px, double y_px, double pixel_m, const char* state) {
  TrackPoint q;
  q.frame = frame;
  q.particle = id;
  q.t = frame / fps;
  q.x_px = x_px;
  q.y_px = y_px;
  q.x = x_px * pixel_m;
  q.y = y_px * pixel_m;
  q.state = state;
  return q;
}

/// Flow: three particles crossing the view at 5 px per frame (1 um pixels, 10 fps: 50 um/s),
/// entering at frames 0, 2 and 4; one sits still. The moving ones' MSD is (50 um/s t)^2.
tracking::TrackRun flowRun() {
  tracking::TrackRun run;
  for (int id = 1; id <= 3; ++id)
    for (int f = 2 * (id - 1); f < 30; ++f) run.tracks.points.push_back(point(id, f, 10, 5 + 5 * (f - 2 * (id - 1)), 20 * id, 1e-6, "mobile"));
  for (int f = 0; f < 30; ++f) run.tracks.points.push_back(point(4, f, 10, 100, 90, 1e-6, "immobile"));
  for (int f = 0; f < 30; ++f) run.frame_index.push_back(f);
  run.detections.resize(30);
  run.motion.model = tracking::MotionModel::flow;
  return run;
}

/// Brownian: 40 particles, 60 frames at 10 fps, 0.5 um pixels, steps of D = 0.5 um^2/s
/// along x and y (standard deviation sqrt(2 D dt) per axis), no drift, no noise.
constexpr double kBrownianD = 0.5e-12, kBrownianDt = 0.1;
tracking::TrackRun brownianRun() {
  tracking::TrackRun run;
  std::mt19937 rng(27);
  std::normal_distribution<double> step(0.0, std::sqrt(2 * kBrownianD * kBrownianDt));
  const double pixel = 0.5e-6;
  for (int id = 1; id <= 40; ++id) {
    double x = (20 + 10 * (id % 8)) * pixel, y = (20 + 10 * (id / 8)) * pixel;
    for (int f = 0; f < 60; ++f) {
      run.tracks.points.push_back(point(id, f, 1 / kBrownianDt, x / pixel, y / pixel, pixel, ""));
      x += step(rng);
      y += step(rng);
    }
  }
  for (int f = 0; f < 60; ++f) run.frame_index.push_back(f);
  run.detections.resize(60);
  run.motion.model = tracking::MotionModel::brownian;
  return run;
}

fs::path trackOutputs(const char* name, const tracking::TrackRun& run, double pixel_m, double fps) {
  tracking::TrackConfig cfg;
  cfg.pixel_size = pixel_m;
  cfg.fps = fps;
  cfg.analysis.motion = run.motion.model;
  const fs::path dir = mmval::test::scratch(name);
  fs::remove_all(dir);
  tracking::writeTrackOutputs(run, cfg, dir, nlohmann::json::object());
  return dir;
}

TEST(OutputDocs, TrackerFlowFilesHaveTheDocumentedColumns) {
  const fs::path dir = trackOutputs("docs-flow", flowRun(), 1e-6, 10);
  for (const char* f : {"detections.csv", "track_summary.csv", "velocities.csv", "dispersion.csv", "msd.csv", "speed_time.csv", "retention.csv"})
    expectColumns(dir / f);
  // msd.csv in flow mode: straight lines at one speed v give MSD = v^2 t^2, so the power-law
  // fit is exact (alpha 2, 4 D = v^2): fit_um2 = msd_um2. The file prints 6 significant
  // digits, so the two agree to 1e-5 relative; no standard error in flow mode.
  const auto msd = columns(dir / "msd.csv");
  ASSERT_GE(msd.at("lag_s").size(), 3u);
  for (std::size_t i = 0; i < msd.at("lag_s").size(); ++i) {
    const double t = msd.at("lag_s")[i], v = 50.0;  // um/s
    EXPECT_NEAR(msd.at("msd_um2")[i], v * v * t * t, 1e-5 * v * v * t * t) << "lag " << t;
    EXPECT_NEAR(msd.at("fit_um2")[i], msd.at("msd_um2")[i], 1e-5 * msd.at("msd_um2")[i]) << "lag " << t;
    EXPECT_TRUE(std::isnan(msd.at("se_um2")[i])) << "lag " << t << ": flow mode has no standard error";
  }
}

TEST(OutputDocs, TrackerBrownianFilesHaveTheDocumentedColumns) {
  const fs::path dir = trackOutputs("docs-brownian", brownianRun(), 0.5e-6, 1 / kBrownianDt);
  for (const char* f : {"detections.csv", "dispersion.csv", "msd.csv", "track_diffusion.csv", "van_hove.csv", "diffusion_histogram.csv"})
    expectColumns(dir / f);
  // msd.csv in Brownian mode: the first lag against the walk's 4 D dt, within 3 of the
  // file's own standard errors (about 2 % each: 2360 displacements). The drift correction
  // subtracts each frame's mean step of the 40 particles, which leaves a step's variance
  // times (1 - 1/40). The fit column is summary.json's line 4 D t + offset, to the 6
  // printed digits (plus 1e-6 um^2 for an offset near 0).
  const auto msd = columns(dir / "msd.csv");
  const auto summary = nlohmann::json::parse(slurp(dir / "summary.json"));
  const double d = summary["brownian"]["D_um2_per_s"].get<double>(), offset = summary["brownian"]["msd_offset_um2"].get<double>();
  const double expected = 4 * kBrownianD * 1e12 * kBrownianDt * (1 - 1.0 / 40);  // um^2
  ASSERT_FALSE(msd.at("lag_s").empty());
  EXPECT_NEAR(msd.at("lag_s")[0], kBrownianDt, 1e-9);
  EXPECT_NEAR(msd.at("msd_um2")[0], expected, 3 * msd.at("se_um2")[0]) << "se " << msd.at("se_um2")[0];
  EXPECT_LT(msd.at("se_um2")[0], 0.1 * expected);
  for (std::size_t i = 0; i < msd.at("lag_s").size(); ++i) {
    const double fit = 4 * d * msd.at("lag_s")[i] + offset;
    EXPECT_NEAR(msd.at("fit_um2")[i], fit, 1e-5 * std::abs(fit) + 1e-6) << "lag " << msd.at("lag_s")[i];
  }
}

TEST(OutputDocs, TrackerSummaryHasTheDocumentedFields) {
  const fs::path flow = trackOutputs("docs-summary-flow", flowRun(), 1e-6, 10);
  const fs::path brownian = trackOutputs("docs-summary-brownian", brownianRun(), 0.5e-6, 1 / kBrownianDt);
  const auto a = nlohmann::json::parse(slurp(flow / "summary.json")), b = nlohmann::json::parse(slurp(brownian / "summary.json"));
  // The first six documented fields come from the tracking-video kind, not from the writer.
  expectFields("summary.json", {a, b}, {"input", "pixel_size_um", "fps", "scores", "background", "detection"});
  // Both runs were made by hand: 3 moving tracks and 1 still one; 40 Brownian tracks.
  EXPECT_EQ(a["tracks"], 4);
  EXPECT_EQ(a["immobile"], 1);
  EXPECT_EQ(b["tracks"], 40);
}

TEST(OutputDocs, ForcesCsvHasTheDocumentedColumns) {
  simulate::ForceHistory h;
  h.add(0.0, 3.1, 0.0);
  h.add(0.01, 3.2, -0.25);
  const fs::path dir = mmval::test::scratch("docs-forces");
  fs::create_directories(dir);
  h.writeCsv(dir / "forces.csv");
  expectColumns(dir / "forces.csv");
  // 9 significant digits: the values come back exactly.
  const auto c = columns(dir / "forces.csv");
  EXPECT_DOUBLE_EQ(c.at("c_D")[1], 3.2);
  EXPECT_DOUBLE_EQ(c.at("c_L")[1], -0.25);
}

TEST(OutputDocs, PermeabilityCsvHasTheDocumentedColumns) {
  // The writer of every kind's permeability.csv (OutputTablesTest runs the kinds).
  const fs::path dir = mmval::test::scratch("docs-permeability");
  fs::create_directories(dir);
  std::ofstream(dir / "permeability.csv") << tables::permeabilityHeader() << tables::formatRow(tables::PermeabilityRow{0, 0.0, 1e-12, 1.0, 50.0, 0, 0});
  expectColumns(dir / "permeability.csv");
}

TEST(OutputDocs, ComparisonRetentionHasTheDocumentedColumns) {
  // The same flow tracks on both sides: the two retained-fraction columns agree.
  const tracking::TrackRun run = flowRun();
  const compare::Comparison c = compare::compareTracks(run.tracks, run.tracks, compare::CompareOptions{});
  const fs::path dir = mmval::test::scratch("docs-compare");
  fs::remove_all(dir);
  compare::writeComparison(c, dir);
  expectColumns(dir / "retention_time.csv");
  expectColumns(dir / "dispersion_frames.csv");
  const auto r = columns(dir / "retention_time.csv");
  ASSERT_FALSE(r.at("t_s").empty());
  for (std::size_t i = 0; i < r.at("t_s").size(); ++i)
    if (!std::isnan(r.at("experiment")[i])) {
      EXPECT_DOUBLE_EQ(r.at("experiment")[i], r.at("simulation")[i]) << "t " << r.at("t_s")[i];
    }
  const auto metrics = nlohmann::json::parse(slurp(dir / "metrics.json"));
  EXPECT_EQ(metrics["schema"], "mmval-compare/1");
}

/// The fields every metric row of a metrics.json has (docs/outputs.md, "metrics.json":
/// result.json's metric fields, plus `case` and `solver` in mmval-metrics/1).
void expectMetricRows(const nlohmann::json& doc, bool gathered, const std::string& what) {
  std::vector<std::string> fields = {"name", "metric", "label", "unit", "dimension", "value", "reference", "error", "error_kind", "tolerance", "pass"};
  if (gathered) fields.insert(fields.end(), {"case", "solver"});
  ASSERT_TRUE(doc.contains("metrics") && doc["metrics"].is_array() && !doc["metrics"].empty()) << what;
  EXPECT_TRUE(doc["all_pass"].is_boolean()) << what;
  for (const auto& m : doc["metrics"])
    for (const auto& f : fields) EXPECT_TRUE(m.contains(f)) << what << ": metric '" << m.value("name", "?") << "' has no '" << f << "'";
}

TEST(OutputDocs, EveryMetricsJsonHasOneRowLayout) {
  // A comparison written by compare's writer, and a run beside it whose result.json holds
  // the same metric rows; the report gathers both and adds a metric it derives itself.
  const fs::path root = mmval::test::scratch("docs-metrics");
  fs::remove_all(root);
  const tracking::TrackRun run = flowRun();
  const compare::Comparison c = compare::compareTracks(run.tracks, run.tracks, compare::CompareOptions{});
  compare::writeComparison(c, root / "compare" / "same");
  const auto cmp = nlohmann::json::parse(slurp(root / "compare" / "same" / "metrics.json"));
  EXPECT_EQ(cmp["schema"], "mmval-compare/1");
  expectMetricRows(cmp, false, "compare's metrics.json");
  for (const char* block : {"experiment", "simulation"}) EXPECT_TRUE(cmp.contains(block)) << block;

  fs::create_directories(root / "runs" / "a");
  const nlohmann::json result = {{"schema", "mmval-result/1"},
                                 {"case", {{"name", "a"}, {"kind", "compare-tracks"}, {"hash", "0123456789abcdef"}, {"file", "a.toml"}, {"description", "-"}}},
                                 {"cost", {{"wall_seconds", 1.0}, {"peak_memory_bytes", 1.0}}},
                                 {"metrics", cmp["metrics"]},
                                 {"all_pass", cmp["all_pass"]},
                                 {"details", nlohmann::json::object()},
                                 {"files", nlohmann::json::array()},
                                 {"provenance", {{"mmval_version", "0"}, {"git_hash", "0"}, {"compiler", "-"}, {"build_type", "-"}, {"host", "-"}}}};
  std::ofstream(root / "runs" / "a" / "result.json") << result.dump(2);
  const reports::ReportInput input = reports::collect({root});
  ASSERT_EQ(input.comparisons.size(), 1u);
  const auto summary = input.summary.metricsJson();
  EXPECT_EQ(summary["schema"], "mmval-metrics/1");
  expectMetricRows(summary, true, "the summary's metrics.json");
  reports::writeReport(input, root / "report");
  const auto report = nlohmann::json::parse(slurp(root / "report" / "metrics.json"));
  EXPECT_EQ(report["schema"], "mmval-metrics/1");
  expectMetricRows(report, true, "the report's metrics.json");
  // The run's rows and the comparison's: the same metrics, told apart by `case`.
  std::map<std::string, int> per_case;
  for (const auto& m : report["metrics"]) ++per_case[m["case"].get<std::string>()];
  EXPECT_EQ(per_case["a"], static_cast<int>(cmp["metrics"].size()));
  EXPECT_EQ(per_case["compare:same"], static_cast<int>(cmp["metrics"].size()));
}

TEST(OutputDocs, ChipFilesHaveTheDocumentedColumnsAndFields) {
  const fs::path dir = mmval::test::scratch("docs-chip");
  fs::remove_all(dir);
  // ChipGeneratorTest's small chip (about a second).
  const auto o = mmval::test::runMmval("chip --length-mm 0.5 --width-mm 0.5 --pixel-size-um 2.5 --mean-grain-um 25 --ladder 1 --quiet --out " + dir.string());
  ASSERT_EQ(o.status, 0) << o.output;
  expectColumns(dir / "grain-sizes.csv");
  expectColumns(dir / "throat-sizes.csv");
  const auto chip = nlohmann::json::parse(slurp(dir / "chip.json"));
  // depth_fit: only with --depth-um fit; narrowest_spanning_throat: only when a path spans the chip.
  expectFields("chip.json", {chip}, {"depth_fit", "narrowest_spanning_throat"});
  // The grain histogram's counts add up to the grains.
  const auto grains = columns(dir / "grain-sizes.csv");
  double n = 0;
  for (double k : grains.at("count")) n += k;
  EXPECT_EQ(n, chip["grains"]["count"].get<double>());
}

/// A physics check's bundled case, made small with --set (each run about a second), and the
/// files it writes.
struct PhysicsRun {
  const char* name;  ///< cases/<name>.toml
  std::vector<std::string> set;
  std::vector<std::string> files;
};

std::ostream& operator<<(std::ostream& os, const PhysicsRun& r) { return os << r.name; }

class PhysicsFiles : public ::testing::TestWithParam<PhysicsRun> {};

TEST_P(PhysicsFiles, HaveTheDocumentedColumns) {
  const PhysicsRun& r = GetParam();
  const fs::path dir = mmval::test::scratch(std::string("docs-") + r.name);
  fs::remove_all(dir);
  std::string args = "run --quiet " + (fs::path(MMVAL_SOURCE_DIR) / "cases" / (std::string(r.name) + ".toml")).string() + " --out " + dir.string();
  for (const auto& kv : r.set) args += " --set '" + kv + "'";
  const auto o = mmval::test::runMmval(args);
  // 3: a metric outside its tolerance, expected of such small runs; the files are written.
  ASSERT_TRUE(o.status == 0 || o.status == 3) << o.output;
  for (const auto& f : r.files) {
    expectColumns(dir / f);
    EXPECT_GT(columns(dir / f).begin()->second.size(), 0u) << f << ": no rows";
  }
}

INSTANTIATE_TEST_SUITE_P(
    EveryCheck, PhysicsFiles,
    ::testing::Values(PhysicsRun{"physics-blocking", {"run.attempted_coverage=0.2"}, {"coverage.csv", "deposits.csv"}},
                      PhysicsRun{"physics-collector-interception", {"sweep.interception=[0.1]"}, {"collector-interception.csv"}},
                      PhysicsRun{"physics-collector-diffusion", {"particles.count=100", "sweep.peclet=[200, 600]"}, {"collector-diffusion.csv"}},
                      PhysicsRun{"physics-diffusion-slit", {"particles.count=50", "analysis.mu=[0.05]"}, {"diffusion-penetration.csv"}},
                      PhysicsRun{"physics-dlvo", {}, {"dlvo-profile.csv", "attachment-vs-ionic-strength.csv"}},
                      PhysicsRun{"physics-near-wall-shear", {}, {"near-wall-shear.csv"}},
                      PhysicsRun{"physics-hindered-diffusion", {"release.particles=2000", "release.heights=[1.5431, 10.0677]"}, {"hindered_diffusion.csv"}},
                      PhysicsRun{"physics-sedimentation-equilibrium", {"particles.count=20", "run.duration=40 s", "run.equilibration=5 s"},
                                 {"height_histogram.csv"}},
                      PhysicsRun{"physics-settling-slit", {"particles.count=10", "analysis.points=5"}, {"settling-deposition.csv", "settling-particles.csv"}}),
    [](const auto& info) {
      std::string n = info.param.name;
      for (char& ch : n)
        if (ch == '-') ch = '_';
      return n;
    });

TEST(OutputDocs, EveryDocumentedTableIsCheckedHere) {
  // The tables of docs/outputs.md the tests above write; a new table needs its writer above.
  const std::set<std::string> checked = {"retention.csv", "permeability.csv", "detections.csv", "track_summary.csv", "velocities.csv",
                                         "dispersion.csv", "msd.csv", "speed_time.csv", "track_diffusion.csv", "van_hove.csv",
                                         "diffusion_histogram.csv", "summary.json", "forces.csv", "grain-sizes.csv", "throat-sizes.csv",
                                         "chip.json", "retention_time.csv", "dispersion_frames.csv", "coverage.csv", "deposits.csv", "collector-interception.csv",
                                         "collector-diffusion.csv", "diffusion-penetration.csv", "dlvo-profile.csv",
                                         "attachment-vs-ionic-strength.csv", "near-wall-shear.csv", "hindered_diffusion.csv",
                                         "height_histogram.csv", "settling-deposition.csv", "settling-particles.csv"};
  std::set<std::string> listed;
  for (const auto& [file, table] : documentedTables()) listed.insert(file);
  EXPECT_EQ(listed, checked);
}

}  // namespace
}  // namespace mmval
