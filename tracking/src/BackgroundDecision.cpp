// The static background decided from the video (SceneDecisions.hpp).
#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/tracking/SceneDecisions.hpp"

namespace mmval::tracking {

namespace {

constexpr std::size_t kDecisionFrames = 8;
constexpr double kSamePlacePx = 1.5;  // a frame's spot on a median spot: within this distance (or refine_radius / 4)
// Spots more elongated than this (principal sigmas 0.6 : 1, SpotQuality) are not particles.
constexpr double kMaxEccentricity = 0.8;
// A median spot found in at least this share of the sampled frames is static structure.
constexpr double kPersistentShare = 0.75;

/// What the spots of one polarity say: those of the sampled frames against those of the median.
struct SpotComparison {
  double spots_per_frame = 0;
  double spots_in_median = 0;
  double static_share = 0;
  int persistent_spots = 0;
};

/// `spots`: the median's round spots first, then those of each of the n sampled frames.
SpotComparison compareSpots(std::span<const std::vector<Detection>> spots, cv::Size size, double same_place) {
  const std::size_t n = spots.size() - 1;
  const std::vector<Detection>& in_median = spots[0];
  const double cell = same_place;
  // Median spots bucketed by cell of kSamePlacePx: a frame spot's match is in its 3 x 3 cells.
  const int gw = size.width / static_cast<int>(std::ceil(cell)) + 2;
  std::vector<std::vector<std::pair<cv::Point2d, std::size_t>>> grid(static_cast<std::size_t>(gw) * (size.height / static_cast<int>(std::ceil(cell)) + 2));
  auto cellOf = [&](double x, double y) { return static_cast<std::size_t>(std::floor(y / std::ceil(cell)) + 1) * gw + static_cast<std::size_t>(std::floor(x / std::ceil(cell)) + 1); };
  for (std::size_t i = 0; i < in_median.size(); ++i) {
    const Detection& d = in_median[i];
    if (d.x >= 0 && d.y >= 0 && d.x < size.width && d.y < size.height) grid[cellOf(d.x, d.y)].push_back({{d.x, d.y}, i});
  }
  std::vector<int> frames_matched(in_median.size(), 0);  // per median spot
  long total = 0, matched = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const std::vector<Detection>& found = spots[k + 1];
    total += static_cast<long>(found.size());
    std::vector<char> seen(in_median.size(), 0);
    for (const auto& d : found) {
      bool hit = false;
      const std::size_t c = cellOf(std::clamp(d.x, 0.0, size.width - 1.0), std::clamp(d.y, 0.0, size.height - 1.0));
      for (long dy = -1; dy <= 1 && !hit; ++dy)
        for (long dx = -1; dx <= 1 && !hit; ++dx) {
          const long idx = static_cast<long>(c) + dy * gw + dx;
          if (idx < 0 || idx >= static_cast<long>(grid.size())) continue;
          for (const auto& [p, i] : grid[static_cast<std::size_t>(idx)])
            if (std::hypot(p.x - d.x, p.y - d.y) <= same_place) {
              seen[i] = 1;
              hit = true;
            }
        }
      matched += hit;
    }
    for (std::size_t i = 0; i < seen.size(); ++i) frames_matched[i] += seen[i];
  }
  SpotComparison out;
  for (int m : frames_matched) out.persistent_spots += m >= kPersistentShare * static_cast<double>(n);
  out.spots_per_frame = static_cast<double>(total) / n;
  out.spots_in_median = static_cast<double>(in_median.size());
  out.static_share = total > 0 ? static_cast<double>(matched) / total : 0.0;
  return out;
}

/// Scale-free cross-check, the same for either polarity: the band-passed (difference of
/// Gaussians of sigma 1 and 10 px) energy of frame - median over that of the frame, the
/// share of the frames' structure that moves, over n frames spread over `frames`.
double movingEnergyShare(const std::vector<cv::Mat>& frames, const cv::Mat& median, std::size_t n) {
  double moving = 0, all = 0;
  cv::Mat mf, mc;
  cv::GaussianBlur(median, mf, cv::Size(0, 0), 1.0);
  cv::GaussianBlur(median, mc, cv::Size(0, 0), 10.0);
  const cv::Mat median_band = mf - mc;
  for (std::size_t k = 0; k < n; ++k) {
    cv::Mat f, ff, fc;
    frames[k * frames.size() / n].convertTo(f, CV_32F);
    cv::GaussianBlur(f, ff, cv::Size(0, 0), 1.0);
    cv::GaussianBlur(f, fc, cv::Size(0, 0), 10.0);
    const cv::Mat band = ff - fc, rest = band - median_band;
    cv::Scalar m, sd;
    cv::meanStdDev(band, m, sd);
    all += sd[0] * sd[0];
    cv::meanStdDev(rest, m, sd);
    moving += sd[0] * sd[0];
  }
  return all > 0 ? moving / all : 0.0;
}

/// Whether to subtract the median, and why, from the numbers in `out`.
void decide(BackgroundDecision& out, Polarity polarity, double same_place) {
  const std::size_t n = static_cast<std::size_t>(out.frames_compared);
  // Without static structure the median is nearly flat: harmless for spots (it evens the
  // illumination their noise floor assumes), but for rings, whose zero-mean matched filter
  // needs no level, it only adds ghosts of slowly moving rings (measured on the ring
  // scene: 0.81 px against 0.05 px without it).
  out.subtract = !(out.static_share > kStaticShareLimit) && (out.persistent_spots > 0 || polarity != Polarity::ring);
  if (out.static_share > kStaticShareLimit)
    out.reason = fmt::format("{:.0f} % of the spots in {} sampled frames sit within {:g} px of a spot of the temporal median (more than {:.0f} %): "
                             "the particles barely move, so the median is the particles and subtracting it would remove them; not subtracted",
                             100 * out.static_share, n, same_place, 100 * kStaticShareLimit);
  else if (out.persistent_spots == 0 && polarity == Polarity::ring)
    out.reason = fmt::format("no spot of the temporal median is in {:.0f} % of the {} sampled frames: the video has no static structure (grains, "
                             "stuck particles) to remove; the rings' matched filter needs no level and a median would keep ghosts of slowly "
                             "moving rings; not subtracted",
                             100 * kPersistentShare, n);
  else if (out.persistent_spots == 0)
    out.reason = fmt::format("no spot of the temporal median is in {:.0f} % of the {} sampled frames and {:.0f} % of the frames' spots are "
                             "elsewhere: the particles move and the median is nearly flat (illumination only); subtracted, which evens the "
                             "level the spot detector's noise floor assumes",
                             100 * kPersistentShare, n, 100 * (1 - out.static_share));
  else
    out.reason = fmt::format("{} spots of the temporal median are in at least {:.0f} % of the {} sampled frames (static structure: grains, stuck "
                             "particles), and {:.0f} % of the frames' spots are elsewhere (they move): subtracted",
                             out.persistent_spots, 100 * kPersistentShare, n, 100 * (1 - out.static_share));
  if (!out.subtract) out.reason += " (a spatial high-pass of detect.refine_radius instead)";
}

}  // namespace

