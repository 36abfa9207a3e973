#include "mmval/particles/Dlvo.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

#include "mmval/particles/Physics.hpp"

namespace mmval::particles {

namespace {

constexpr double kElementaryCharge = 1.602176634e-19;     // C (SI 2019, exact)
constexpr double kAvogadro = 6.02214076e23;               // 1/mol (SI 2019, exact)
constexpr double kVacuumPermittivity = 8.8541878128e-12;  // F/m (CODATA 2018)

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("DLVO: " + what);
}

/// Golden-section search for the extremum of f on [lo, hi] (sign +1: maximum,
/// -1: minimum); returns the abscissa.
double goldenExtremum(const std::function<double(double)>& f, double lo, double hi, double sign) {
  const double r = 0.5 * (std::sqrt(5.0) - 1.0);
  double a = lo, b = hi;
  double c = b - r * (b - a), d = a + r * (b - a);
  double fc = sign * f(c), fd = sign * f(d);
  for (int it = 0; it < 200 && (b - a) > 1e-13 * (std::abs(a) + std::abs(b) + 1e-300); ++it) {
    if (fc > fd) {
      b = d;
      d = c;
      fd = fc;
      c = b - r * (b - a);
      fc = sign * f(c);
    } else {
      a = c;
      c = d;
      fc = fd;
      d = a + r * (b - a);
      fd = sign * f(d);
    }
  }
  return 0.5 * (a + b);
}

/// Extrema of an energy profile V(h) (J), sampled in ln h and refined.
DlvoProfileFeatures featuresOf(const std::function<double(double)>& V, const std::function<double(double)>& V_core, double kT,
                               double gap_min, double gap_max) {
  require(gap_min > 0 && gap_max > gap_min, "profile range needs 0 < gap_min < gap_max");
  constexpr int n = 2500;  // ln-step 0.005 over 0.01 nm - 5 um: features narrower than that are not DLVO
  const double u0 = std::log(gap_min), u1 = std::log(gap_max);
  std::vector<double> u(n), e(n);
  for (int i = 0; i < n; ++i) {
    u[i] = u0 + (u1 - u0) * i / (n - 1);
    e[i] = V(std::exp(u[i]));
  }
  const auto f = [&](double uu) { return V(std::exp(uu)); };
  struct Extremum { double gap, energy; };
  std::vector<Extremum> maxima, minima;
  for (int i = 1; i + 1 < n; ++i) {
    if (!std::isfinite(e[i])) continue;
    if (e[i] > e[i - 1] && e[i] >= e[i + 1]) {
      const double um = goldenExtremum(f, u[i - 1], u[i + 1], +1.0);
      maxima.push_back({std::exp(um), f(um)});
    } else if (e[i] < e[i - 1] && e[i] <= e[i + 1]) {
      const double um = goldenExtremum(f, u[i - 1], u[i + 1], -1.0);
      minima.push_back({std::exp(um), f(um)});
    }
  }
  DlvoProfileFeatures out;
  // No interior maximum but a well: either a primary minimum reached without a barrier,
  // or a well beyond a repulsive wall that merges with the Born wall (high potentials:
  // the double layer beats van der Waals down to contact). The profile without the
  // Born term tells them apart: it keeps a maximum inside the well only in the second
  // case, and that maximum is the barrier (its energy taken with Born included).
  if (maxima.empty() && !minima.empty() && V_core) {
    const auto well = std::min_element(minima.begin(), minima.end(), [](const Extremum& a, const Extremum& b) { return a.energy < b.energy; });
    double best = -std::numeric_limits<double>::infinity(), best_u = 0;
    double prev2 = V_core(std::exp(u[0])), prev1 = V_core(std::exp(u[1]));
    for (int i = 1; i + 1 < n && std::exp(u[i + 1]) < well->gap; ++i) {
      const double next = V_core(std::exp(u[i + 1]));
      if (prev1 > prev2 && prev1 >= next && prev1 > best) {
        best = prev1;
        best_u = goldenExtremum([&](double uu) { return V_core(std::exp(uu)); }, u[i - 1], u[i + 1], +1.0);
      }
      prev2 = prev1;
      prev1 = next;
    }
    if (std::isfinite(best)) maxima.push_back({std::exp(best_u), f(best_u)});
  }
  if (!maxima.empty()) {
    const auto top = std::max_element(maxima.begin(), maxima.end(), [](const Extremum& a, const Extremum& b) { return a.energy < b.energy; });
    out.has_barrier = true;
    out.barrier_kT = top->energy / kT;
    out.barrier_gap = top->gap;
  }
  for (const auto& m : minima) {
    const bool outside = out.has_barrier && m.gap > out.barrier_gap;
    if (outside) {
      if (!out.has_secondary_minimum || m.energy / kT < out.secondary_minimum_kT) {
        out.has_secondary_minimum = true;
        out.secondary_minimum_kT = m.energy / kT;
        out.secondary_minimum_gap = m.gap;
      }
    } else if (!out.has_primary_minimum || m.energy / kT < out.primary_minimum_kT) {
      out.has_primary_minimum = true;
      out.primary_minimum_kT = m.energy / kT;
      out.primary_minimum_gap = m.gap;
    }
  }
  return out;
}

/// Adaptive Simpson on [a, b] with the end and mid values given.
double simpson(const std::function<double(double)>& f, double a, double b, double fa, double fm, double fb, double whole,
               double tol, int depth) {
  const double m = 0.5 * (a + b), lm = 0.5 * (a + m), rm = 0.5 * (m + b);
  const double flm = f(lm), frm = f(rm);
  const double left = (m - a) / 6.0 * (fa + 4.0 * flm + fm), right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
  const double diff = left + right - whole;
  if (depth <= 0 || std::abs(diff) <= 15.0 * tol) return left + right + diff / 15.0;
  return simpson(f, a, m, fa, flm, fm, left, 0.5 * tol, depth - 1) + simpson(f, m, b, fm, frm, fb, right, 0.5 * tol, depth - 1);
}

/// ln of Int_{h0}^{h1} exp(g(ln h)) d(ln h), where g is given in ln space and peaks
/// near the `breaks`. The integrand is scaled by its sampled maximum so that
/// barriers of thousands of kT neither overflow nor lose precision.
double logIntegral(const std::function<double(double)>& g, double h0, double h1, std::vector<double> breaks) {
  const double u0 = std::log(h0), u1 = std::log(h1);
  constexpr int pieces = 96;
  std::vector<double> nodes;
  for (int i = 0; i <= pieces; ++i) nodes.push_back(u0 + (u1 - u0) * i / pieces);
  for (double b : breaks)
    if (b > h0 && b < h1) nodes.push_back(std::log(b));
  std::sort(nodes.begin(), nodes.end());
  double gmax = -std::numeric_limits<double>::infinity();
  for (double u : nodes) gmax = std::max(gmax, g(u));
  for (int i = 0; i < 1001; ++i) gmax = std::max(gmax, g(u0 + (u1 - u0) * i / 1000.0));
  const auto f = [&](double u) { return std::exp(g(u) - gmax); };
  // First pass for the scale of the total, then the adaptive pass to 1e-10 of it.
  double rough = 0;
  for (std::size_t i = 0; i + 1 < nodes.size(); ++i) {
    const double a = nodes[i], b = nodes[i + 1];
    rough += (b - a) / 6.0 * (f(a) + 4.0 * f(0.5 * (a + b)) + f(b));
  }
  const double tol = 1e-10 * std::max(rough, 1e-300);
  double sum = 0;
  for (std::size_t i = 0; i + 1 < nodes.size(); ++i) {
    const double a = nodes[i], b = nodes[i + 1];
    if (!(b > a)) continue;
    const double fa = f(a), fm = f(0.5 * (a + b)), fb = f(b);
    sum += simpson(f, a, b, fa, fm, fb, (b - a) / 6.0 * (fa + 4.0 * fm + fb), tol / static_cast<double>(nodes.size()), 40);
  }
  return gmax + std::log(sum);
}

}  // namespace

