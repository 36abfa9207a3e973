// The contract of retention.csv and permeability.csv (mmval/core/OutputTables.hpp):
// the headers the writer emits are the ones docs/outputs.md lists, and every kind
// that writes them (particles-channel, -micromodel, -resolved, the tracker) writes
// that header with rows that keep the schema's invariants.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/particles/Kinds.hpp"
#include "mmval/tracking/Pipeline.hpp"

#include "../TestScratch.hpp"

namespace mmval {
namespace {

namespace fs = std::filesystem;

/// 1 darcy in m2 (NIST SP 811, 2008, Appendix B.8), written here independently of the writer's constant.
constexpr double kDarcyM2 = 9.869233e-13;
/// The writer prints 9 significant digits: a ratio of two printed numbers is exact to ~1e-8 relative.
constexpr double kPrinted = 2e-8;

std::string slurp(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The (column, unit) rows of the table under the heading "### `<file>`" of docs/outputs.md.
std::vector<std::pair<std::string, std::string>> documentedColumns(const std::string& file) {
  const std::string doc = slurp(fs::path(MMVAL_SOURCE_DIR) / "docs" / "outputs.md");
  const std::size_t at = doc.find("### `" + file + "`");
  if (at == std::string::npos) return {};
  std::istringstream in(doc.substr(at));
  std::string line;
  std::getline(in, line);
  std::vector<std::pair<std::string, std::string>> cols;
  const std::regex row(R"(^\| `([A-Za-z0-9_]+)` \| ([^|]+?) \|)");
  while (std::getline(in, line) && !line.starts_with("#")) {
    std::smatch m;
    if (std::regex_search(line, m, row)) cols.emplace_back(m[1], m[2]);
  }
  return cols;
}

void expectDocumented(const std::string& file, const std::vector<tables::Column>& schema, const std::string& header) {
  const auto doc = documentedColumns(file);
  ASSERT_EQ(doc.size(), schema.size()) << file << ": docs/outputs.md lists " << doc.size() << " columns, the writer " << schema.size();
  std::string joined;
  for (std::size_t i = 0; i < doc.size(); ++i) {
    EXPECT_EQ(doc[i].first, schema[i].name) << file << " column " << i;
    EXPECT_EQ(doc[i].second, schema[i].unit) << file << " unit of " << doc[i].first;
    joined += (i ? "," : "") + doc[i].first;
  }
  EXPECT_EQ(joined + "\n", header) << file;
}

TEST(OutputTables, HeadersAreTheOnesTheDocsList) {
  expectDocumented("retention.csv", tables::retentionColumns(), tables::retentionHeader());
  expectDocumented("permeability.csv", tables::permeabilityColumns(), tables::permeabilityHeader());
}

TEST(OutputTables, WriterRefusesUnbalancedCountsAndFillsDerivedColumns) {
  EXPECT_THROW(tables::formatRow(tables::RetentionRow{0, 0.0, 5, 1, 1, 1}), std::logic_error);
  EXPECT_EQ(tables::formatRow(tables::RetentionRow{3, 0.3, 8, 1, 2, 5}), "3,0.3,8,1,2,5,0.25\n");
  EXPECT_EQ(tables::formatRow(tables::RetentionRow{0, 0.0, 0, 0, 0, 0}), "0,0,0,0,0,0,0\n");
  // 1 D = 9.869233e-13 m2; no flow path: an empty pressure drop.
  EXPECT_EQ(tables::formatRow(tables::PermeabilityRow{1, 0.5, 2 * kDarcyM2, 0.5, 120.0, 4, 2}), "1,0.5,1.9738466e-12,2,0.5,120,4,2\n");
  EXPECT_EQ(tables::formatRow(tables::PermeabilityRow{2, 1.0, 0.0, 0.0, INFINITY, 9, 3}), "2,1,0,0,0,,9,3\n");
  const auto cols = tables::parseTable(tables::permeabilityHeader() + "2,1,0,0,0,,9,3\n", "test");
  EXPECT_TRUE(std::isnan(cols.at("pressure_drop_pa")[0]));
  EXPECT_THROW(tables::parseTable("a,b\n1,x\n", "test"), std::runtime_error);
}

/// Checks a retention.csv: the schema's header, balanced counts, the fraction, frames in order.
/// Returns the columns.
tables::TableColumns checkRetention(const fs::path& file) {
  const std::string text = slurp(file);
  EXPECT_EQ(text.substr(0, text.find('\n') + 1), tables::retentionHeader()) << file;
  const tables::TableColumns c = tables::parseTable(text, file.string());
  const std::size_t n = c.at("t_s").size();
  EXPECT_GT(n, 1u) << file;
  for (std::size_t i = 0; i < n; ++i) {
    const double inj = c.at("injected")[i], ret = c.at("retained")[i];
    EXPECT_EQ(inj, c.at("inside")[i] + ret + c.at("left")[i]) << file << " row " << i;
    EXPECT_GE(c.at("inside")[i], 0) << file << " row " << i;
    EXPECT_NEAR(c.at("retained_fraction")[i], inj > 0 ? ret / inj : 0.0, kPrinted) << file << " row " << i;
    if (i > 0) {
      EXPECT_EQ(c.at("frame")[i], c.at("frame")[i - 1] + 1) << file << " row " << i;
      EXPECT_GT(c.at("t_s")[i], c.at("t_s")[i - 1]) << file << " row " << i;
      EXPECT_GE(ret, c.at("retained")[i - 1]) << file << " row " << i << ": retained is for good";
    }
  }
  return c;
}

/// Checks a permeability.csv: header, k_D, k/k0 against one k0, Darcy's law dp k = const, counts.
tables::TableColumns checkPermeability(const fs::path& file) {
  const std::string text = slurp(file);
  EXPECT_EQ(text.substr(0, text.find('\n') + 1), tables::permeabilityHeader()) << file;
  const tables::TableColumns c = tables::parseTable(text, file.string());
  const auto& k = c.at("k_m2");
  const auto& ratio = c.at("k_over_k0");
  const auto& dp = c.at("pressure_drop_pa");
  EXPECT_GT(k.size(), 1u) << file;
  const double k0 = k[0] / ratio[0], darcy = dp[0] * k[0];
  for (std::size_t i = 0; i < k.size(); ++i) {
    EXPECT_NEAR(c.at("k_D")[i], k[i] / kDarcyM2, kPrinted * k[i] / kDarcyM2) << file << " row " << i;
    if (k[i] > 0) {
      EXPECT_NEAR(ratio[i], k[i] / k0, kPrinted * ratio[i]) << file << " row " << i;
      EXPECT_NEAR(dp[i] * k[i], darcy, 3 * kPrinted * darcy) << file << " row " << i << ": Darcy, dp = mu u L / k";
    } else {
      EXPECT_TRUE(std::isnan(dp[i])) << file << " row " << i << ": no flow path, no pressure drop";
    }
    if (i > 0) {
      EXPECT_GE(c.at("deposited")[i], c.at("deposited")[i - 1]) << file << " row " << i;
      EXPECT_GE(c.at("resolves")[i], c.at("resolves")[i - 1]) << file << " row " << i;
    }
  }
  return c;
}

fs::path writePgm(const fs::path& file, int w, int h, const std::function<bool(int, int)>& grain) {
  std::ofstream f(file, std::ios::binary);
  f << "P5\n" << w << " " << h << "\n255\n";
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) f.put(static_cast<char>(grain(c, r) ? 0 : 255));
  return file;
}

/// One kind's small run, as the kind's own tests run it.
struct KindCase {
  const char* name;
  std::function<std::string(const fs::path& dir)> text;
  bool retention, permeability;
};

std::ostream& operator<<(std::ostream& os, const KindCase& k) { return os << k.name; }

class KindTables : public ::testing::TestWithParam<KindCase> {};

TEST_P(KindTables, FilesFollowTheSchema) {
  CaseKindRegistry reg;
  particles::registerParticleKinds(reg);
  const KindCase& k = GetParam();
  const fs::path dir = mmval::test::scratch(std::string("tables-") + k.name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Case c = Case::parse(k.text(dir), dir / "case.toml", reg);
  RunContext ctx;
  ctx.out_dir = dir / "out";
  ctx.quiet = true;
  fs::create_directories(ctx.out_dir);
  const RunOutput out = reg.find(c.kind())->run(c, ctx);
  if (k.retention) {
    const auto r = checkRetention(ctx.out_dir / "retention.csv");
    // The last row is the run's final count (the kinds name the retained count "retained" or "deposited").
    EXPECT_EQ(r.at("retained").back(), out.metrics.count("retained") ? out.metrics.at("retained") : out.metrics.at("deposited"));
    EXPECT_EQ(r.at("injected").back(), r.at("inside").back() + out.metrics.at("left") + r.at("retained").back());
    EXPECT_EQ(r.at("left").back(), out.metrics.at("left"));
    EXPECT_EQ(r.at("inside").back(), out.metrics.at("inside"));
  }
  if (k.permeability) {
    const auto p = checkPermeability(ctx.out_dir / "permeability.csv");
    EXPECT_NEAR(p.at("k_over_k0").back(), out.metrics.at("k_over_k0"), kPrinted);
    if (k.retention) {
      EXPECT_EQ(p.at("deposited"), checkRetention(ctx.out_dir / "retention.csv").at("retained"));
    }
  }
}

std::string channelCase(const fs::path&) {
  return "[case]\nname = \"t\"\nkind = \"particles-channel\"\n[channel]\nlength = \"300 um\"\nwidth = \"100 um\"\n"
         "[particles]\ncount = 30\ninjection_time = \"0.2 s\"\n[run]\nduration = \"0.6 s\"\noutput_interval = \"0.02 s\"\n";
}

/// A 60 x 10 px chip with a 4 px throat that deposits clog (BookkeepingTest's scene, shorter):
/// deposits, re-solves and, at the end, no flow path.
std::string micromodelCase(const fs::path& dir) {
  const fs::path mask = writePgm(dir / "throat.pgm", 60, 10, [](int c, int r) { return c >= 28 && c < 32 && (r < 3 || r >= 7); });
  return "[case]\nname = \"t\"\nkind = \"particles-micromodel\"\n"
         "[geometry]\nmask = \"" + mask.filename().string() + "\"\npixel_size = \"5 um\"\ndepth = \"20 um\"\n"
         "[flow]\nrate = \"5 uL/min\"\nrate_width = \"10 mm\"\n"
         "[particles]\ndiameter = \"5 um\"\ncount = 200\ninjection_time = \"4 s\"\nsample_fraction = 0.3\n"
         "[coupling]\nresolve_threshold = 1e-3\n[numerics]\ncells_per_pixel = 0.5\n"
         "[run]\nduration = \"4 s\"\noutput_interval = \"0.05 s\"\nseed = 3\ncheckpoint_every = 0\n";
}

/// ResolvedCaseTest's grain channel: a disk meets a fixed obstacle and sticks there.
std::string resolvedCase(const fs::path&) {
  return "[case]\nname = \"t\"\nkind = \"particles-resolved\"\n[channel]\nlength = \"80 um\"\nwidth = \"40 um\"\nmean_velocity = \"0.05 mm/s\"\n"
         "[particles]\ndiameter = \"8 um\"\nx = [\"15 um\"]\ny = [\"20 um\"]\n"
         "[obstacles]\nx = [\"45 um\"]\ny = [\"20 um\"]\ndiameter = [\"12 um\"]\n[deposition]\ncapture_distance = \"0.5 um\"\n"
         "[numerics]\ncells_per_diameter = 8\nmax_step_fraction = 1.0\n[run]\nduration = \"2 s\"\noutput_interval = \"0.5 s\"\n";
}

INSTANTIATE_TEST_SUITE_P(EveryKind, KindTables,
                         ::testing::Values(KindCase{"channel", channelCase, true, false}, KindCase{"micromodel", micromodelCase, true, true},
                                           KindCase{"resolved", resolvedCase, true, true}),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(OutputTables, ResolvedCleanChannelPermeabilityIsPoiseuille) {
  // Plane Poiseuille flow between walls W apart: dp = 12 mu U L / W^2, so k0 = mu U L / dp0 = W^2 / 12.
  CaseKindRegistry reg;
  particles::registerParticleKinds(reg);
  const fs::path dir = mmval::test::scratch("tables-poiseuille");
  fs::remove_all(dir);
  fs::create_directories(dir / "out");
  const std::string text = "[case]\nname = \"t\"\nkind = \"particles-resolved\"\n[channel]\nlength = \"80 um\"\nwidth = \"40 um\"\n"
                           "mean_velocity = \"0.05 mm/s\"\n[particles]\ndiameter = \"8 um\"\nx = [\"15 um\"]\ny = [\"20 um\"]\n"
                           "[numerics]\ncells_per_diameter = 8\nmax_step_fraction = 1.0\n[run]\nduration = \"0.5 s\"\noutput_interval = \"0.5 s\"\n";
  const Case c = Case::parse(text, dir / "case.toml", reg);
  RunContext ctx;
  ctx.out_dir = dir / "out";
  ctx.quiet = true;
  reg.find("particles-resolved")->run(c, ctx);
  const auto p = checkPermeability(ctx.out_dir / "permeability.csv");
  const double k0 = p.at("k_m2")[0] / p.at("k_over_k0")[0], W = 40e-6;
  // Measured 1.3350e-10 m2 (+0.13 %) with 1 um cells (8 per 8 um diameter, 40 across W);
  // 0.5 %: the discretisation error of the pressure next to the inflow face, with margin.
  EXPECT_NEAR(k0, W * W / 12, 0.005 * W * W / 12) << "k0 " << k0 << " m2 against W^2/12 = " << W * W / 12 << " m2";
}

/// A tracked flow video, made by hand: 30 frames at 10 fps, 1 um pixels. Particle 1 crosses
/// the view; 2 enters at frame 3 and stops for good at frame 8 (labelled deposited from there,
/// as the tracker labels a resting end); 3 enters at frame 5 and is last seen at frame 15;
/// 4 sits still all along (immobile, no particle the flow brought).
tracking::TrackRun handMadeRun() {
  tracking::TrackRun run;
  auto add = [&](std::int64_t id, int f, double x_px, double y_px, const char* state) {
    TrackPoint q;
    q.frame = f;
    q.particle = id;
    q.t = f / 10.0;
    q.x_px = x_px;
    q.y_px = y_px;
    q.x = x_px * 1e-6;
    q.y = y_px * 1e-6;
    q.state = state;
    run.tracks.points.push_back(q);
  };
  for (int f = 0; f < 30; ++f) add(1, f, 5 + 5 * f, 20, "mobile");
  for (int f = 3; f < 30; ++f) add(2, f, 5 + 6 * std::min(f - 3, 5), 40, f >= 8 ? "deposited" : "mobile");
  for (int f = 5; f <= 15; ++f) add(3, f, 5 + 8 * (f - 5), 60, "mobile");
  for (int f = 0; f < 30; ++f) add(4, f, 100, 80, "immobile");
  for (int f = 0; f < 30; ++f) run.frame_index.push_back(f);
  return run;
}

TEST(OutputTables, TrackerRetentionCountsTracksThatEnteredTheView) {
  tracking::TrackConfig cfg;
  cfg.pixel_size = 1e-6;
  cfg.fps = 10;
  cfg.analysis.motion = tracking::MotionModel::flow;
  const fs::path dir = mmval::test::scratch("tables-tracker");
  fs::remove_all(dir);
  tracking::writeTrackOutputs(handMadeRun(), cfg, dir, nlohmann::json::object());
  ASSERT_FALSE(fs::exists(dir / "retention_time.csv")) << "folded into retention.csv";
  const auto r = checkRetention(dir / "retention.csv");
  ASSERT_EQ(r.at("frame").size(), 30u);
  // By hand: injected 1 (frames 0-2), 2 (3-4), 3 (5 on); retained from frame 8; left from frame 16.
  for (int f = 0; f < 30; ++f) {
    EXPECT_EQ(r.at("injected")[f], f < 3 ? 1 : f < 5 ? 2 : 3) << "frame " << f;
    EXPECT_EQ(r.at("retained")[f], f < 8 ? 0 : 1) << "frame " << f;
    EXPECT_EQ(r.at("left")[f], f < 16 ? 0 : 1) << "frame " << f;
    EXPECT_NEAR(r.at("t_s")[f], f / 10.0, 1e-12) << "frame " << f;
  }
  // The totals the old summary table held are in summary.json.
  const auto summary = nlohmann::json::parse(slurp(dir / "summary.json"));
  EXPECT_EQ(summary["tracks"], 4);
  EXPECT_EQ(summary["immobile"], 1);
  EXPECT_EQ(summary["mobile"], 3);
  EXPECT_EQ(summary["retained"], r.at("retained").back());
}

}  // namespace
}  // namespace mmval
