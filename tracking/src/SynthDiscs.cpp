#include "mmval/tracking/SynthDiscs.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "mmval/core/AtomicFile.hpp"

namespace mmval::tracking {

namespace {

constexpr int kPlacementAttempts = 20000;  // random sequential placement before giving up
constexpr double kEdgeSoftnessPx = 0.5;    // logistic width of the interior's edge
constexpr double kEdgeMarginPx = 2;        // discs stay this far inside the frame

void require(bool ok, const char* field, const std::string& rule) {
  if (!ok) throw std::invalid_argument(fmt::format("disc scene option {} {}", field, rule));
}

void validate(const DiscSceneOptions& o) {
  require(o.width >= 64 && o.height >= 64 && o.width <= 8192 && o.height <= 8192, "width/height", "must be 64 to 8192 px");
  require(o.frames >= 2, "frames", "must be >= 2");
  require(std::isfinite(o.fps_hz) && o.fps_hz > 0, "fps_hz", "must be finite and > 0");
  require(std::isfinite(o.pixel_size_um) && o.pixel_size_um > 0, "pixel_size_um", "must be finite and > 0");
  require(o.particles >= 0 && o.particles <= 1000, "particles", "must be 0 to 1000");
  require(std::isfinite(o.radius_min_px) && std::isfinite(o.radius_max_px) && o.radius_min_px >= 10 && o.radius_max_px >= o.radius_min_px,
          "radius_min_px/radius_max_px", "must be finite with 10 <= min <= max");
  require(2 * o.radius_max_px + 2 * kEdgeMarginPx < std::min(o.width, o.height), "radius_max_px", "must leave the disc inside the frame");
  for (double v : {o.rim_contrast, o.interior, o.ground, o.noise}) require(std::isfinite(v) && v >= 0 && v <= 1, "contrast/level/noise", "must be in [0, 1]");
  require(std::isfinite(o.rim_sigma_px) && o.rim_sigma_px > 0.3 && o.rim_sigma_px < o.radius_min_px / 4, "rim_sigma_px", "must be in (0.3, radius_min_px / 4)");
  require(std::isfinite(o.rim_offset_px) && o.rim_offset_px >= 0 && o.rim_offset_px < o.radius_min_px / 4, "rim_offset_px", "must be in [0, radius_min_px / 4)");
  require(std::isfinite(o.gap_px) && o.gap_px >= 0, "gap_px", "must be finite and >= 0");
  require(std::isfinite(o.step_px) && o.step_px >= 0, "step_px", "must be finite and >= 0");
}

struct Disc {
  cv::Point2d c;
  double r = 0;
};

bool fits(const std::vector<Disc>& discs, std::size_t self, const Disc& d, const DiscSceneOptions& o) {
  if (d.c.x < d.r + kEdgeMarginPx || d.c.y < d.r + kEdgeMarginPx || d.c.x > o.width - 1 - d.r - kEdgeMarginPx || d.c.y > o.height - 1 - d.r - kEdgeMarginPx)
    return false;
  for (std::size_t j = 0; j < discs.size(); ++j)
    if (j != self && std::hypot(d.c.x - discs[j].c.x, d.c.y - discs[j].c.y) < d.r + discs[j].r + o.gap_px) return false;
  return true;
}

/// The frame: ground plus each disc's profile, plus read noise.
cv::Mat render(const std::vector<Disc>& discs, const DiscSceneOptions& o, cv::RNG& camera) {
  cv::Mat img(o.height, o.width, CV_32F, cv::Scalar(o.ground));
  const double reach = 3 * o.rim_sigma_px + 1;
  for (const auto& d : discs) {
    const int x0 = std::max(0, static_cast<int>(d.c.x - d.r - reach)), x1 = std::min(o.width - 1, static_cast<int>(d.c.x + d.r + reach));
    const int y0 = std::max(0, static_cast<int>(d.c.y - d.r - reach)), y1 = std::min(o.height - 1, static_cast<int>(d.c.y + d.r + reach));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double dist = std::hypot(x - d.c.x, y - d.c.y), rim = dist - d.r + o.rim_offset_px;
        const double inside = 1 / (1 + std::exp(-(d.r - dist) / (kEdgeSoftnessPx / 4)));
        img.at<float>(y, x) += static_cast<float>((o.interior - o.ground) * inside + o.rim_contrast * std::exp(-rim * rim / (2 * o.rim_sigma_px * o.rim_sigma_px)));
      }
  }
  cv::Mat noise(img.size(), CV_32F);
  camera.fill(noise, cv::RNG::NORMAL, 0, o.noise);
  return img + noise;
}

}  // namespace

DiscSceneResult writeDiscScene(const DiscSceneOptions& o, const std::filesystem::path& dir) {
  validate(o);
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> n01(0, 1);
  std::vector<Disc> discs;
  for (int attempt = 0; static_cast<int>(discs.size()) < o.particles; ++attempt) {
    require(attempt < kPlacementAttempts, "particles", "too many discs for the frame (they must not overlap)");
    Disc d;
    d.r = o.radius_min_px + u01(rng) * (o.radius_max_px - o.radius_min_px);
    d.c = {u01(rng) * (o.width - 1), u01(rng) * (o.height - 1)};
    if (fits(discs, discs.size(), d, o)) discs.push_back(d);
  }
  DiscSceneResult result;
  for (const auto& d : discs) result.radii_px.push_back(d.r);
  SynthFrameWriter writer(dir, o.format, o.fps_hz);
  std::seed_seq noise_seed{static_cast<std::uint32_t>(o.seed), 0x64697363u};
  cv::RNG camera(std::uint64_t{std::mt19937_64(noise_seed)()});
  for (int f = 0; f < o.frames; ++f) {
    for (std::size_t i = 0; f > 0 && i < discs.size(); ++i) {
      Disc moved = discs[i];
      moved.c += cv::Point2d(o.step_px * n01(rng), o.step_px * n01(rng));
      if (fits(discs, i, moved, o)) discs[i] = moved;
    }
    for (std::size_t i = 0; i < discs.size(); ++i) {
      TrackPoint t;
      t.frame = f;
      t.particle = static_cast<std::int64_t>(i);
      t.t = f / o.fps_hz;
      t.x_px = discs[i].c.x;
      t.y_px = discs[i].c.y;
      t.x = discs[i].c.x * o.pixel_size_um * 1e-6;
      t.y = discs[i].c.y * o.pixel_size_um * 1e-6;
      result.truth.points.push_back(t);
    }
    writer.write(f, render(discs, o, camera));
  }
  result.files = writer.finish();
  nlohmann::json j;
  j["radii_px"] = result.radii_px;
  j["rim"] = {{"contrast", o.rim_contrast}, {"sigma_px", o.rim_sigma_px}, {"offset_px", o.rim_offset_px}};
  j["interior"] = o.interior;
  j["ground"] = o.ground;
  j["step_px"] = o.step_px;
  j["noise"] = o.noise;
  j["profile"] = "I(d) = b + (I_in - b) S(R - d) + A exp(-(d - R + o)^2 / 2 s^2)";
  writeSynthTruth(dir, result.truth, {"large-discs", o.seed, o.frames, o.width, o.height, o.particles, o.fps_hz, o.pixel_size_um, o.format}, std::move(j));
  return result;
}

}  // namespace mmval::tracking