double debyeLength(const Electrolyte& e) {
  require(e.ionic_strength > 0, "ionic strength must be > 0 mol/m3, got " + std::to_string(e.ionic_strength));
  require(e.valence >= 1, "valence must be >= 1, got " + std::to_string(e.valence));
  require(e.temperature > 0, "temperature must be > 0 K");
  require(e.relative_permittivity > 0, "relative permittivity must be > 0");
  // kappa^2 = sum_i c_i z_i^2 e^2 N_A / (eps kT) = 2 I e^2 N_A / (eps kT) (Israelachvili 2011, Eq. 14.36).
  const double kappa2 = 2.0 * e.ionic_strength * kElementaryCharge * kElementaryCharge * kAvogadro /
                        (e.relative_permittivity * kVacuumPermittivity * kBoltzmann * e.temperature);
  return 1.0 / std::sqrt(kappa2);
}

RegulatedCharge regulatedCharge(const SternSurface& s, const Electrolyte& e, double pH) {
  require(std::isfinite(pH) && pH >= 0 && pH <= 14, "pH must be in [0, 14], got " + std::to_string(pH));
  require(std::isfinite(s.pK), "silanol pK must be finite");
  require(std::isfinite(s.site_density) && s.site_density > 0, "silanol site density must be > 0 and finite");
  require(s.capacitance > 0, "Stern capacitance must be > 0 F/m2 (infinity: no Stern layer)");
  const double kappa = 1.0 / debyeLength(e);  // validates the electrolyte
  const double kT = kBoltzmann * e.temperature;
  const double eps = e.relative_permittivity * kVacuumPermittivity;
  const double z = e.valence;
  const double q = kElementaryCharge;
  // Dimensionless potentials phi = e psi / kT. Grahame for a z:z salt: sigma_d = -(2 eps kappa kT / z e)
  // sinh(z phi_d / 2) = e Gamma alpha, so phi_d = -(2/z) asinh(g alpha); the Stern layer: phi_0 = phi_d
  // + e sigma_0 / (C kT) = phi_d - s alpha; mass action at the surface: alpha / (1 - alpha) =
  // 10^(pH - pK) exp(phi_0), i.e. phi_0 = x + L with x = logit(alpha), L = ln10 (pK - pH).
  const double g = z * q * q * s.site_density / (2.0 * eps * kappa * kT);
  const double stern = std::isinf(s.capacitance) ? 0.0 : q * q * s.site_density / (s.capacitance * kT);
  const double L = std::log(10.0) * (s.pK - pH);
  const auto alphaOf = [](double x) { return x < 0 ? std::exp(x) / (1.0 + std::exp(x)) : 1.0 / (1.0 + std::exp(-x)); };
  const auto residual = [&](double x) {
    const double a = alphaOf(x);
    return x + L + (2.0 / z) * std::asinh(g * a) + stern * a;
  };
  // residual(x) - x - L lies in [0, B): the root lies in [-L - B, -L].
  const double B = (2.0 / z) * std::asinh(g) + stern;
  double lo = -L - B, hi = -L;
  for (int it = 0; it < 400 && hi - lo > 1e-15 * (1.0 + std::abs(lo) + std::abs(hi)); ++it) {
    const double mid = 0.5 * (lo + hi);
    (residual(mid) < 0 ? lo : hi) = mid;
  }
  const double x = 0.5 * (lo + hi);
  RegulatedCharge out;
  out.dissociated_fraction = alphaOf(x);
  out.surface_charge = -q * s.site_density * out.dissociated_fraction;
  out.diffuse_potential = -(2.0 / z) * std::asinh(g * out.dissociated_fraction) * kT / q;
  out.surface_potential = out.diffuse_potential + (std::isinf(s.capacitance) ? 0.0 : out.surface_charge / s.capacitance);
  return out;
}

