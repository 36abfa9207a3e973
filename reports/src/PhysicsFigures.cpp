#include "mmval/reports/PhysicsFigures.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <optional>
#include <tuple>
#include <variant>

#include <fmt/format.h>

#include "mmval/core/ReferenceData.hpp"
#include "mmval/reports/Tables.hpp"

namespace fs = std::filesystem;

namespace mmval::reports {

namespace {

using Columns = std::map<std::string, std::vector<double>>;

/// What every figure builder gets: the run, its folder and reference-data/.
struct RunFiles {
  const nlohmann::json& run;
  fs::path dir, refdir;
  std::string name() const { return run["case"]["name"].get<std::string>(); }
};

/// The run's CSV `file` when it has every column of `need`; empty (and a note on stderr) otherwise.
std::optional<Columns> columnsOf(const RunFiles& rf, const std::string& file, const std::vector<std::string>& need) {
  const fs::path path = rf.dir / file;
  if (!fs::is_regular_file(path)) {
    std::fprintf(stderr, "report: %s: no %s, its figure is left out\n", rf.name().c_str(), file.c_str());
    return std::nullopt;
  }
  Columns cols = readCsvColumns(path);
  for (const auto& c : need)
    if (!cols.count(c)) {
      std::fprintf(stderr, "report: %s: no column %s, its figure is left out\n", path.string().c_str(), c.c_str());
      return std::nullopt;
    }
  return cols;
}

Series series(const Columns& c, const std::string& x, const std::string& y, const std::string& name, const std::string& style,
              const std::string& err = {}) {
  Series s{name, c.at(x), c.at(y), style};
  if (!err.empty() && c.count(err)) s.yerr = c.at(err);
  return s;
}

/// Measured values: filled circles, with error bars when the series has them.
std::string measured(bool bars) { return bars ? "yerrorbars pt 7 ps 0.9" : "points pt 7 ps 0.9"; }

std::string metricText(const nlohmann::json& run, const std::string& name, const char* format) {
  const auto v = metricValue(run, name);
  return v ? fmt::format(fmt::runtime(format), *v) : std::string("not recorded");
}

/// Rows of a reference-data file for `quantity` (and `at`) sorted by the numeric condition `by`.
Series referenceSeries(const fs::path& refdir, const std::string& file, const std::string& quantity, const AtMap& at, const std::string& by,
                       const std::string& name, const std::string& style) {
  Series s{name, {}, {}, style};
  if (refdir.empty() || !fs::exists(refdir / file)) return s;
  std::vector<std::pair<double, double>> pts;
  for (const ReferenceRow* row : loadReferenceFile(refdir / file).find(quantity, at)) {
    const auto it = row->at.find(by);
    if (it == row->at.end() || !row->value || !std::holds_alternative<double>(it->second)) continue;
    pts.emplace_back(std::get<double>(it->second), *row->value);
  }
  std::sort(pts.begin(), pts.end());
  for (const auto& [x, y] : pts) {
    s.x.push_back(x);
    s.y.push_back(y);
  }
  return s;
}

void addIfAny(Plot& p, Series s) {
  if (!s.x.empty()) p.series.push_back(std::move(s));
}

// ------------------------------------------------------------------ one builder per kind

void sedimentation(const RunFiles& rf, std::vector<CheckFigure>& out) {
  const auto c = columnsOf(rf, "height_histogram.csv", {"z_um", "count", "density_1_per_um", "boltzmann_density_1_per_um"});
  if (!c) return;
  // Poisson error of each bin's count (the run reports snapshot correlation ~0.25: the bars are a lower bound).
  Series m = series(*c, "z_um", "density_1_per_um", "measured (histogram of centre heights)", measured(true));
  for (std::size_t i = 0; i < m.y.size(); ++i) {
    const double n = c->at("count")[i];
    m.yerr.push_back(n > 0 ? m.y[i] / std::sqrt(n) : 0.0);
  }
  Plot p{"Sedimentation equilibrium between two plates", "centre height z (um)", "probability density (1/um)", false, false, {}, 640, 400};
  p.series = {m, series(*c, "z_um", "boltzmann_density_1_per_um", "Boltzmann, exp(-(z - a)/l_s) on [a, h - a]", "lines")};
  out.push_back({"height-histogram",
                 fmt::format("Height distribution of non-sticky Brownian particles between the plates (points, Poisson error bars of each bin) against "
                             "Boltzmann's truncated exponential with the sedimentation length l_s = k_B T / (Delta rho V g) = {} um (Perrin 1909). "
                             "Mean height {} um against {} um.",
                             metricText(rf.run, "sedimentation_length", "{:.4g}"), metricText(rf.run, "mean_height", "{:.4g}"),
                             metricText(rf.run, "mean_height_reference", "{:.4g}")),
                 p, rf.dir / "height_histogram.csv"});
}

void hinderedDiffusion(const RunFiles& rf, std::vector<CheckFigure>& out) {
  const auto c = columnsOf(rf, "hindered_diffusion.csv", {"z_over_a", "lambda_par", "lambda_par_se", "lambda_perp", "lambda_perp_se"});
  if (!c) return;
  // Against the gap (z - a) / a on a log axis: the near-wall points spread out.
  Columns g = *c;
  for (double& v : g["z_over_a"]) v -= 1;
  Plot p{"Hindered diffusion near a plate", "gap over radius (z - a) / a", "drag factor lambda = D0 / D", true, true, {}, 640, 400};
  p.series = {series(g, "z_over_a", "lambda_par", "measured, parallel", measured(true), "lambda_par_se"),
              series(g, "z_over_a", "lambda_perp", "measured, normal", "yerrorbars pt 5 ps 0.9", "lambda_perp_se")};
  const std::string file = "wall-hydrodynamics.toml";
  for (auto [quantity, at, name, style] : std::vector<std::tuple<std::string, AtMap, std::string, std::string>>{
           {"lambda_par", {{"from", std::string("Faxen series")}}, "Faxen series, parallel", "lines"},
           {"lambda_perp", {}, "Brenner (1961), normal", "lines dt 2"}}) {
    Series s = referenceSeries(rf.refdir, file, quantity, at, "z_over_a", name, style);
    for (double& v : s.x) v -= 1;
    addIfAny(p, std::move(s));
  }
  out.push_back({"hindered-diffusion",
                 "Drag factors lambda = D0 / D measured from short-time displacements at fixed heights (points, one standard error) against Faxen's "
                 "series (parallel; below z / a ~ 2 the series is no reference and the engine joins it to Goldman, Cox & Brenner's lubrication form) "
                 "and Brenner's exact solution (normal), tabulated in reference-data/wall-hydrodynamics.toml (log-log).",
                 p, rf.dir / "hindered_diffusion.csv"});
}

void blocking(const RunFiles& rf, std::vector<CheckFigure>& out) {
  const auto c = columnsOf(rf, "coverage.csv", {"attempted_coverage", "coverage"});
  if (!c) return;
  Plot p{"Blocking: coverage against attempted coverage", "attempted coverage tau = pi a^2 (particles dropped) / area", "coverage theta", false, false, {}, 640, 400};
  p.series = {series(*c, "attempted_coverage", "coverage", "measured", "lines")};
  const double t_end = c->at("attempted_coverage").empty() ? 1.0 : c->at("attempted_coverage").back();
  const std::string file = "rsa-blocking.toml";
  for (const auto& [model, label, style] : std::vector<std::array<std::string, 3>>{
           {"BD", "ballistic deposition jamming (Talbot & Ricci 1992)", "lines dt 2"}, {"RSA", "random sequential adsorption jamming", "lines dt 3"}}) {
    if (!rf.refdir.empty() && fs::exists(rf.refdir / file))
      for (const ReferenceRow* row : loadReferenceFile(rf.refdir / file).find("jamming_coverage", {{"model", model}}))
        if (row->value) p.series.push_back({fmt::format("{} {:g}", label, *row->value), {0.0, t_end}, {*row->value, *row->value}, style});
  }
  out.push_back({"coverage",
                 fmt::format("Coverage of the plate against attempted coverage (dimensionless time) for sedimenting spheres whose deposits are not sticky, "
                             "against the jamming limits of ballistic deposition and random sequential adsorption (reference-data/rsa-blocking.toml). "
                             "Final coverage {}.",
                             metricText(rf.run, "coverage", "{:.4f}")),
                 p, rf.dir / "coverage.csv"});
}

void settlingSlit(const RunFiles& rf, std::vector<CheckFigure>& out) {
  const auto c = columnsOf(rf, "settling-deposition.csv",
                           {"length_mm", "fraction_point", "fraction_point_reference", "fraction_point_limit", "fraction_full", "fraction_full_reference"});
  if (!c) return;
  Plot p{"Settling deposition in a slit", "slit length L (mm)", "fraction deposited within L", false, false, {}, 640, 400};
  p.yrange = "[0:1.05]";
  p.series = {series(*c, "length_mm", "fraction_point", "measured, point model (hindrance and Faxen off)", "points pt 7 ps 0.7"),
              series(*c, "length_mm", "fraction_point_reference", "closed form, finite size and capture distance", "lines"),
              series(*c, "length_mm", "fraction_point_limit", "point particles, min(1, L v_s / (h U))", "lines dt 2"),
              series(*c, "length_mm", "fraction_full", "measured, full model", "points pt 5 ps 0.7"),
              series(*c, "length_mm", "fraction_full_reference", "quadrature of the engine's drift, full model", "lines dt 3")};
  out.push_back({"settling-fraction",
                 "Fraction of non-Brownian particles deposited on the bottom plate within a length L of plane Poiseuille flow (points) against the exact "
                 "trajectory result: the closed form for the point model (Fuchs 1964, flat channel, with the particle's radius and capture distance) and a "
                 "quadrature of dx/dz = v_x / v_z of the engine's own velocity for the full model (a check of stepping and capture).",
                 p, rf.dir / "settling-deposition.csv"});
}

void diffusionSlit(const RunFiles& rf, std::vector<CheckFigure>& out) {
  const auto c = columnsOf(rf, "diffusion-penetration.csv",
                           {"mu", "penetration", "penetration_se", "penetration_graetz", "penetration_graetz_point", "penetration_leveque"});
  if (!c) return;
  Plot p{"Diffusion deposition in a slit", "dimensionless length mu' = D L / (U h^2)", "penetration P", true, false, {}, 640, 400};
  p.series = {series(*c, "mu", "penetration", "measured", measured(true), "penetration_se"),
              series(*c, "mu", "penetration_graetz", "Graetz series, centres caught at a + c", "lines"),
              series(*c, "mu", "penetration_graetz_point", "Graetz series, point particles", "lines dt 2"),
              series(*c, "mu", "penetration_leveque", "Leveque limit 1 - 2.935 mu'^(2/3)", "lines dt 3")};
  out.push_back({"penetration",
                 "Penetration (fraction not deposited on either plate) against mu' (points, binomial standard error) against the Graetz series for plane "
                 "Poiseuille flow between absorbing plates (40 modes from its eigenproblem; Shah & London 1978) and its short-length Leveque limit "
                 "(Leveque 1928). Lines join the series' values at the measured lengths.",
                 p, rf.dir / "diffusion-penetration.csv"});
}

void collectorInterception(const RunFiles& rf, std::vector<CheckFigure>& out) {
  const auto c = columnsOf(rf, "collector-interception.csv", {"R_capture", "eta_measured", "eta_uncertainty", "eta_theory_kuwabara", "eta_theory_lee_liu"});
  if (!c) return;
  Plot p{"Interception by a post in its Kuwabara cell", "interception parameter R = capture radius / a_f", "single-collector efficiency eta", true, true, {}, 640, 400};
  p.series = {series(*c, "R_capture", "eta_measured", "measured (grazing-trajectory search)", measured(true), "eta_uncertainty"),
              series(*c, "R_capture", "eta_theory_kuwabara", "Kuwabara interception f(1 + R), exact", "lines"),
              series(*c, "R_capture", "eta_theory_lee_liu", "Lee & Liu (1982) small-R form", "lines dt 2")};
  if (c->count("eta_square_array")) addIfAny(p, series(*c, "R_capture", "eta_square_array", "solved square array (information)", "points pt 6 ps 1.1"));
  out.push_back({"eta-vs-R",
                 "Single-collector efficiency by interception against R (log-log): measured in the Kuwabara cell's flow (points, half the final search "
                 "bracket) against the exact Kuwabara interception (Stechkina, Kirsch & Fuchs 1969) and Lee & Liu's small-R form.",
                 p, rf.dir / "collector-interception.csv"});
}

void collectorDiffusion(const RunFiles& rf, std::vector<CheckFigure>& out) {
  const auto c = columnsOf(rf, "collector-diffusion.csv", {"Pe", "eta_measured", "eta_std_error", "eta_theory", "eta_D", "eta_theory_lee_liu"});
  if (!c) return;
  Plot p{"Diffusion capture by a post in its Kuwabara cell", "Peclet number Pe = 2 a_f U / D", "single-collector efficiency eta", true, true, {}, 640, 400};
  p.series = {series(*c, "Pe", "eta_measured", "measured", measured(true), "eta_std_error"),
              series(*c, "Pe", "eta_theory", "Stechkina, Kirsch & Fuchs: eta_D + eta_DR + eta_R", "lines"),
              series(*c, "Pe", "eta_D", "eta_D = 2.9 Ku^(-1/3) Pe^(-2/3) + 0.624/Pe alone", "lines dt 2"),
              series(*c, "Pe", "eta_theory_lee_liu", "Lee & Liu (1982)", "lines dt 3")};
  out.push_back({"eta-vs-Pe",
                 fmt::format("Single-collector efficiency of Brownian particles against Pe (log-log; points with binomial standard errors) against "
                             "Stechkina, Kirsch & Fuchs (1969) for Kuwabara flow, whose boundary-layer term falls as Pe^(-2/3). Fitted exponent {} "
                             "(theory's own values at these Pe: {}).",
                             metricText(rf.run, "diffusion_exponent", "{:.3f}"), metricText(rf.run, "diffusion_exponent_theory", "{:.3f}")),
                 p, rf.dir / "collector-diffusion.csv"});
}

void dlvo(const RunFiles& rf, std::vector<CheckFigure>& out) {
  if (const auto c = columnsOf(rf, "dlvo-profile.csv", {"gap_nm", "energy_kT", "double_layer_kT", "van_der_waals_kT", "born_kT"})) {
    Plot p{"DLVO interaction energy", "surface gap h (nm)", "energy / k_B T", true, false, {}, 640, 400};
    p.series = {series(*c, "gap_nm", "energy_kT", "total", "lines"), series(*c, "gap_nm", "double_layer_kT", "double layer", "lines dt 2"),
                series(*c, "gap_nm", "van_der_waals_kT", "retarded van der Waals (Gregory 1981)", "lines dt 3"),
                series(*c, "gap_nm", "born_kT", "Born", "lines dt 4")};
    // The y range of the total beyond 1 nm: the van der Waals and Born terms diverge at contact.
    double lo = -5, hi = 5;
    for (std::size_t i = 0; i < c->at("gap_nm").size(); ++i)
      if (c->at("gap_nm")[i] >= 1.0 && std::isfinite(c->at("energy_kT")[i])) {
        lo = std::min(lo, 1.3 * c->at("energy_kT")[i]);
        hi = std::max(hi, 1.3 * c->at("energy_kT")[i]);
      }
    p.yrange = fmt::format("[{:.6g}:{:.6g}]", lo, hi);
    out.push_back({"dlvo-profile",
                   fmt::format("DLVO energy against gap at the case's chemistry and its parts (barrier {} k_B T, secondary minimum {} k_B T deep). No published "
                               "profile for a stated parameter set could be retrieved (reference-data/dlvo-profiles.toml says so); the profile is checked "
                               "against closed forms instead (force = -dV/dh, HHF limits, Debye length), in the metrics above.",
                               metricText(rf.run, "barrier_height", "{:.4g}"), metricText(rf.run, "secondary_minimum_depth", "{:.3g}")),
                   p, rf.dir / "dlvo-profile.csv"});
  }
  if (const auto c = columnsOf(rf, "attachment-vs-ionic-strength.csv", {"ionic_strength_mM", "log10_alpha", "log10_alpha_laplace"})) {
    Plot p{"Attachment efficiency against ionic strength", "ionic strength I (mM)", "log10 alpha", true, false, {}, 640, 400};
    p.series = {series(*c, "ionic_strength_mM", "log10_alpha", "attachment integral over the profile", measured(false)),
                series(*c, "ionic_strength_mM", "log10_alpha_laplace", "Laplace (Kramers) estimate over the barrier", "lines")};
    out.push_back({"attachment-vs-ionic-strength",
                   "Attachment efficiency alpha against ionic strength at fixed surface potentials (points: the interaction-force boundary-layer integral "
                   "over the profile) against its Laplace (Kramers) estimate over the barrier; where a barrier stands, d ln alpha / d ln I must equal "
                   "minus the barrier's slope (the metrics above).",
                   p, rf.dir / "attachment-vs-ionic-strength.csv"});
  }
}

void nearWallShear(const RunFiles& rf, std::vector<CheckFigure>& out) {
  const auto c = columnsOf(rf, "near-wall-shear.csv", {"h_over_a", "U_over_gamma_h_gcb", "U_over_gamma_h_engine", "U_over_gamma_h_advanced"});
  if (!c) return;
  Columns g = *c;
  g["gap_over_a"] = c->at("h_over_a");
  for (double& v : g["gap_over_a"]) v -= 1;
  Plot p{"Sphere near a wall in shear", "gap over radius (h - a) / a", "U / (gamma h)", true, false, {}, 640, 400};
  p.series = {series(g, "gap_over_a", "U_over_gamma_h_gcb", "Goldman, Cox & Brenner (1967) table", "linespoints pt 6 ps 1.2"),
              series(g, "gap_over_a", "U_over_gamma_h_engine", "engine velocity", "points pt 7 ps 0.9"),
              series(g, "gap_over_a", "U_over_gamma_h_advanced", "engine, advanced over a distance", "points pt 2 ps 1.2")};
  out.push_back({"translation",
                 "Translation velocity of a free sphere in shear near a wall over the undisturbed flow at its centre, against its gap to the wall (h the "
                 "centre height): the engine (points) against the table of Goldman, Cox & Brenner (1967) in reference-data/goldman-cox-brenner.toml.",
                 p, rf.dir / "near-wall-shear.csv"});
}

}  // namespace

std::vector<CheckFigure> physicsCheckFigures(const nlohmann::json& run, const fs::path& reference_dir) {
  using Builder = std::function<void(const RunFiles&, std::vector<CheckFigure>&)>;
  static const std::map<std::string, Builder> by_kind = {{"physics-sedimentation", sedimentation},
                                                         {"physics-hindered-diffusion", hinderedDiffusion},
                                                         {"physics-blocking", blocking},
                                                         {"physics-settling-slit", settlingSlit},
                                                         {"physics-diffusion-slit", diffusionSlit},
                                                         {"physics-collector-interception", collectorInterception},
                                                         {"physics-collector-diffusion", collectorDiffusion},
                                                         {"physics-dlvo", dlvo},
                                                         {"physics-near-wall-shear", nearWallShear}};
  std::vector<CheckFigure> out;
  if (!run.contains("run_dir") || !run.contains("case") || !run["case"].contains("kind")) return out;
  const auto it = by_kind.find(run["case"]["kind"].get<std::string>());
  if (it == by_kind.end()) return out;
  it->second(RunFiles{run, fs::path(run["run_dir"].get<std::string>()), reference_dir}, out);
  return out;
}

}  // namespace mmval::reports
