// The report as a site: a summary page with failures first and one line per
// case, a page per case with its metrics, figures, case file and links, a
// provenance block on every page, comparisons named by their inputs, colour
// bars on field images, a CSV behind every plot, and every link resolving.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include <fmt/format.h>

#include "mmval/core/VtkWriter.hpp"
#include "mmval/reports/Plot.hpp"
#include "mmval/reports/Report.hpp"
#include "mmval/reports/Site.hpp"

#include "../TestScratch.hpp"

namespace mmval::reports {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;
using ::testing::Not;

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  std::stringstream b;
  b << in.rdbuf();
  return b.str();
}

nlohmann::json metric(const std::string& name, double value, const std::string& unit, nlohmann::json reference = nullptr, nlohmann::json pass = nullptr,
                      const std::string& source = {}) {
  nlohmann::json m{{"name", name}, {"value", value}, {"unit", unit}, {"reference", reference}, {"error", nullptr}, {"error_kind", "relative"},
                   {"tolerance", pass.is_null() ? nlohmann::json(nullptr) : nlohmann::json("5 %")}, {"pass", pass}};
  if (reference.is_number()) m["error"] = value / reference.get<double>() - 1;
  if (!source.empty()) m["source"] = source;
  return m;
}

/// `m` with the typed fields of a metric judged against a reference of a declared setting.
nlohmann::json typed(nlohmann::json m, const std::string& metric, const std::string& label, const std::string& setup) {
  m["metric"] = metric;
  m["label"] = label;
  m["reference_setup"] = setup;
  return m;
}

/// A result.json as `mmval run` writes it (reduced), with a case file beside the runs.
void fakeRun(const fs::path& root, const std::string& name, const std::string& kind, nlohmann::json metrics, nlohmann::json details = nlohmann::json::object(),
             nlohmann::json files = nlohmann::json::array(), nlohmann::json resolved = nullptr) {
  const fs::path dir = root / "runs" / name;
  fs::create_directories(dir);
  fs::create_directories(root / "cases");
  std::ofstream(root / "cases" / (name + ".toml")) << "[case]\nname = \"" << name << "\"\nkind = \"" << kind << "\"\n";
  bool all = true;
  for (const auto& m : metrics)
    if (m["pass"].is_boolean() && !m["pass"].get<bool>()) all = false;
  nlohmann::json r{{"schema", "mmval-result/1"},
                   {"case", {{"name", name}, {"kind", kind}, {"hash", "0123456789abcdef"}, {"file", (root / "cases" / (name + ".toml")).string()}, {"description", "a test case"}}},
                   {"cost", {{"wall_seconds", 1.5}, {"peak_memory_bytes", 1048576.0}}},
                   {"metrics", metrics},
                   {"all_pass", all},
                   {"details", details},
                   {"files", files},
                   {"provenance",
                    {{"mmval_version", "0.1.0"}, {"git_hash", "abc123def456-dirty"}, {"compiler", "GNU 12.2.0"}, {"build_type", "Release"}, {"host", "testhost"},
                     {"finished_utc", "2026-01-02T03:04:05Z"}, {"dependencies", {{"opencv", "4.6.0"}, {"petsc", "3.18.5"}}}}}};
  if (!resolved.is_null()) r["resolved_case"] = resolved;
  std::ofstream(dir / "result.json") << r.dump(2);
}

/// A 2 x 1 cell ASCII .vtr whose largest cell speed is 5 m/s.
void fakeVtr(const fs::path& file) {
  std::ofstream(file) << "<?xml version=\"1.0\"?>\n<VTKFile type=\"RectilinearGrid\"><RectilinearGrid WholeExtent=\"0 2 0 1 0 0\"><Piece Extent=\"0 2 0 1 0 0\">"
                         "<CellData Scalars=\"p\" Vectors=\"U\"><DataArray type=\"Float64\" Name=\"p\" format=\"ascii\">1 2</DataArray>"
                         "<DataArray type=\"Float64\" Name=\"U\" NumberOfComponents=\"3\" format=\"ascii\">1 0 0 3 4 0</DataArray></CellData>"
                         "</Piece></RectilinearGrid></VTKFile>\n";
}