double regulatedSurfacePotential(const SternSurface& s, const Electrolyte& e, double pH) {
  return regulatedCharge(s, e, pH).diffuse_potential;
}

DlvoParameters withRegulatedCollector(DlvoParameters p) {
  if (p.collector_charge.regulated)
    p.collector_potential = regulatedSurfacePotential(p.collector_charge.surface, p.electrolyte, p.collector_charge.ph);
  return p;
}

DlvoParameters atIonicStrength(DlvoParameters p, double ionic_strength) {
  p.electrolyte.ionic_strength = ionic_strength;
  return withRegulatedCollector(p);
}

DlvoInteraction::DlvoInteraction(const DlvoParameters& p) : m_p(p) {
  require(p.particle_radius > 0, "particle radius must be > 0");
  require(p.collector_radius > 0, "collector radius must be > 0 (infinity: a plate)");
  require(p.hamaker >= 0, "Hamaker constant must be >= 0");
  require(p.retardation_wavelength > 0, "retardation wavelength must be > 0");
  require(!p.born || p.born_collision_diameter > 0, "Born collision diameter must be > 0");
  require(std::isfinite(p.particle_potential) && std::isfinite(p.collector_potential), "surface potentials must be finite");
  m_kappa = 1.0 / debyeLength(p.electrolyte);
  m_kT = kBoltzmann * p.electrolyte.temperature;
  m_eps = p.electrolyte.relative_permittivity * kVacuumPermittivity;
  m_plate = std::isinf(p.collector_radius);
  m_reff = m_plate ? p.particle_radius : p.particle_radius * p.collector_radius / (p.particle_radius + p.collector_radius);
}

