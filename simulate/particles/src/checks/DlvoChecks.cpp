// Check 7, DLVO (kind "physics-dlvo"): the interaction library against theory
// that does not use its own code paths, for one stated chemistry.
//   - Debye length against Israelachvili's printed 0.304 nm / sqrt(I / M) (1:1 salt, 25 C);
//   - force = -dV/dh (central differences over the profile);
//   - HHF limits: equal potentials reduce to 4 pi eps R psi^2 ln(1 + exp(-kappa h)), and at
//     low potentials and kappa h >> 1 HHF and LSA coincide (4 pi eps R psi1 psi2 exp(-kappa h));
//   - the attachment integral against its Laplace (Kramers) estimate over the barrier;
//   - the attachment efficiency alpha(I) over a scan of ionic strengths: it must rise
//     with I, and its slope d ln alpha / d ln I must equal minus the barrier's slope
//     d (Phi_max / kT) / d ln I, taken in closed form at the barrier (envelope theorem;
//     the sphere-plate analogue of Reerink & Overbeek 1954), at fixed surface potentials.
// Outputs: dlvo-profile.csv (the profile at the case's chemistry) and
// attachment-vs-ionic-strength.csv (alpha(I) with the barrier and secondary minimum).
#include "PhysicsChecks.hpp"

#include "../CaseScene.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/particles/Dlvo.hpp"
#include "mmval/particles/Physics.hpp"

