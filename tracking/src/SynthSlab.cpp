#include "mmval/tracking/SynthSlab.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>
#include <unordered_set>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Resources.hpp"

namespace mmval::tracking {

namespace {

// Above this many photons per pixel the Poisson shot noise is drawn as a
// Gaussian of the same variance (relative skewness 1/sqrt(50) = 0.14).
constexpr double kGaussianShotNoisePhotons = 50;
// A spot is drawn out to this many blur widths (the Gaussian is 3e-4 of its peak there).
constexpr double kSpotExtentSigmas = 4;
// Per-axis variance of an opaque sphere's projected shadow (a chord-length
// weighted disc): a^2 / 5; of a uniform disc of radius r: r^2 / 4.
constexpr double kSphereShadowVarianceOverA2 = 0.2;
// Gaussian approximation of the Airy disc: sigma = 0.21 lambda / NA (Zhang et al. 2007).
constexpr double kAiryGaussianFactor = 0.21;
// Background brightness, fraction of full scale: brightfield (dark particles) and bright particles on a dim field.
constexpr double kBrightBackground = 0.8, kDimBackground = 0.25;
// Memory of the truth per record: record, samples, and its CSV line.
constexpr double kBytesPerRecord = 48 + 120;

void require(bool ok, const char* field, const std::string& rule) {
  if (!ok) throw std::invalid_argument(fmt::format("Brownian slab option {} {}", field, rule));
}

void validate(const BrownianSlabOptions& o) {
  require(o.width >= 8 && o.height >= 8 && o.width <= 8192 && o.height <= 8192, "width/height", "must be 8 to 8192 px");
  require(o.frames >= 2, "frames", "must be >= 2");
  require(std::isfinite(o.fps_hz) && o.fps_hz > 0, "fps_hz", "must be finite and > 0");
  require(std::isfinite(o.pixel_size_um) && o.pixel_size_um > 0, "pixel_size_um", "must be finite and > 0");
  require(o.particles >= 0, "particles", "must be >= 0");
  require(std::isfinite(o.diffusion_um2_s) && o.diffusion_um2_s >= 0, "diffusion_um2_s", "must be finite and >= 0 (0: Stokes-Einstein)");
  if (o.diffusion_um2_s == 0) {
    require(std::isfinite(o.temperature_K) && o.temperature_K > 0, "temperature_K", "must be finite and > 0");
    require(std::isfinite(o.viscosity_Pa_s) && o.viscosity_Pa_s > 0, "viscosity_Pa_s", "must be finite and > 0");
  }
  require(std::isfinite(o.radius_um) && o.radius_um > 0, "radius_um", "must be finite and > 0");
  require(std::isfinite(o.slab_um) && o.slab_um > 0, "slab_um", "must be finite and > 0");
  require(std::isfinite(o.focus_um) && o.focus_um <= o.slab_um, "focus_um", "must be in [0, slab_um] (< 0: mid-slab)");
  for (double v : {o.drift_um_s[0], o.drift_um_s[1], o.drift_change_um_s2[0], o.drift_change_um_s2[1]})
    require(std::isfinite(v), "drift_um_s/drift_change_um_s2", "must be finite");
  require(std::isfinite(o.medium_index) && o.medium_index >= 1, "medium_index", "must be >= 1");
  require(std::isfinite(o.numerical_aperture) && o.numerical_aperture > 0 && o.numerical_aperture < o.medium_index, "numerical_aperture",
          "must be in (0, medium_index)");
  require(std::isfinite(o.wavelength_um) && o.wavelength_um > 0, "wavelength_um", "must be finite and > 0");
  require(std::isfinite(o.contrast) && o.contrast >= 0 && o.contrast <= 1, "contrast", "must be in [0, 1]");
  require(std::isfinite(o.flicker) && o.flicker >= 0 && o.flicker <= 0.5, "flicker", "must be in [0, 0.5]");
  require(std::isfinite(o.noise) && o.noise >= 0 && o.noise <= 0.5, "noise", "must be in [0, 0.5]");
  require(std::isfinite(o.photons) && o.photons >= 0, "photons", "must be finite and >= 0");
  require(std::isfinite(o.exposure_s) && o.exposure_s >= 0 && o.exposure_s <= 1 / o.fps_hz, "exposure_s", "must be in [0, 1 / fps_hz]");
  require(o.exposure_substeps >= 1 && o.exposure_substeps <= 1000, "exposure_substeps", "must be 1 to 1000");
}

/// Reflecting walls at 0 and H (folding handles steps longer than H).
double reflectIntoSlab(double z, double h) {
  const double period = 2 * h;
  z = std::fmod(z, period);
  if (z < 0) z += period;
  return z > h ? period - z : z;
}

struct Walker {
  std::int64_t id;
  double x, y, z;  // px, px, um
};

}  // namespace

double stokesEinsteinDiffusion(double temperature_K, double viscosity_Pa_s, double radius_m) {
  return kBoltzmannJPerK * temperature_K / (6 * std::numbers::pi * viscosity_Pa_s * radius_m);
}

double slabDiffusion(const BrownianSlabOptions& o) {
  return o.diffusion_um2_s > 0 ? o.diffusion_um2_s : stokesEinsteinDiffusion(o.temperature_K, o.viscosity_Pa_s, o.radius_um * 1e-6) * 1e12;
}

double SlabOptics::sigmaUm(double z_um) const {
  const double dz = blur_slope * (z_um - focus_um);
  return std::sqrt(sigma0_um * sigma0_um + dz * dz);
}

double SlabOptics::peakContrast(double z_um, double contrast) const {
  const double s = sigmaUm(z_um);
  return contrast * sigma0_um * sigma0_um / (s * s);
}

bool SlabOptics::inFocus(double z_um) const { return std::abs(z_um - focus_um) <= 0.5 * depth_of_field_um; }

SlabOptics slabOptics(const BrownianSlabOptions& o) {
  SlabOptics s;
  const double airy = kAiryGaussianFactor * o.wavelength_um / o.numerical_aperture;
  s.sigma0_um = std::sqrt(kSphereShadowVarianceOverA2 * o.radius_um * o.radius_um + airy * airy);
  s.blur_slope = 0.5 * std::tan(std::asin(o.numerical_aperture / o.medium_index));
  s.depth_of_field_um = o.wavelength_um * o.medium_index / (o.numerical_aperture * o.numerical_aperture);
  s.focus_um = o.focus_um < 0 ? 0.5 * o.slab_um : o.focus_um;
  return s;
}

SlabSimulation simulateBrownianSlab(const BrownianSlabOptions& o) {
  validate(o);
  const SlabOptics optics = slabOptics(o);
  SlabSimulation sim;
  const double far_um = std::max(optics.focus_um, o.slab_um - optics.focus_um);
  sim.box_margin_px = std::ceil(kSpotExtentSigmas * optics.sigmaUm(optics.focus_um + far_um) / o.pixel_size_um);
  const double box_w = o.width + 2 * sim.box_margin_px, box_h = o.height + 2 * sim.box_margin_px;
  sim.particles_in_box = static_cast<int>(std::lround(o.particles * box_w * box_h / (static_cast<double>(o.width) * o.height)));
  const int k_sub = o.exposure_s > 0 ? o.exposure_substeps : 1;
  sim.samples_per_record = k_sub;
  const double records = static_cast<double>(o.frames) * sim.particles_in_box;
  requireMemory(records * (kBytesPerRecord + 24.0 * k_sub), defaultMaxMemoryBytes(),
                fmt::format("the ground truth of {} frames x {} particles", o.frames, sim.particles_in_box), {{}, 0, 0, "--frames"},
                "fewer frames or particles (--frames, --particles)");

  const double d_px2_s = slabDiffusion(o) / (o.pixel_size_um * o.pixel_size_um), d_um2_s = slabDiffusion(o);
  const double dt = 1 / o.fps_hz, h = k_sub > 1 ? o.exposure_s / k_sub : 0;
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> n01(0, 1);
  std::int64_t next_id = 0;
  std::vector<Walker> walkers(static_cast<std::size_t>(sim.particles_in_box));
  for (auto& w : walkers) w = {next_id++, -sim.box_margin_px + u01(rng) * box_w, -sim.box_margin_px + u01(rng) * box_h, u01(rng) * o.slab_um};
  // Exact increments over [t, t + tau]: the drift's integral is v(t + tau/2) tau for a linear v(t).
  auto advance = [&](Walker& w, double t, double tau) {
    if (tau <= 0) return;
    const double tm = t + 0.5 * tau;
    const double sxy = std::sqrt(2 * d_px2_s * tau), sz = std::sqrt(2 * d_um2_s * tau);
    w.x += (o.drift_um_s[0] + o.drift_change_um_s2[0] * tm) * tau / o.pixel_size_um + sxy * n01(rng);
    w.y += (o.drift_um_s[1] + o.drift_change_um_s2[1] * tm) * tau / o.pixel_size_um + sxy * n01(rng);
    w.z = reflectIntoSlab(w.z + sz * n01(rng), o.slab_um);
  };
  auto wrap = [&](double& v, double size) {
    const double lo = -sim.box_margin_px;
    if (v >= lo && v < lo + size) return false;
    v = lo + std::fmod(std::fmod(v - lo, size) + size, size);
    return true;
  };
  sim.records.reserve(static_cast<std::size_t>(records));
  sim.samples.reserve(static_cast<std::size_t>(records) * k_sub);
  for (int f = 0; f < o.frames; ++f) {
    const double t0 = f * dt;
    for (auto& w : walkers) {
      SlabRecord r;
      r.frame = f;
      r.particle = w.id;
      for (int k = 0; k < k_sub; ++k) {
        if (k > 0) advance(w, t0 + (k - 1) * h, h);
        sim.samples.emplace_back(w.x, w.y, w.z);
        r.x_px += w.x / k_sub;
        r.y_px += w.y / k_sub;
        r.z_um += w.z / k_sub;
      }
      r.in_view = r.x_px >= 0 && r.x_px <= o.width - 1 && r.y_px >= 0 && r.y_px <= o.height - 1;
      sim.records.push_back(r);
      advance(w, t0 + (k_sub - 1) * h, dt - (k_sub - 1) * h);
      // Leaving the box on one side: a new particle enters on the other, at a new height.
      const bool wx = wrap(w.x, box_w), wy = wrap(w.y, box_h);
      if (wx || wy) {
        w.id = next_id++;
        w.z = u01(rng) * o.slab_um;
      }
    }
  }
  return sim;
}

cv::Mat renderSlabFrame(const BrownianSlabOptions& o, const SlabOptics& optics, const cv::Point3d* samples, std::size_t count,
                        int samples_per_record, double brightness) {
  cv::Mat darkening(o.height, o.width, CV_32F, cv::Scalar(0));
  std::vector<float> gx, gy;
  for (std::size_t i = 0; i < count; ++i) {
    const cv::Point3d& s = samples[i];
    const double sigma = optics.sigmaUm(s.z) / o.pixel_size_um;
    const double amp = optics.peakContrast(s.z, o.contrast) / samples_per_record;
    const double reach = kSpotExtentSigmas * sigma;
    const int x0 = std::max(0, static_cast<int>(std::ceil(s.x - reach))), x1 = std::min(o.width - 1, static_cast<int>(std::floor(s.x + reach)));
    const int y0 = std::max(0, static_cast<int>(std::ceil(s.y - reach))), y1 = std::min(o.height - 1, static_cast<int>(std::floor(s.y + reach)));
    if (x0 > x1 || y0 > y1) continue;
    // The Gaussian is separable: two 1-D profiles instead of an exp per pixel.
    const double inv = -0.5 / (sigma * sigma);
    gx.resize(static_cast<std::size_t>(x1 - x0 + 1));
    gy.resize(static_cast<std::size_t>(y1 - y0 + 1));
    for (int x = x0; x <= x1; ++x) gx[static_cast<std::size_t>(x - x0)] = static_cast<float>(std::exp(inv * (x - s.x) * (x - s.x)));
    for (int y = y0; y <= y1; ++y) gy[static_cast<std::size_t>(y - y0)] = static_cast<float>(amp * std::exp(inv * (y - s.y) * (y - s.y)));
    for (int y = y0; y <= y1; ++y) {
      float* row = darkening.ptr<float>(y) + x0;
      const float a = gy[static_cast<std::size_t>(y - y0)];
      for (std::size_t j = 0; j < gx.size(); ++j) row[j] += a * gx[j];
    }
  }
  const double b = (o.dark_particles ? kBrightBackground : kDimBackground) * brightness;
  cv::Mat img;
  darkening.convertTo(img, CV_32F, o.dark_particles ? -b : b, b);
  return img;
}

namespace {

/// Shot noise (Poisson, Gaussian above kGaussianShotNoisePhotons) and Gaussian read noise, in place.
void addCameraNoise(cv::Mat& img, const BrownianSlabOptions& o, std::mt19937_64& rng) {
  if (o.photons <= 0 && o.noise <= 0) return;
  cv::RNG cv_rng(rng());
  cv::Mat z(img.size(), CV_32F);
  cv_rng.fill(z, cv::RNG::NORMAL, 0, 1);
  for (int y = 0; y < img.rows; ++y) {
    float* v = img.ptr<float>(y);
    const float* n = z.ptr<float>(y);
    for (int x = 0; x < img.cols; ++x) {
      const double mean = std::max(0.0, static_cast<double>(v[x]));
      double value;
      if (o.photons > 0 && mean * o.photons <= kGaussianShotNoisePhotons) {
        std::poisson_distribution<long> shot(mean * o.photons);
        value = static_cast<double>(shot(rng)) / o.photons + o.noise * std::normal_distribution<double>(0, 1)(rng);
      } else {
        // Shot and read noise are independent Gaussians here: one draw with the summed variance.
        const double shot_var = o.photons > 0 ? mean / o.photons : 0;
        value = mean + std::sqrt(shot_var + o.noise * o.noise) * n[x];
      }
      v[x] = static_cast<float>(value);
    }
  }
}

/// Rows of the particles in view (only those within the depth of field with `in_focus_only`), by particle then frame.
void writeTruthCsv(const std::filesystem::path& file, const BrownianSlabOptions& o, const SlabOptics& optics, const SlabSimulation& sim,
                   bool in_focus_only) {
  std::vector<const SlabRecord*> rows;
  for (const auto& r : sim.records)
    if (r.in_view && (!in_focus_only || optics.inFocus(r.z_um))) rows.push_back(&r);
  std::stable_sort(rows.begin(), rows.end(), [](const SlabRecord* a, const SlabRecord* b) {
    return a->particle != b->particle ? a->particle < b->particle : a->frame < b->frame;
  });
  std::string out = "frame,particle,x,y,x_um,y_um,t_s,z_um,dz_um,sigma_px,peak_contrast,in_focus\n";
  out.reserve(rows.size() * 110);
  for (const SlabRecord* r : rows)
    out += fmt::format("{},{},{:.4f},{:.4f},{:.5f},{:.5f},{:.10g},{:.4f},{:.4f},{:.4f},{:.5f},{}\n", r->frame, r->particle, r->x_px, r->y_px,
                       r->x_px * o.pixel_size_um, r->y_px * o.pixel_size_um, r->frame / o.fps_hz, r->z_um, r->z_um - optics.focus_um,
                       optics.sigmaUm(r->z_um) / o.pixel_size_um, optics.peakContrast(r->z_um, o.contrast), optics.inFocus(r->z_um) ? 1 : 0);
  writeFileAtomic(file, out);
}

}  // namespace

BrownianSlabResult writeBrownianSlabVideo(const BrownianSlabOptions& o, const std::filesystem::path& dir) {
  BrownianSlabResult result;
  result.simulation = simulateBrownianSlab(o);
  const SlabSimulation& sim = result.simulation;
  const SlabOptics optics = slabOptics(o);
  result.diffusion_um2_s = slabDiffusion(o);
  // Flicker and camera noise from their own stream: the trajectories do not depend on them.
  std::seed_seq noise_seed{static_cast<std::uint32_t>(o.seed), static_cast<std::uint32_t>(o.seed >> 32), 0x6e6f6973u};
  std::mt19937_64 noise_rng(noise_seed);
  std::normal_distribution<double> n01(0, 1);
  SynthFrameWriter writer(dir, o.format, o.fps_hz);
  const std::size_t per_frame = static_cast<std::size_t>(sim.particles_in_box);
  const int k_sub = sim.samples_per_record;
  std::int64_t in_view = 0, in_focus = 0;
  for (int f = 0; f < o.frames; ++f) {
    // The illumination factor stays positive whatever the draw.
    const double brightness = o.flicker > 0 ? std::max(0.05, 1 + o.flicker * n01(noise_rng)) : 1.0;
    result.brightness.push_back(brightness);
    const std::size_t first = static_cast<std::size_t>(f) * per_frame;
    cv::Mat img = renderSlabFrame(o, optics, sim.samples.data() + first * k_sub, per_frame * k_sub, k_sub, brightness);
    addCameraNoise(img, o, noise_rng);
    writer.write(f, img);
    for (std::size_t i = first; i < first + per_frame; ++i)
      if (sim.records[i].in_view) {
        ++in_view;
        if (optics.inFocus(sim.records[i].z_um)) ++in_focus;
      }
  }
  result.files = writer.finish();
  result.mean_in_view = static_cast<double>(in_view) / o.frames;
  result.mean_in_focus = static_cast<double>(in_focus) / o.frames;
  std::unordered_set<std::int64_t> ids;
  for (const auto& r : sim.records)
    if (r.in_view) ids.insert(r.particle);
  result.distinct_in_view = static_cast<std::int64_t>(ids.size());
  writeTruthCsv(dir / "truth.csv", o, optics, sim, false);
  writeTruthCsv(dir / "truth_in_focus.csv", o, optics, sim, true);

  const double dt = 1 / o.fps_hz, d = result.diffusion_um2_s;
  const double blur_te = o.exposure_s > 0 ? o.exposure_s * (1 - 1.0 / (k_sub * k_sub)) : 0;
  const double t_end = (o.frames - 1) * dt;
  nlohmann::json j;
  j["scene"] = "brownian-slab";
  j["seed"] = o.seed;
  j["frames"] = o.frames;
  j["width_px"] = o.width;
  j["height_px"] = o.height;
  j["fps_hz"] = o.fps_hz;
  j["pixel_size_um"] = o.pixel_size_um;
  j["format"] = synthFormatName(o.format);
  j["diffusion_um2_s"] = d;
  j["diffusion_source"] = o.diffusion_um2_s > 0 ? "given" : "Stokes-Einstein kB T / (6 pi eta a)";
  j["temperature_K"] = o.temperature_K;
  j["viscosity_Pa_s"] = o.viscosity_Pa_s;
  j["radius_um"] = o.radius_um;
  j["msd_slope_4D_um2_s"] = 4 * d;
  j["step_variance_per_axis_um2"] = 2 * d * (dt - blur_te / 3);
  j["drift_um_s"] = {o.drift_um_s[0], o.drift_um_s[1]};
  j["drift_change_um_s2"] = {o.drift_change_um_s2[0], o.drift_change_um_s2[1]};
  j["drift_end_um_s"] = {o.drift_um_s[0] + o.drift_change_um_s2[0] * t_end, o.drift_um_s[1] + o.drift_change_um_s2[1] * t_end};
  j["slab_um"] = o.slab_um;
  j["focus_um"] = optics.focus_um;
  j["numerical_aperture"] = o.numerical_aperture;
  j["medium_index"] = o.medium_index;
  j["wavelength_um"] = o.wavelength_um;
  j["sigma0_um"] = optics.sigma0_um;
  j["sigma0_px"] = optics.sigma0_um / o.pixel_size_um;
  j["blur_slope"] = optics.blur_slope;
  j["depth_of_field_um"] = optics.depth_of_field_um;
  j["contrast"] = o.contrast;
  j["dark_particles"] = o.dark_particles;
  j["flicker"] = o.flicker;
  j["noise"] = o.noise;
  j["photons"] = o.photons;
  j["exposure_s"] = o.exposure_s;
  j["exposure_substeps"] = k_sub;
  j["particles_in_box"] = sim.particles_in_box;
  j["box_margin_px"] = sim.box_margin_px;
  j["mean_in_view_per_frame"] = result.mean_in_view;
  j["mean_in_focus_per_frame"] = result.mean_in_focus;
  j["distinct_particles_in_view"] = result.distinct_in_view;
  j["models"] = {
      {"defocus", "sigma(z)^2 = sigma0^2 + (c |z - z_f|)^2, c = tan(asin(NA/n))/2 (geometric blur circle; Olsen and Adrian 2000)"},
      {"sigma0", "sqrt(a^2/5 + (0.21 lambda/NA)^2) (projected sphere + Gaussian Airy approximation, Zhang et al. 2007)"},
      {"contrast", "peak = contrast * sigma0^2 / sigma(z)^2 (integrated darkening conserved)"},
      {"in_focus", "|z - z_f| <= dof/2, dof = lambda n / NA^2 (Inoue and Spring 1997)"},
      {"walls", "reflecting at z = 0 and slab_um (centre heights)"},
      {"truth_positions", "averaged over the exposure; t_s is the frame's start"}};
  writeFileAtomic(dir / "truth.json", j.dump(2) + "\n");
  return result;
}

}  // namespace mmval::tracking