double DlvoInteraction::doubleLayerEnergy(double h) const {
  const double kh = m_kappa * h;
  const double p1 = m_p.particle_potential, p2 = m_p.collector_potential;
  if (m_p.double_layer == DoubleLayerModel::lsa) {
    // Gregory 1975 (Derjaguin): 64 pi eps R (kT/ze)^2 g1 g2 exp(-kappa h), g = tanh(z e psi / 4 kT).
    const double ze = m_p.electrolyte.valence * kElementaryCharge;
    const double g1 = std::tanh(ze * p1 / (4.0 * m_kT)), g2 = std::tanh(ze * p2 / (4.0 * m_kT));
    const double s = m_kT / ze;
    return 64.0 * kPi * m_eps * m_reff * s * s * g1 * g2 * std::exp(-kh);
  }
  // HHF 1966: pi eps R [2 p1 p2 ln((1+x)/(1-x)) + (p1^2 + p2^2) ln(1 - x^2)], x = exp(-kappa h);
  // ln(1 - x): log1p(-x) far out (no cancellation), ln(-expm1(-kappa h)) near contact.
  const double x = std::exp(-kh);
  const double ln1mx = x < 0.5 ? std::log1p(-x) : std::log(-std::expm1(-kh)), ln1px = std::log1p(x);
  return kPi * m_eps * m_reff * (2.0 * p1 * p2 * (ln1px - ln1mx) + (p1 * p1 + p2 * p2) * (ln1px + ln1mx));
}

double DlvoInteraction::doubleLayerForce(double h) const {
  const double kh = m_kappa * h;
  if (m_p.double_layer == DoubleLayerModel::lsa) return m_kappa * doubleLayerEnergy(h);
  const double p1 = m_p.particle_potential, p2 = m_p.collector_potential;
  // -dV/dh of the HHF form: 2 pi eps R kappa x / (1 - x^2) [2 p1 p2 - (p1^2 + p2^2) x].
  const double x = std::exp(-kh);
  const double one_minus_x2 = -std::expm1(-2.0 * kh);
  return 2.0 * kPi * m_eps * m_reff * m_kappa * x / one_minus_x2 * (2.0 * p1 * p2 - (p1 * p1 + p2 * p2) * x);
}

double DlvoInteraction::vanDerWaalsEnergy(double h) const {
  const double b = 14.0 / m_p.retardation_wavelength;
  return -m_p.hamaker * m_reff / (6.0 * h * (1.0 + b * h));
}

double DlvoInteraction::vanDerWaalsForce(double h) const {
  // -d/dh of Gregory's form: -A R (1 + 2 b h) / (6 h^2 (1 + b h)^2), b = 14 / lambda.
  const double b = 14.0 / m_p.retardation_wavelength;
  const double q = 1.0 + b * h;
  return -m_p.hamaker * m_reff * (1.0 + 2.0 * b * h) / (6.0 * h * h * q * q);
}

double DlvoInteraction::bornEnergy(double h) const {
  if (!m_p.born) return 0.0;
  const double s6 = std::pow(m_p.born_collision_diameter, 6);
  if (m_plate) {
    // Ruckenstein & Prieve 1976 (AIChE J. 22:276), sphere-plate:
    // A sigma^6 / 7560 [(8a + h) / (2a + h)^7 + (6a - h) / h^7].
    const double a = m_p.particle_radius;
    return m_p.hamaker * s6 / 7560.0 * ((8.0 * a + h) / std::pow(2.0 * a + h, 7) + (6.0 * a - h) / std::pow(h, 7));
  }
  // Two spheres: the same term's h << a limit with the Derjaguin radius, A sigma^6 R / (1260 h^7).
  return m_p.hamaker * s6 * m_reff / (1260.0 * std::pow(h, 7));
}

