#include "mmval/tracking/SynthRings.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "mmval/core/AtomicFile.hpp"

namespace mmval::tracking {

namespace {

// The colloids stay this many ring radii from the edges and this many apart (2.5 R:
// rings do not overlap, their halos may touch).
constexpr double kEdgeMarginRadii = 1.5, kClosestRadii = 2.5;
// A colloid is drawn out to the halo plus four widths (the profile is < 1e-3 there).
constexpr double kReachWidths = 6.5;
constexpr double kSpeckSigmaPx = 3;
// Redraws of a step before the colloid stays where it is for that frame.
constexpr int kStepAttempts = 50;

void require(bool ok, const char* field, const std::string& rule) {
  if (!ok) throw std::invalid_argument(fmt::format("ring scene option {} {}", field, rule));
}

void validate(const RingSceneOptions& o) {
  require(o.width >= 32 && o.height >= 32 && o.width <= 8192 && o.height <= 8192, "width/height", "must be 32 to 8192 px");
  require(o.frames >= 2, "frames", "must be >= 2");
  require(std::isfinite(o.fps_hz) && o.fps_hz > 0, "fps_hz", "must be finite and > 0");
  require(std::isfinite(o.pixel_size_um) && o.pixel_size_um > 0, "pixel_size_um", "must be finite and > 0");
  require(std::isfinite(o.ring_radius_px) && o.ring_radius_px >= 2 && o.ring_radius_px <= 100, "ring_radius_px", "must be 2 to 100 px");
  require(std::isfinite(o.ring_width_px) && o.ring_width_px > 0.3 && o.ring_width_px < o.ring_radius_px, "ring_width_px", "must be in (0.3, ring_radius_px)");
  require(std::isfinite(o.centre_sigma_px) && o.centre_sigma_px > 0.3 && o.centre_sigma_px < o.ring_radius_px, "centre_sigma_px",
          "must be in (0.3, ring_radius_px)");
  for (double c : {o.centre_contrast, o.ring_contrast, o.halo_contrast, o.speck_contrast})
    require(std::isfinite(c) && c >= 0 && c <= 1, "contrast", "must be in [0, 1]");
  require(std::isfinite(o.diffusion_px2) && o.diffusion_px2 >= 0, "diffusion_px2", "must be finite and >= 0");
  require(std::isfinite(o.background) && o.background > 0 && o.background < 1, "background", "must be in (0, 1)");
  require(std::isfinite(o.illumination_gradient) && std::abs(o.illumination_gradient) < 0.9, "illumination_gradient", "must be in (-0.9, 0.9)");
  require(o.static_specks >= 0 && o.static_specks <= 1000, "static_specks", "must be 0 to 1000");
  require(std::isfinite(o.noise) && o.noise >= 0 && o.noise <= 0.5, "noise", "must be in [0, 0.5]");
  const double free_w = o.width - 2 * kEdgeMarginRadii * o.ring_radius_px, free_h = o.height - 2 * kEdgeMarginRadii * o.ring_radius_px;
  // Random sequential placement jams near a packing fraction of ~0.55; stay well below it.
  const double area = M_PI * 0.25 * std::pow(kClosestRadii * o.ring_radius_px, 2) * o.particles;
  require(o.particles >= 0 && free_w > 0 && free_h > 0 && area <= 0.3 * free_w * free_h, "particles",
          "must fit in the frame without overlapping (at most 30 % of it covered by discs of 2.5 ring radii)");
}

}  // namespace

double ringProfile(const RingSceneOptions& o, double r) {
  const double w2 = 2 * o.ring_width_px * o.ring_width_px, halo = o.ring_radius_px + 2.5 * o.ring_width_px;
  return o.centre_contrast * std::exp(-r * r / (2 * o.centre_sigma_px * o.centre_sigma_px)) -
         o.ring_contrast * std::exp(-(r - o.ring_radius_px) * (r - o.ring_radius_px) / w2) + o.halo_contrast * std::exp(-(r - halo) * (r - halo) / w2);
}

RingSceneResult writeRingScene(const RingSceneOptions& o, const std::filesystem::path& dir) {
  validate(o);
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> n01(0, 1);
  const double margin = kEdgeMarginRadii * o.ring_radius_px, closest = kClosestRadii * o.ring_radius_px;
  const double lo_x = margin, hi_x = o.width - 1 - margin, lo_y = margin, hi_y = o.height - 1 - margin;
  auto fold = [](double v, double lo, double hi) {  // reflection into [lo, hi]
    const double span = hi - lo;
    double t = std::fmod(v - lo, 2 * span);
    if (t < 0) t += 2 * span;
    return lo + (t > span ? 2 * span - t : t);
  };
  std::vector<cv::Point2d> pos;
  auto free = [&](const cv::Point2d& p, std::size_t self) {
    for (std::size_t j = 0; j < pos.size(); ++j)
      if (j != self && std::hypot(p.x - pos[j].x, p.y - pos[j].y) < closest) return false;
    return true;
  };
  while (static_cast<int>(pos.size()) < o.particles) {
    const cv::Point2d p(lo_x + u01(rng) * (hi_x - lo_x), lo_y + u01(rng) * (hi_y - lo_y));
    if (free(p, pos.size())) pos.push_back(p);
  }
  // Static specks: fixed dark blobs anywhere (they may lie under a colloid's path).
  std::vector<cv::Point2d> specks;
  for (int k = 0; k < o.static_specks; ++k) specks.emplace_back(u01(rng) * (o.width - 1), u01(rng) * (o.height - 1));
  // Static part of the image: illumination times the specks' transmission.
  cv::Mat field(o.height, o.width, CV_32F);
  for (int y = 0; y < o.height; ++y)
    for (int x = 0; x < o.width; ++x) {
      double t = 1;
      for (const auto& s : specks) t -= o.speck_contrast * std::exp(-((x - s.x) * (x - s.x) + (y - s.y) * (y - s.y)) / (2 * kSpeckSigmaPx * kSpeckSigmaPx));
      field.at<float>(y, x) = static_cast<float>(o.background * (1 - o.illumination_gradient * x / (o.width - 1)) * t);
    }
  RingSceneResult result;
  SynthFrameWriter writer(dir, o.format, o.fps_hz);
  const double step = std::sqrt(2 * o.diffusion_px2);
  const double reach = o.ring_radius_px + kReachWidths * o.ring_width_px;
  std::seed_seq noise_seed{static_cast<std::uint32_t>(o.seed), 0x72696e67u};
  cv::RNG camera(std::uint64_t{std::mt19937_64(noise_seed)()});
  for (int f = 0; f < o.frames; ++f) {
    if (f > 0)
      for (std::size_t i = 0; i < pos.size(); ++i)
        for (int attempt = 0; attempt < kStepAttempts; ++attempt) {
          const cv::Point2d p(fold(pos[i].x + step * n01(rng), lo_x, hi_x), fold(pos[i].y + step * n01(rng), lo_y, hi_y));
          if (free(p, i)) {
            pos[i] = p;
            break;
          }
        }
    cv::Mat modulation(o.height, o.width, CV_32F, cv::Scalar(1));
    for (std::size_t i = 0; i < pos.size(); ++i) {
      const int x0 = std::max(0, static_cast<int>(std::floor(pos[i].x - reach))), x1 = std::min(o.width - 1, static_cast<int>(std::ceil(pos[i].x + reach)));
      const int y0 = std::max(0, static_cast<int>(std::floor(pos[i].y - reach))), y1 = std::min(o.height - 1, static_cast<int>(std::ceil(pos[i].y + reach)));
      for (int y = y0; y <= y1; ++y)
        for (int x = x0; x <= x1; ++x) modulation.at<float>(y, x) += static_cast<float>(ringProfile(o, std::hypot(x - pos[i].x, y - pos[i].y)));
      TrackPoint t;
      t.frame = f;
      t.particle = static_cast<std::int64_t>(i);
      t.t = f / o.fps_hz;
      t.x_px = pos[i].x;
      t.y_px = pos[i].y;
      t.x = pos[i].x * o.pixel_size_um * 1e-6;
      t.y = pos[i].y * o.pixel_size_um * 1e-6;
      result.truth.points.push_back(t);
    }
    cv::Mat img = field.mul(modulation), noise(img.size(), CV_32F);
    camera.fill(noise, cv::RNG::NORMAL, 0, o.noise);
    img += noise;
    writer.write(f, img);
  }
  result.files = writer.finish();
  nlohmann::json j;
  j["ring_radius_px"] = o.ring_radius_px;
  j["ring_width_px"] = o.ring_width_px;
  j["centre_sigma_px"] = o.centre_sigma_px;
  j["contrast"] = {{"centre", o.centre_contrast}, {"ring", -o.ring_contrast}, {"halo", o.halo_contrast}};
  j["diffusion_px2_per_frame"] = o.diffusion_px2;
  j["background"] = o.background;
  j["illumination_gradient"] = o.illumination_gradient;
  j["static_specks"] = o.static_specks;
  j["noise"] = o.noise;
  j["profile"] = "I/b = 1 + C exp(-r^2/2s_c^2) - K exp(-(r-R)^2/2w^2) + H exp(-(r-R-2.5w)^2/2w^2) (phenomenological Lorenz-Mie pattern)";
  writeSynthTruth(dir, result.truth, {"brightfield-rings", o.seed, o.frames, o.width, o.height, o.particles, o.fps_hz, o.pixel_size_um, o.format}, std::move(j));
  return result;
}

}  // namespace mmval::tracking