/// A 4 x 4 PNG (written as raw bytes of a valid file).
void fakePng(const fs::path& file) {
  static const unsigned char png[] = {0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a, 0x00, 0x00, 0x00, 0x0d, 0x49, 0x48, 0x44, 0x52, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00,
                                      0x00, 0x01, 0x08, 0x02, 0x00, 0x00, 0x00, 0x90, 0x77, 0x53, 0xde, 0x00, 0x00, 0x00, 0x0c, 0x49, 0x44, 0x41, 0x54, 0x08, 0xd7, 0x63,
                                      0xf8, 0xcf, 0xc0, 0x00, 0x00, 0x03, 0x01, 0x01, 0x00, 0x18, 0xdd, 0x8d, 0xb0, 0x00, 0x00, 0x00, 0x00, 0x49, 0x45, 0x4e, 0x44, 0xae,
                                      0x42, 0x60, 0x82};
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(png), sizeof png);
}

/// A validation folder: a failing and a passing cylinder run, a confined benchmark, a
/// field image with its .vtr, a rendered-video tracking run and the pipeline check on it.
fs::path buildFixture(const std::string& name) {
  const fs::path root = mmval::test::scratch(name);  // per process: ctest runs each test of this suite as its own process, in parallel
  fs::remove_all(root);
  const std::string dc = "S. C. R. Dennis, G.-Z. Chang (1970). J. Fluid Mech. 42(3), 471-489., doi:10.1017/S0022112070001428";
  fakeRun(root, "cyl-re20", "cylinder-channel", nlohmann::json::array({typed(metric("c_D (Dennis & Chang)", 2.12, "1", 2.045, true, dc), "c_D", "Dennis & Chang", "unbounded-cylinder")}), {{"Re", 20.0}},
          nlohmann::json::array({"fields.vtr", "fields-speed.png"}));
  fakeVtr(root / "runs" / "cyl-re20" / "fields.vtr");
  fakePng(root / "runs" / "cyl-re20" / "fields-speed.png");
  fakeRun(root, "cyl-re40", "cylinder-channel", nlohmann::json::array({typed(metric("c_D (Dennis & Chang)", 1.9, "1", 1.522, false, dc), "c_D", "Dennis & Chang", "unbounded-cylinder")}), {{"Re", 40.0}});
  fakeRun(root, "st-2d1", "cylinder-channel", nlohmann::json::array({typed(metric("c_D", 5.58, "1", 5.58, true), "c_D", "", "confined-channel-cylinder")}), {{"Re", 20.0}});
  fakeRun(root, "zz-info-only", "channel", nlohmann::json::array({metric("flow_rate", 1.0, "m^2/s")}));
  fakeRun(root, "rendered", "tracking-rendered", nlohmann::json::array(), nlohmann::json::object(), nlohmann::json::array(),
          {{"inputs", {{"trajectories_run", "scene"}}}});
  const nlohmann::json compared =
      nlohmann::json::array({metric("mean_speed", 478.9, "um/s", 487.9, true, "experiment tracks"), metric("speed_ks_p_value", 7.9e-109, "1")});
  fakeRun(root, "pipeline", "compare-tracks", compared, {{"experiment", {{"steps", 67174}}}}, nlohmann::json::array({"metrics.json", "mean_speed_time_um_per_s.csv"}),
          {{"inputs", {{"experiment_run", "rendered"}, {"simulation_run", "scene"}}}});
  // compare's own files in the pipeline run's folder (as `mmval validate` writes them).
  const nlohmann::json cmp{{"schema", "mmval-compare/1"}, {"metrics", compared}, {"all_pass", true}};
  std::ofstream(root / "runs" / "pipeline" / "metrics.json") << cmp.dump(2);
  {
    std::ofstream f(root / "runs" / "pipeline" / "mean_speed_time_um_per_s.csv");
    f << "t_s,experiment,simulation\n0.5,480,470\n1.5,490,480\n";
  }
  return root;
}

/// Rows of the summary's case table, in order: (result, case).
std::vector<std::pair<std::string, std::string>> summaryRows(const std::string& html) {
  std::vector<std::pair<std::string, std::string>> rows;
  const std::string table = html.substr(html.find("<table id=\"cases\">"));
  static const std::regex row(R"re(<tr class="(\w+)"><td>\w+</td><td class="l"><a href="cases/[^"]+">([^<]+)</a>)re");
  for (auto it = std::sregex_iterator(table.begin(), table.begin() + static_cast<long>(table.find("</table>")), row); it != std::sregex_iterator(); ++it)
    rows.emplace_back((*it)[1].str(), (*it)[2].str());
  return rows;
}

class ReportSite : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    root_ = buildFixture("report-site");
    writeReport(collect({root_}), root_ / "report");
  }
  static fs::path root_;
  static fs::path report() { return root_ / "report"; }
};
fs::path ReportSite::root_;