namespace mmval::particles::checks {

namespace {

constexpr double kMillivolt = 1e-3;
constexpr double kNm = 1e-9;
/// Barrier (kT) above which the barrier-limited (Kramers) rate applies to a scan point.
constexpr double kBarrierForSlope_kT = 10.0;

void declareDlvo(Schema& s) {
  s.quantity("particles.diameter", "um", "Particle diameter (the paper's fines: 5 um carboxylate polystyrene latex)").def("5 um").positive();
  s.choice("collector.geometry", {"plate", "sphere"}, "Collector: a plate (grain wall, chip plate) or a sphere (a deposited particle)").def("plate");
  s.quantity("collector.diameter", "um", "Collector sphere diameter (collector.geometry = \"sphere\")").def("5 um").positive();
  declareChemistry(s, true);
  s.quantityList("check.ionic_strengths", "mol/m3", "Ionic strengths of the alpha(I) scan (at least 2, increasing)")
      .def(std::vector<double>{1, 2, 5, 10, 20, 50});
  s.real("check.low_potential_mv", "Potential of both surfaces (mV) for the HHF-LSA low-potential far-field check").def(5.0).min(0.01).max(15);
  s.real("check.far_field_kappa_h", "kappa h of the HHF-LSA far-field check").def(6.0).min(3).max(30);
  s.integer("check.profile_points", "Rows of dlvo-profile.csv (log-spaced gaps)").def(400).min(10).max(100000);
  s.quantity("check.profile_min_gap", "nm", "Smallest gap of the profile features and the attachment integral (dlvo-profile.csv starts at 0.1 nm at the least)").def("0.01 nm").positive();
  s.quantity("check.profile_max_gap", "nm", "Largest gap of the profile and its features").def("5000 nm").positive();
}

void dlvoMetrics(Schema& s) {
  s.metric("debye_length", "nm", "Debye length 1/kappa at chemistry.ionic_strength");
  s.metric("barrier_height", "1", "Primary maximum (energy barrier) Phi_max / kT (absent when there is none)");
  s.metric("barrier_gap", "nm", "Gap of the primary maximum");
  s.metric("secondary_minimum_depth", "1", "Depth -Phi_2min / kT of the secondary minimum (absent when there is none)");
  s.metric("secondary_minimum_gap", "nm", "Gap of the secondary minimum");
  s.metric("primary_minimum_energy", "1", "Phi_1min / kT at the primary minimum (with Born repulsion; absent without)");
  s.metric("primary_minimum_gap", "nm", "Gap of the primary minimum");
  s.metric("log10_attachment_efficiency", "1", "log10 alpha at chemistry.ionic_strength (IFBL rate with / without the double layer)");
  s.metric("ln_alpha_laplace_difference", "1",
           "ln alpha (adaptive quadrature) - ln alpha (Laplace estimate over the barrier); absent without a barrier above zero");
  s.metric("secondary_capture_probability", "1", "Maxwell fraction with kinetic energy below the secondary-minimum depth");
  s.metric("force_consistency_error", "1", "max |F - (-dV/dh)_numerical| over the profile, over max |F| on the profile");
  s.metric("hhf_equal_potential_error", "1", "max relative difference of HHF at equal potentials and 4 pi eps R psi^2 ln(1 + exp(-kappa h))");
  s.metric("hhf_over_lsa_far_field", "1", "HHF / LSA at check.low_potential_mv on both surfaces and kappa h = check.far_field_kappa_h");
  s.metric("alpha_rises_with_ionic_strength", "1", "1 when log alpha increases strictly along check.ionic_strengths, else 0");
  s.metric("alpha_slope", "1", "d ln alpha / d ln I between the scan's two middle points (secant)");
  s.metric("alpha_slope_theory", "1", "-d (Phi_max / kT) / d ln I at their geometric mean (envelope theorem at the barrier)");
  s.metric("alpha_slope_ratio", "1", "alpha_slope / alpha_slope_theory");
  s.metric("alpha_slope_ratio_worst", "1", "The scan pair whose slope ratio is farthest from 1 (pairs with barriers > 10 kT at both ends)");
  s.metric("slope_pairs", "1", "Scan pairs with barriers > 10 kT at both ends (used for the slope ratios)");
  s.metric("barrier_height_at_*", "1",
           "Phi_max / kT at the scan's ionic strength the suffix names in mol/m3 (= mM; p for the decimal point), one per scan point "
           "with a barrier");
  s.metric("secondary_minimum_depth_at_*", "1", "-Phi_2min / kT at the scan point the suffix names, as barrier_height_at_*");
  s.metric("wall_time", "s", "Wall-clock time of the run");
}

/// The metric suffix of a scan point: its ionic strength in mol/m3 (= mM), "p" for the
/// decimal point and "m" for a minus sign ("0p01", "10", "1e-05" -> "1em05").
std::string scanTag(double ionic_strength) {
  std::string t = fmt::format("{:g}", ionic_strength);
  for (char& ch : t) {
    if (ch == '.') ch = 'p';
    if (ch == '-') ch = 'm';
  }
  t.erase(std::remove(t.begin(), t.end(), '+'), t.end());
  return t;
}

DlvoParameters parametersFromCase(const Case& c) {
  DlvoParameters p = chemistryFromCase(c, "chemistry.temperature");
  p.particle_radius = 0.5 * c.quantity("particles.diameter");
  p.collector_radius = c.text("collector.geometry") == "plate" ? std::numeric_limits<double>::infinity() : 0.5 * c.quantity("collector.diameter");
  return p;
}

std::vector<double> logGrid(double lo, double hi, int n) {
  std::vector<double> g(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) g[static_cast<std::size_t>(i)] = lo * std::pow(hi / lo, static_cast<double>(i) / (n - 1));
  return g;
}

/// dlvo-profile.csv and the force check over the same gaps.
double writeProfile(const DlvoInteraction& v, const std::vector<double>& gaps, const std::filesystem::path& file) {
  std::ostringstream csv;
  csv << "gap_nm,energy_kT,double_layer_kT,van_der_waals_kT,born_kT,force_N\n";
  double worst = 0, scale = 0;
  for (double h : gaps) {
    const double dh = 1e-5 * h;
    const double numerical = -(v.energy(h + dh) - v.energy(h - dh)) / (2.0 * dh);
    worst = std::max(worst, std::abs(v.force(h) - numerical));
    scale = std::max(scale, std::abs(v.force(h)));
    csv << fmt::format("{:.6g},{:.8g},{:.8g},{:.8g},{:.8g},{:.8g}\n", h / kNm, v.energy(h) / v.kT(), v.doubleLayerEnergy(h) / v.kT(),
                       v.vanDerWaalsEnergy(h) / v.kT(), v.bornEnergy(h) / v.kT(), v.force(h));
  }
  writeFileAtomic(file, csv.str());
  return scale > 0 ? worst / scale : worst;
}

/// HHF at equal potentials against its closed form, max relative difference over kappa h in [0.01, 20].
double hhfEqualPotentialError(DlvoParameters p) {
  p.double_layer = DoubleLayerModel::hhf;
  p.collector_potential = p.particle_potential;
  const DlvoInteraction v(p);
  const double eps = p.electrolyte.relative_permittivity * 8.8541878128e-12;
  const double psi = p.particle_potential;
  double worst = 0;
  for (double kh : logGrid(0.01, 20.0, 200)) {
    const double h = kh / v.kappa();
    const double closed = 4.0 * kPi * eps * v.effectiveRadius() * psi * psi * std::log1p(std::exp(-kh));
    worst = std::max(worst, std::abs(v.doubleLayerEnergy(h) - closed) / std::abs(closed));
  }
  return worst;
}

double hhfOverLsaFarField(DlvoParameters p, double psi, double kappa_h) {
  p.particle_potential = p.collector_potential = psi;
  p.double_layer = DoubleLayerModel::hhf;
  const DlvoInteraction hhf(p);
  p.double_layer = DoubleLayerModel::lsa;
  const DlvoInteraction lsa(p);
  const double h = kappa_h / hhf.kappa();
  return hhf.doubleLayerEnergy(h) / lsa.doubleLayerEnergy(h);
}

struct ScanPoint {
  double ionic_strength = 0;
  DlvoProfileFeatures features;
  DlvoAttachment attachment;
  double barrier_slope = 0;  // d (Phi_max / kT) / d ln I
};

ScanPoint scanPoint(DlvoParameters p, double ionic_strength, double gap_min, double gap_max) {
  p.electrolyte.ionic_strength = ionic_strength;
  const DlvoInteraction v(p);
  ScanPoint s;
  s.ionic_strength = ionic_strength;
  s.features = profileFeatures(v, gap_min, gap_max);
  s.attachment = attachmentEfficiency(v, gap_min);
  s.barrier_slope = barrierSlopeWithIonicStrength(v, s.features);
  return s;
}

struct Gaps {
  double min = 0, max = 0;  // m
};

/// Stage 1: the profile at the case's chemistry, its features and attachment, the
/// force and HHF self-consistency checks; writes dlvo-profile.csv.
void profileStage(const Case& c, const DlvoParameters& p, Gaps gaps, const RunContext& ctx, RunOutput& out) {
  const DlvoInteraction v(p);
  const DlvoProfileFeatures f = profileFeatures(v, gaps.min, gaps.max);
  const DlvoAttachment a = attachmentEfficiency(v, gaps.min);
  out.metrics["debye_length"] = 1.0 / v.kappa();
  out.units["debye_length"] = "nm";
  if (f.has_barrier) {
    out.metrics["barrier_height"] = f.barrier_kT;
    out.metrics["barrier_gap"] = f.barrier_gap;
    out.units["barrier_gap"] = "nm";
  }
  if (f.has_secondary_minimum) {
    out.metrics["secondary_minimum_depth"] = -f.secondary_minimum_kT;
    out.metrics["secondary_minimum_gap"] = f.secondary_minimum_gap;
    out.units["secondary_minimum_gap"] = "nm";
  }
  if (f.has_primary_minimum) {
    out.metrics["primary_minimum_energy"] = f.primary_minimum_kT;
    out.metrics["primary_minimum_gap"] = f.primary_minimum_gap;
    out.units["primary_minimum_gap"] = "nm";
  }
  if (std::isfinite(a.ln_alpha)) out.metrics["log10_attachment_efficiency"] = a.ln_alpha / std::log(10.0);
  if (f.has_barrier && f.barrier_kT > 0 && std::isfinite(a.ln_alpha)) out.metrics["ln_alpha_laplace_difference"] = a.ln_alpha - a.ln_alpha_laplace;
  out.metrics["secondary_capture_probability"] = f.has_secondary_minimum ? secondaryMinimumCaptureProbability(-f.secondary_minimum_kT) : 0.0;

  const auto csv_gaps = logGrid(std::max(gaps.min, 0.1 * kNm), gaps.max, static_cast<int>(c.integer("check.profile_points")));
  out.metrics["force_consistency_error"] = writeProfile(v, csv_gaps, ctx.out_dir / "dlvo-profile.csv");
  out.metrics["hhf_equal_potential_error"] = hhfEqualPotentialError(p);
  out.metrics["hhf_over_lsa_far_field"] = hhfOverLsaFarField(p, c.real("check.low_potential_mv") * kMillivolt, c.real("check.far_field_kappa_h"));

  out.details["primary_minimum_reachable"] = a.primary_minimum_reachable;
  out.details["double_layer"] = p.double_layer == DoubleLayerModel::hhf ? "HHF (Hogg, Healy & Fuerstenau 1966), constant potential"
                                                                        : "LSA (Gregory 1975)";
  out.details["geometry"] = v.plate() ? "sphere-plate" : "sphere-sphere";
  out.details["kappa_a"] = v.kappa() * p.particle_radius;
  out.details["attachment_integration_gaps_nm"] = {a.inner_gap / kNm, a.outer_gap / kNm};
}

void writeScan(const DlvoParameters& p, const std::vector<ScanPoint>& points, const std::filesystem::path& file) {
  std::ostringstream csv;
  csv << "ionic_strength_mM,debye_length_nm,barrier_kT,barrier_gap_nm,secondary_minimum_kT,secondary_minimum_gap_nm,log10_alpha,"
         "log10_alpha_laplace,secondary_capture_probability,barrier_slope_dlnI\n";
  const auto opt = [](bool has, double value, const char* format) { return has ? fmt::format(fmt::runtime(format), value) : std::string(); };
  for (const ScanPoint& s : points) {
    Electrolyte e = p.electrolyte;
    e.ionic_strength = s.ionic_strength;
    const auto& sf = s.features;
    csv << fmt::format("{:.6g},{:.6g},{},{},{},{},{:.8g},{:.8g},{:.6g},{:.8g}\n", s.ionic_strength, debyeLength(e) / kNm,
                       opt(sf.has_barrier, sf.barrier_kT, "{:.8g}"), opt(sf.has_barrier, sf.barrier_gap / kNm, "{:.6g}"),
                       opt(sf.has_secondary_minimum, sf.secondary_minimum_kT, "{:.8g}"),
                       opt(sf.has_secondary_minimum, sf.secondary_minimum_gap / kNm, "{:.6g}"), s.attachment.ln_alpha / std::log(10.0),
                       s.attachment.ln_alpha_laplace / std::log(10.0),
                       sf.has_secondary_minimum ? secondaryMinimumCaptureProbability(-sf.secondary_minimum_kT) : 0.0, s.barrier_slope);
  }
  writeFileAtomic(file, csv.str());
}

/// Stage 2: alpha(I) over the scan at fixed surface potentials, its monotonicity and its
/// slope against the barrier's closed-form slope; writes attachment-vs-ionic-strength.csv.
void scanStage(const Case& c, const DlvoParameters& p, const std::vector<double>& scan, Gaps gaps, const RunContext& ctx, RunOutput& out) {
  std::vector<ScanPoint> points;
  for (double I : scan) points.push_back(scanPoint(p, I, gaps.min, gaps.max));
  writeScan(p, points, ctx.out_dir / "attachment-vs-ionic-strength.csv");
  for (const ScanPoint& s : points) {
    if (s.features.has_barrier) out.metrics[fmt::format("barrier_height_at_{}", scanTag(s.ionic_strength))] = s.features.barrier_kT;
    if (s.features.has_secondary_minimum)
      out.metrics[fmt::format("secondary_minimum_depth_at_{}", scanTag(s.ionic_strength))] = -s.features.secondary_minimum_kT;
  }

  // A pair is in the barrier-limited regime when both ends have a barrier above 10 kT and a primary minimum behind it.
  const auto usable = [&](std::size_t i) {
    const auto& f0 = points[i].features;
    const auto& f1 = points[i + 1].features;
    return f0.has_barrier && f1.has_barrier && f0.barrier_kT > kBarrierForSlope_kT && f1.barrier_kT > kBarrierForSlope_kT &&
           points[i].attachment.primary_minimum_reachable && points[i + 1].attachment.primary_minimum_reachable;
  };
  // Secant of ln alpha between neighbours against the closed form at their geometric mean.
  const auto pairSlope = [&](std::size_t i) {
    const double num = (points[i + 1].attachment.ln_alpha - points[i].attachment.ln_alpha) /
                       std::log(points[i + 1].ionic_strength / points[i].ionic_strength);
    const ScanPoint mid = scanPoint(p, std::sqrt(points[i].ionic_strength * points[i + 1].ionic_strength), gaps.min, gaps.max);
    return std::pair{num, -mid.barrier_slope};
  };
  // alpha must rise with I: strictly across every pair the barrier-limited theory covers,
  // and never fall elsewhere (beyond the critical coagulation concentration alpha -> 1).
  bool rising = true;
  for (std::size_t i = 0; i + 1 < points.size(); ++i) {
    const double lo = points[i].attachment.ln_alpha, hi = points[i + 1].attachment.ln_alpha;
    if (usable(i) ? !(hi > lo) : (hi < lo - 1e-9)) rising = false;
  }
  out.metrics["alpha_rises_with_ionic_strength"] = rising ? 1.0 : 0.0;

  const std::size_t mid = (points.size() - 2) / 2;
  if (!usable(mid))
    throw InputError(c.where("check.ionic_strengths"),
                     "the middle pair of the scan has no barrier above 10 kT (or no primary minimum behind it), so the "
                     "barrier-limited slope does not apply there",
                     fmt::format("{:g} and {:g} mol/m3", points[mid].ionic_strength, points[mid + 1].ionic_strength),
                     "ionic strengths below the critical coagulation concentration of this chemistry");
  double worst = 1.0;
  int pairs = 0;
  nlohmann::json slope_rows = nlohmann::json::array();
  for (std::size_t i = 0; i + 1 < points.size(); ++i) {
    if (!usable(i)) continue;
    const auto [n, t] = pairSlope(i);
    ++pairs;
    if (std::abs(n / t - 1.0) > std::abs(worst - 1.0)) worst = n / t;
    if (i == mid) {
      out.metrics["alpha_slope"] = n;
      out.metrics["alpha_slope_theory"] = t;
      out.metrics["alpha_slope_ratio"] = n / t;
    }
    slope_rows.push_back({{"from_mM", points[i].ionic_strength}, {"to_mM", points[i + 1].ionic_strength}, {"slope", n}, {"theory", t}});
  }
  out.metrics["alpha_slope_ratio_worst"] = worst;
  out.metrics["slope_pairs"] = pairs;
  out.details["slope_by_pair"] = slope_rows;
}

RunOutput runDlvo(const Case& c, const RunContext& ctx) {
  const auto t0 = std::chrono::steady_clock::now();
  const DlvoParameters p = parametersFromCase(c);
  // The scan's theory (the barrier's slope with ln I, Reerink-Overbeek) holds the surface
  // potentials fixed; a charge-regulated collector moves with I, so this check does not apply.
  if (p.collector_charge.regulated)
    throw InputError(c.where("chemistry.collector_charge"),
                     "the alpha(I) check compares with the barrier's slope at fixed surface potentials; a charge-regulated "
                     "collector potential changes with the ionic strength",
                     "\"regulated\"", "\"fixed\" (the potential at one ionic strength: chemistry.collector_zeta_mv)");
  const Gaps gaps{c.quantity("check.profile_min_gap"), c.quantity("check.profile_max_gap")};
  if (!(gaps.max > 10.0 * gaps.min))
    throw InputError(c.where("check.profile_max_gap"), "the profile range is too narrow", fmt::format("{:g} nm", gaps.max / kNm),
                     fmt::format("> 10 x check.profile_min_gap ({:g} nm)", 10.0 * gaps.min / kNm));
  const std::vector<double>& scan = c.reals("check.ionic_strengths");
  if (scan.size() < 2 || !std::is_sorted(scan.begin(), scan.end()) || std::adjacent_find(scan.begin(), scan.end()) != scan.end())
    throw InputError(c.where("check.ionic_strengths"), "the alpha(I) scan needs at least two ionic strengths in increasing order",
                     fmt::format("{} values", scan.size()), "e.g. [1, 2, 5, 10, 20, 50] (mol/m3)");
  if (scan.front() <= 0)
    throw InputError(c.where("check.ionic_strengths"), "ionic strengths must be > 0", fmt::format("{:g} mol/m3", scan.front()), "> 0 mol/m3");

  RunOutput out;
  profileStage(c, p, gaps, ctx, out);
  scanStage(c, p, scan, gaps, ctx, out);
  out.metrics["wall_time"] = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  out.units["wall_time"] = "s";
  out.files = {"dlvo-profile.csv", "attachment-vs-ionic-strength.csv"};
  out.details["assumptions"] =
      "surface potentials taken equal to the zeta potentials and independent of ionic strength over the scan; the paper gives "
      "no chemistry, so the potentials, ionic strength and Hamaker constant are assumptions (reference-data/dlvo-materials.toml)";
  return out;
}

}  // namespace

void registerDlvoChecks(CaseKindRegistry& registry) {
  CaseKind k;
  k.name = "physics-dlvo";
  k.summary = "DLVO sphere-plate / sphere-sphere profile (HHF or LSA double layer, Gregory's retarded van der Waals, Born) and "
              "the IFBL attachment efficiency alpha(I), against closed forms and the barrier's slope with ionic strength";
  k.declare = declareDlvo;
  k.run = runDlvo;
  registry.add(k);
  registry.declareMetrics(k.name, dlvoMetrics);
}

}  // namespace mmval::particles::checks