double DlvoInteraction::bornForce(double h) const {
  if (!m_p.born) return 0.0;
  const double s6 = std::pow(m_p.born_collision_diameter, 6);
  if (m_plate) {
    const double a = m_p.particle_radius, q = 2.0 * a + h;
    const double dvdh = 1.0 / std::pow(q, 7) - 7.0 * (8.0 * a + h) / std::pow(q, 8) - 1.0 / std::pow(h, 7) -
                        7.0 * (6.0 * a - h) / std::pow(h, 8);
    return -m_p.hamaker * s6 / 7560.0 * dvdh;
  }
  return 7.0 * m_p.hamaker * s6 * m_reff / (1260.0 * std::pow(h, 8));
}

double DlvoInteraction::energy(double h) const { return doubleLayerEnergy(h) + vanDerWaalsEnergy(h) + bornEnergy(h); }
double DlvoInteraction::force(double h) const { return doubleLayerForce(h) + vanDerWaalsForce(h) + bornForce(h); }

DlvoProfileFeatures profileFeatures(const DlvoInteraction& v, double gap_min, double gap_max) {
  return featuresOf([&](double h) { return v.energy(h); }, [&](double h) { return v.energy(h) - v.bornEnergy(h); }, v.kT(), gap_min,
                    gap_max);
}

double normalResistanceFactor(const DlvoInteraction& v, double h) {
  const double a = v.parameters().particle_radius;
  const double H = h / a;
  if (v.plate()) {
    if (H >= 0.01) return brennerPerpendicular(a, a + h);
    return (1.0 + 0.2 * H * std::log(1.0 / H) + 0.971 * H) / H;
  }
  return (6.0 * H * H + 13.0 * H + 2.0) / (6.0 * H * H + 4.0 * H);
}

double DlvoAttachment::alpha() const { return std::exp(ln_alpha); }

DlvoAttachment attachmentEfficiency(const DlvoInteraction& v, double gap_min) {
  require(gap_min > 0, "attachment: gap_min must be > 0");
  const double kT = v.kT();
  const DlvoParameters& p = v.parameters();
  // Outer edge: 20 Debye lengths, or where |V_vdW| = 0.01 kT: b h^2 + h - c = 0, c = A R / (0.06 kT).
  double h_vdw = 0;
  if (p.hamaker > 0) {
    const double b = 14.0 / p.retardation_wavelength, c = p.hamaker * v.effectiveRadius() / (0.06 * kT);
    h_vdw = 2.0 * c / (1.0 + std::sqrt(1.0 + 4.0 * b * c));
  }
  const double gap_max = std::max({20.0 / v.kappa(), h_vdw, 100.0 * gap_min});
  const auto total = [&](double h) { return v.energy(h); };
  const auto fav = [&](double h) { return v.favourableEnergy(h); };
  const DlvoProfileFeatures ft = profileFeatures(v, gap_min, gap_max);
  const DlvoProfileFeatures ff = featuresOf(fav, [&](double h) { return v.vanDerWaalsEnergy(h); }, kT, gap_min, gap_max);
  const double sum_r = v.plate() ? 0.0 : p.particle_radius + p.collector_radius;
  const auto weight = [&](double h) { return v.plate() ? 1.0 : sum_r * sum_r / ((sum_r + h) * (sum_r + h)); };
  // Integrand in u = ln h: w beta exp(Phi / kT) h.
  const auto g_of = [&](const std::function<double(double)>& V) {
    return [&, V](double u) {
      const double h = std::exp(u);
      return std::log(weight(h) * normalResistanceFactor(v, h) * h) + V(h) / kT;
    };
  };
  DlvoAttachment out;
  out.inner_gap = ft.has_primary_minimum ? ft.primary_minimum_gap : gap_min;
  const double inner_fav = ff.has_primary_minimum ? ff.primary_minimum_gap : gap_min;
  out.outer_gap = gap_max;
  std::vector<double> breaks;
  if (ft.has_barrier) breaks.push_back(ft.barrier_gap);
  if (ft.has_secondary_minimum) breaks.push_back(ft.secondary_minimum_gap);
  out.ln_resistance_favourable = logIntegral(g_of(fav), inner_fav, gap_max, {});
  if (p.born && ft.has_barrier && !ft.has_primary_minimum) {
    // Born repulsion bounds the approach, yet no well lies inside the barrier: nothing
    // to attach in (the wall and the barrier merge); only the secondary minimum holds.
    out.primary_minimum_reachable = false;
    out.ln_alpha = out.ln_alpha_laplace = -std::numeric_limits<double>::infinity();
    out.ln_resistance = std::numeric_limits<double>::infinity();
    return out;
  }
  out.ln_resistance = logIntegral(g_of(total), out.inner_gap, gap_max, breaks);
  out.ln_alpha = out.ln_resistance_favourable - out.ln_resistance;
  out.ln_alpha_laplace = out.ln_alpha;
  if (ft.has_barrier && ft.barrier_kT > 0) {
    const double hm = ft.barrier_gap, dh = 1e-4 * hm;
    const double curvature = -(v.force(hm + dh) - v.force(hm - dh)) / (2.0 * dh);  // V'' < 0 at a maximum
    if (curvature < 0) {
      const double ln_laplace = std::log(weight(hm) * normalResistanceFactor(v, hm)) + ft.barrier_kT +
                                0.5 * std::log(2.0 * kPi * kT / -curvature);
      out.ln_alpha_laplace = out.ln_resistance_favourable - ln_laplace;
    }
  }
  return out;
}