TEST_F(ReportSite, EveryLinkOfEveryPageResolves) {
  const auto broken = brokenLinks(report());
  EXPECT_TRUE(broken.empty()) << ::testing::PrintToString(broken);
  // The pages the links go to exist: summary, cross-case page, one page per run.
  for (const char* page : {"index.html", "paper.html", "cases/cyl-re20.html", "cases/cyl-re40.html", "cases/st-2d1.html", "cases/pipeline.html", "cases/rendered.html",
                           "cases/zz-info-only.html"})
    EXPECT_TRUE(fs::exists(report() / page)) << page;
}

TEST_F(ReportSite, SummaryListsFailuresFirstOneLinePerCase) {
  const auto rows = summaryRows(slurp(report() / "index.html"));
  ASSERT_EQ(rows.size(), 6u);
  EXPECT_EQ(rows[0], std::make_pair(std::string("FAIL"), std::string("cyl-re40")));
  for (std::size_t i = 1; i < 4; ++i) EXPECT_EQ(rows[i].first, "pass") << rows[i].second;
  EXPECT_EQ(rows[4].first, "info");
  EXPECT_EQ(rows[5].first, "info");
  // The failing metric links to its row on the case page.
  EXPECT_THAT(slurp(report() / "index.html"), HasSubstr("href=\"cases/cyl-re40.html#metric-c_D (Dennis &amp; Chang)\""));
}

TEST_F(ReportSite, EveryPageCarriesTheProvenanceBlock) {
  int pages = 0;
  for (const auto& e : fs::recursive_directory_iterator(report())) {
    if (e.path().extension() != ".html") continue;
    ++pages;
    const std::string html = slurp(e.path());
    EXPECT_THAT(html, HasSubstr("id=\"provenance\"")) << e.path();
    EXPECT_THAT(html, HasSubstr("abc123def456")) << e.path();
    EXPECT_THAT(html, HasSubstr("yes (uncommitted changes)")) << e.path();
    EXPECT_THAT(html, HasSubstr("<th>OpenCV</th><td>4.6.0</td>")) << e.path();
    EXPECT_THAT(html, HasSubstr("<th>PETSc</th><td>3.18.5</td>")) << e.path();
    EXPECT_THAT(html, HasSubstr("<th>LIGGGHTS</th><td class=\"missing\">not recorded</td>")) << e.path();
    EXPECT_THAT(html, HasSubstr("<th>host</th><td>testhost</td>")) << e.path();
  }
  EXPECT_EQ(pages, 8);
}

TEST_F(ReportSite, CasePageHasMetricsFiguresCaseFileAndLinks) {
  const std::string html = slurp(report() / "cases" / "cyl-re20.html");
  EXPECT_THAT(html, HasSubstr("id=\"metric-c_D (Dennis &amp; Chang)\""));
  EXPECT_THAT(html, HasSubstr("2.045 (-)"));  // the unit on the reference side too
  EXPECT_THAT(html, HasSubstr("<a href=\"https://doi.org/10.1017/S0022112070001428\">"));
  EXPECT_THAT(html, HasSubstr("href=\"../../runs/cyl-re20/\""));
  EXPECT_THAT(html, HasSubstr("href=\"../../runs/cyl-re20/fields.vtr\""));
  EXPECT_THAT(html, HasSubstr("href=\"cyl-re20.toml\""));
  EXPECT_THAT(html, HasSubstr("<pre id=\"case-file\">[case]"));
  EXPECT_EQ(slurp(report() / "cases" / "cyl-re20.toml"), slurp(root_ / "cases" / "cyl-re20.toml"));
  // The field image with its colour bar: 0 to the .vtr's largest speed, 5 m/s.
  EXPECT_THAT(html, HasSubstr("class=\"cbar\""));
  EXPECT_THAT(html, HasSubstr("5 m/s"));
  EXPECT_THAT(html, HasSubstr("src=\"../figures/cyl-re20-fields-speed.png\""));
  EXPECT_THAT(html, HasSubstr("[data: <a href=\"../../runs/cyl-re20/fields.vtr\">fields (.vtr)</a>]"));
}