BackgroundDecision decideBackground(const std::vector<cv::Mat>& frames, const cv::Mat& median, Polarity polarity, const DetectOptions& options) {
  BackgroundDecision out;
  if (frames.empty() || median.empty()) {
    out.reason = "no frames to compare with a median: median subtracted";
    return out;
  }
  if (options.find_stuck) {
    out.reason = "detect.find_stuck looks for particles stuck all along in the median background: median subtracted";
    return out;
  }
  // A spatial high-pass (boxcar of the particle's radius, as trackpy's band pass)
  // stands in for the temporal background on both sides of the comparison.
  DetectOptions o = options;
  if (o.local_background == 0) o.local_background = std::max(2, o.refine_radius);
  o.max_size_ratio = 0;
  // Round spots only: grain edges and corners survive the high-pass as elongated spots,
  // static but not particles, and would pass for particles that never move.
  auto particleLike = [](std::vector<Detection> v) {
    std::erase_if(v, [](const Detection& d) { return d.quality.eccentricity > kMaxEccentricity; });
    return v;
  };
  // Automatic: both sides are judged, and the one that shows more spots against the
  // spatial high-pass (the particles) decides; dark on a tie.
  const std::vector<Polarity> sides = polarity == Polarity::automatic ? std::vector<Polarity>{Polarity::dark, Polarity::bright} : std::vector<Polarity>{polarity};
  // Per side, the median's spots and the sampled frames' (the expensive part: the full
  // detector on images that still hold the static structure), all detected in parallel.
  const std::size_t n = std::min(frames.size(), kDecisionFrames);
  std::vector<std::vector<Detection>> spots(sides.size() * (n + 1));
  cv::parallel_for_(cv::Range(0, static_cast<int>(spots.size())), [&](const cv::Range& range) {
    for (int j = range.start; j < range.end; ++j) {
      const std::size_t side = static_cast<std::size_t>(j) / (n + 1), k = static_cast<std::size_t>(j) % (n + 1);
      spots[static_cast<std::size_t>(j)] = particleLike(detect(k == 0 ? median : frames[(k - 1) * frames.size() / n], {}, sides[side], o));
    }
  });
  const double same_place = std::max(kSamePlacePx, 0.25 * o.refine_radius);
  std::size_t chosen = 0;
  SpotComparison best;
  for (std::size_t side = 0; side < sides.size(); ++side) {
    const SpotComparison c = compareSpots(std::span(spots).subspan(side * (n + 1), n + 1), median.size(), same_place);
    if (side == 0 || !(best.spots_per_frame >= c.spots_per_frame)) {
      best = c;
      chosen = side;
    }
  }
  out.frames_compared = static_cast<int>(n);
  out.spots_per_frame = best.spots_per_frame;
  out.spots_in_median = best.spots_in_median;
  out.static_share = best.static_share;
  out.persistent_spots = best.persistent_spots;
  out.moving_energy_share = movingEnergyShare(frames, median, n);
  decide(out, sides[chosen], same_place);
  return out;
}

Polarity guessPolaritySpatial(const std::vector<cv::Mat>& frames) {
  double bright = 0, dark = 0;
  const std::size_t n = std::min(frames.size(), kDecisionFrames);
  for (std::size_t k = 0; k < n; ++k) {
    cv::Mat f, fine, coarse;
    frames[k * frames.size() / n].convertTo(f, CV_32F);
    cv::GaussianBlur(f, fine, cv::Size(0, 0), 1.0);
    cv::GaussianBlur(f, coarse, cv::Size(0, 0), 10.0);
    const cv::Mat band = fine - coarse;
    std::vector<float> a(band.begin<float>(), band.end<float>());
    for (auto& v : a) v = std::abs(v);
    std::nth_element(a.begin(), a.begin() + static_cast<std::ptrdiff_t>(a.size() / 2), a.end());
    const double t = 4 * std::max(1e-6, 1.4826 * a[a.size() / 2]);
    for (auto it = band.begin<float>(); it != band.end<float>(); ++it) {
      if (*it > t) bright += *it - t;
      if (*it < -t) dark += -*it - t;
    }
  }
  return bright > dark ? Polarity::bright : Polarity::dark;
}

}  // namespace mmval::tracking