double barrierSlopeWithIonicStrength(const DlvoInteraction& v, const DlvoProfileFeatures& f) {
  if (!f.has_barrier) return 0.0;
  // At fixed surface potentials V_EDL depends on kappa h only, so d V_EDL / d ln kappa = h dV_EDL/dh
  // = -h F_EDL; at the maximum the total force vanishes, so moving h_m costs nothing to first
  // order (envelope theorem), and kappa^2 ~ I gives d ln kappa = d ln I / 2.
  return -0.5 * f.barrier_gap * v.doubleLayerForce(f.barrier_gap) / v.kT();
}

double secondaryMinimumCaptureProbability(double depth_kT) {
  if (!(depth_kT > 0)) return 0.0;
  if (std::isinf(depth_kT)) return 1.0;
  const double x = depth_kT;
  return std::erf(std::sqrt(x)) - 2.0 * std::sqrt(x / kPi) * std::exp(-x);
}

double patchwiseEfficiency(double favourable_fraction, double alpha_unfavourable) {
  const auto in_unit = [](double v) { return v >= 0 && v <= 1; };
  if (!in_unit(favourable_fraction)) throw std::invalid_argument("favourable fraction " + std::to_string(favourable_fraction) + " outside [0, 1]");
  if (!in_unit(alpha_unfavourable)) throw std::invalid_argument("attachment efficiency " + std::to_string(alpha_unfavourable) + " outside [0, 1]");
  return favourable_fraction + (1 - favourable_fraction) * alpha_unfavourable;
}

std::uint64_t splitmix64(std::uint64_t z) {
  z += 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

double FavourablePatchMap::cellValue(Sheet sheet, std::int64_t i, std::int64_t j, std::int64_t k) const {
  // splitmix64 chained over (salt, seed, sheet, i, j, k): each word goes through a full mix before
  // the next is folded in, so neighbouring cells and seeds give unrelated values. The salt keeps
  // this stream apart from the engine's per-arrival draw of the same seed.
  std::uint64_t z = splitmix64(0x5A7C4E5D1B2F3A69ULL ^ seed);
  z = splitmix64(z ^ static_cast<std::uint64_t>(sheet));
  z = splitmix64(z ^ static_cast<std::uint64_t>(i));
  z = splitmix64(z ^ static_cast<std::uint64_t>(j));
  z = splitmix64(z ^ static_cast<std::uint64_t>(k));
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

bool FavourablePatchMap::favourableAt(Sheet sheet, double x, double y, double z) const {
  if (!(fraction > 0)) return false;
  // The walls' cells are shifted by kWallShift of a cell on every axis: a pixel mask's walls lie on
  // round coordinates, and a wall on a cell face would read either cell as the wall point's
  // rounding falls.
  const double shift = sheet == Sheet::walls ? kWallShift : 0.0;
  const auto cell = [&](double v) { return static_cast<std::int64_t>(std::floor(v / size + shift)); };
  const std::int64_t k = sheet == Sheet::walls ? cell(z) : 0;
  return cellValue(sheet, cell(x), cell(y), k) < fraction;
}

}  // namespace mmval::particles