TEST_F(ReportSite, ComparisonsAreNamedByTheirInputs) {
  const std::string html = slurp(report() / "cases" / "pipeline.html");
  EXPECT_THAT(html, HasSubstr("Pipeline check"));
  EXPECT_THAT(html, HasSubstr("tracks of a rendered video of scene (run rendered)"));
  EXPECT_THAT(html, HasSubstr("simulated trajectories of scene"));
  EXPECT_THAT(html, Not(HasSubstr("Experiment vs simulation")));
  EXPECT_THAT(html, Not(HasSubstr("experiment tracks")));
  // The KS p-value says what it is worth.
  EXPECT_THAT(html, HasSubstr("67174 steps"));
  EXPECT_THAT(html, HasSubstr("as if the steps were independent"));
  EXPECT_THAT(slurp(report() / "index.html"), HasSubstr("Pipeline check (compare-tracks)"));
  EXPECT_THAT(slurp(report() / "report.md"), HasSubstr("## Pipeline check: pipeline"));
  EXPECT_THAT(slurp(report() / "report.md"), Not(HasSubstr("Experiment vs simulation")));
}

TEST_F(ReportSite, EveryPlotHasItsCsvAndTheDragPlotKeepsToOneSetUp) {
  if (!gnuplotAvailable()) GTEST_SKIP() << "no gnuplot";
  int svgs = 0;
  for (const auto& e : fs::directory_iterator(report() / "figures"))
    if (e.path().extension() == ".svg") {
      ++svgs;
      EXPECT_TRUE(fs::exists(fs::path(e.path()).replace_extension(".csv"))) << e.path();
    }
  EXPECT_GE(svgs, 2);
  // C_d against Re: the Table 1 set-up only; the confined benchmark (5.58) is named, not drawn.
  const std::string csv = slurp(report() / "figures" / "cd-vs-re.csv");
  EXPECT_THAT(csv, HasSubstr("2.12"));
  EXPECT_THAT(csv, Not(HasSubstr("5.58")));
  EXPECT_THAT(slurp(report() / "paper.html"), HasSubstr("Not on these axes (other set-ups, e.g. confined channels whose walls raise C_d): st-2d1"));
  EXPECT_THAT(slurp(report() / "paper.html"), HasSubstr("[data: <a href=\"figures/cd-vs-re.csv\">CSV</a>]"));
}

/// A 2 x 1 x 3 cell binary .vtr as simulate writes fields-3d.vtr: in the middle layer (k = 1) a
/// fluid cell at |U| = 2 m/s (0, 1.2, 1.6) and a solid cell whose U (9 m/s) is left out; the
/// layers above and below at 7 m/s.
void fakeVtr3d(const fs::path& file) {
  vtk::RectilinearGrid g;
  g.x = {0, 1e-6, 2e-6};
  g.y = {0, 1e-6};
  g.z = {0, 1e-6, 2e-6, 3e-6};
  const std::vector<double> u = {7, 0, 0, 0, 7, 0,  0, 1.2, 1.6, 9, 0, 0,  0, 0, 7, 7, 0, 0};
  g.cell_data = {vtk::Array::float64("U", "m/s", 3, u), vtk::Array::float32("solid", "1", 1, {0, 0, 0, 1, 0, 0}),
                 vtk::Array::float64("p", "Pa", 1, {0, 0, 0, 0, 0, 0})};
  vtk::writeVtr(file, g);
}

TEST(FieldImages, MidDepthPictureCarriesTheColourBarOfItsPlane) {
  const fs::path root = mmval::test::scratch("report-mid-depth");
  fs::remove_all(root);
  fakeRun(root, "chip3d", "image-permeability", nlohmann::json::array({metric("permeability", 2.0, "D")}), nlohmann::json::object(),
          nlohmann::json::array({"fields-3d.vtr", "fields-3d-middepth-speed.png", "tracks/speed_map.png", "tracks/streamlines.png"}));
  const fs::path run = root / "runs" / "chip3d";
  fakeVtr3d(run / "fields-3d.vtr");
  EXPECT_NEAR(maxSpeedOnMidDepthPlane(run / "fields-3d.vtr"), 2.0, 1e-12);
  EXPECT_TRUE(std::isnan(maxSpeedOnMidDepthPlane(run / "no-such.vtr")));
  fakePng(run / "fields-3d-middepth-speed.png");
  fs::create_directories(run / "tracks");
  fakePng(run / "tracks" / "speed_map.png");
  fakePng(run / "tracks" / "streamlines.png");
  std::ofstream(run / "tracks" / "velocities.csv") << "particle,t_s,x_um,y_um,vx_um_per_s,vy_um_per_s,speed_um_per_s\n";
  std::ofstream(run / "tracks" / "tracks.csv") << "frame,particle,x_um,y_um,t_s\n";
  writeReport(collect({root}), root / "report");
  const std::string html = slurp(root / "report" / "cases" / "chip3d.html");
  // The bar runs from 0 to the plane's 2 m/s (not the 7 m/s of the other layers, nor "not recorded").
  EXPECT_THAT(html, HasSubstr("speed |u| on the mid-depth plane (m/s)"));
  EXPECT_THAT(html, HasSubstr("<span>2 m/s</span>"));
  EXPECT_THAT(html, HasSubstr("<span>1 m/s</span>"));
  EXPECT_THAT(html, Not(HasSubstr("not recorded</span>")));
  EXPECT_THAT(html, HasSubstr("[data: <a href=\"../../runs/chip3d/fields-3d.vtr\">fields-3d (.vtr)</a>]"));
  EXPECT_THAT(html, HasSubstr("mid-depth plane of the 3D Stokes solve"));
  // The tracker's pictures say what they show and link the CSV they are drawn from.
  EXPECT_THAT(html, HasSubstr("tracks/speed_map.png (mean speed of the steps in each bin"));
  EXPECT_THAT(html, HasSubstr("[data: <a href=\"../../runs/chip3d/tracks/velocities.csv\">velocities.csv (CSV)</a>]"));
  EXPECT_THAT(html, HasSubstr("tracks/streamlines.png (tracks drawn over the background image"));
  EXPECT_THAT(html, HasSubstr("[data: <a href=\"../../runs/chip3d/tracks/tracks.csv\">tracks.csv (CSV)</a>]"));
  EXPECT_TRUE(brokenLinks(root / "report").empty()) << ::testing::PrintToString(brokenLinks(root / "report"));
}

TEST(BrokenLinks, FindsMissingFilesAndAnchors) {
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / "broken-links";
  fs::remove_all(dir);
  fs::create_directories(dir / "sub");
  std::ofstream(dir / "a.html") << "<a href=\"sub/b.html#here\">x</a><a href=\"sub/b.html#gone\">y</a><img src=\"missing.png\"><a href=\"https://doi.org/10.1/x\">d</a>"
                                  "<a href=\"#top\">t</a><p id=\"top\"></p><img src=\"data:image/png;base64,AA\"><a href=\"sub/a%20b.csv\">s</a>";
  std::ofstream(dir / "sub" / "a b.csv") << "x\n";
  std::ofstream(dir / "sub" / "b.html") << "<h2 id=\"here\">h</h2><a href=\"../a.html\">back</a>";
  EXPECT_THAT(brokenLinks(dir), ::testing::UnorderedElementsAre("a.html: sub/b.html#gone (no such anchor)", "a.html: missing.png"));
}

TEST(Provenance, DirtyFlagFromTheGitHashAndNotRecordedForTheRest) {
  const Provenance p = provenanceOf(nlohmann::json{{"provenance", {{"git_hash", "0123abc"}}}});
  EXPECT_EQ(p.git_hash, "0123abc");
  EXPECT_EQ(p.dirty, "no");
  EXPECT_EQ(p.opencv, "not recorded");
  EXPECT_EQ(p.openfoam, "not recorded");
  const Provenance q = provenanceOf(nlohmann::json{{"provenance", {{"git_hash", "0123abc-dirty"}}}, {"details", {{"solver", "openfoam v1912"}}}});
  EXPECT_EQ(q.git_hash, "0123abc");
  EXPECT_EQ(q.dirty, "yes (uncommitted changes)");
  EXPECT_THAT(q.openfoam, HasSubstr("openfoam v1912"));
  // A run that used LIGGGHTS records the version its log header prints (details.liggghts_version).
  EXPECT_EQ(p.liggghts, "not recorded");
  const std::string v = "LIGGGHTS-PUBLIC 3.8.0, compiled 2022-01-26-19:42:32 by buildd, git commit unknown";
  const Provenance r = provenanceOf(nlohmann::json{{"provenance", {{"git_hash", "0123abc"}}}, {"details", {{"liggghts_version", v}}}});
  EXPECT_EQ(r.liggghts, v);
}

TEST(LinkDois, DoisBecomeLinksAndTheRestIsEscaped) {
  EXPECT_EQ(linkDois("A & B (1970), doi:10.1017/S0022112070001428."),
            "A &amp; B (1970), <a href=\"https://doi.org/10.1017/S0022112070001428\">doi:10.1017/S0022112070001428</a>.");
}

}  // namespace
}  // namespace mmval::reports
