#include "mmval/tracking/RenderTracks.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/AtomicFile.hpp"

namespace mmval::tracking {

RenderedVideo renderTracksVideo(const Tracks& tracks, const cv::Mat& grains, double geometry_pixel, const RenderOptions& o,
                                const std::filesystem::path& dir) {
  if (tracks.points.empty()) throw std::invalid_argument(tracks.source + ": no trajectory points to render");
  std::map<std::int64_t, double> frame_time;
  for (const auto& p : tracks.points) {
    if (!std::isfinite(p.x_px) || !std::isfinite(p.y_px))
      throw std::invalid_argument(tracks.source + ": trajectories need pixel columns x, y (positions in the geometry image)");
    frame_time.emplace(p.frame, p.t);
  }
  if (frame_time.size() < 2) throw std::invalid_argument(tracks.source + ": fewer than two output steps, nothing moves in a video");
  const std::int64_t first = frame_time.begin()->first, f1 = frame_time.rbegin()->first;
  const double dt = (frame_time.rbegin()->second - frame_time.begin()->second) / static_cast<double>(f1 - first);
  if (!(dt > 0)) throw std::invalid_argument(tracks.source + ": output steps do not advance in time (t_s)");
  // The video starts where the simulation's clock does: when output step k is at t = k dt (a
  // run whose first particles appear at step 3 writes nothing before it), the empty steps
  // before the first particle are frames too, so the tracker's frame k (its t = k / fps) is
  // the simulation's step k at the same time. Otherwise it starts at the first step written.
  const double t_first = frame_time.begin()->second;
  const std::int64_t f0 = first > 0 && std::abs(t_first - static_cast<double>(first) * dt) <= 1e-6 * dt ? 0 : first;

  const int width = std::max(1, static_cast<int>(std::lround(grains.cols * o.scale)));
  const int height = std::max(1, static_cast<int>(std::lround(grains.rows * o.scale)));
  // Static scene as the synthetic videos draw it: bright glass, darker grains, soft edges.
  cv::Mat grains_big;
  cv::resize(grains, grains_big, cv::Size(width, height), 0, 0, cv::INTER_NEAREST);
  cv::Mat scene(height, width, CV_32F, cv::Scalar(0.8));
  scene.setTo(cv::Scalar(0.3), grains_big != 0);
  cv::GaussianBlur(scene, scene, cv::Size(0, 0), 1.0);

  std::map<std::int64_t, std::vector<const TrackPoint*>> by_frame;
  for (const auto& p : tracks.points) by_frame[p.frame].push_back(&p);
  // A deposited particle stays where it attached and in view until the video
  // ends, as on the chip (simulations stop writing it once it is deposited).
  std::vector<TrackPoint> stays;
  for (std::size_t i = 0; i < tracks.points.size(); ++i) {
    const TrackPoint& p = tracks.points[i];
    const bool last = i + 1 == tracks.points.size() || tracks.points[i + 1].particle != p.particle;
    if (last && p.state == "deposited")
      for (std::int64_t f = p.frame + 1; f <= f1; ++f) {
        TrackPoint q = p;
        q.frame = f;
        q.t = p.t + (f - p.frame) * dt;
        stays.push_back(q);
      }
  }
  for (const auto& q : stays) by_frame[q.frame].push_back(&q);
  RenderedVideo out;
  out.fps = 1.0 / dt;
  out.frames = static_cast<int>(f1 - f0 + 1);
  const double video_pixel = geometry_pixel / o.scale;
  std::mt19937_64 rng(o.seed);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(o.amplitude / o.snr));
  std::filesystem::create_directories(dir / "frames");
  const int half = static_cast<int>(std::ceil(4 * o.spot_sigma));
  for (std::int64_t f = f0; f <= f1; ++f) {
    cv::Mat img = scene.clone();
    for (const TrackPoint* p : by_frame[f]) {
      // Pixel coordinates count from the first pixel's centre (as the tracker's do); a
      // geometry pixel's centre maps to the centre of its scale x scale video block.
      const double x = (p->x_px + 0.5) * o.scale - 0.5, y = (p->y_px + 0.5) * o.scale - 0.5;
      for (int yy = std::max(0, static_cast<int>(y) - half); yy <= std::min(height - 1, static_cast<int>(y) + half); ++yy)
        for (int xx = std::max(0, static_cast<int>(x) - half); xx <= std::min(width - 1, static_cast<int>(x) + half); ++xx)
          img.at<float>(yy, xx) -= static_cast<float>(o.amplitude * std::exp(-((xx - x) * (xx - x) + (yy - y) * (yy - y)) / (2 * o.spot_sigma * o.spot_sigma)));
      TrackPoint t = *p;
      t.frame = f - f0;
      t.x_px = x;
      t.y_px = y;
      t.x = x * video_pixel;
      t.y = y * video_pixel;
      out.truth.points.push_back(t);
    }
    for (int yy = 0; yy < height; ++yy) {
      float* row = img.ptr<float>(yy);
      for (int xx = 0; xx < width; ++xx) row[xx] += noise(rng);
    }
    cv::Mat bytes;
    img.convertTo(bytes, CV_8U, 255.0);
    const auto name = dir / "frames" / fmt::format("frame_{:05d}.png", f - f0);
    const auto tmp = temporaryPathFor(name);
    cv::imwrite(tmp.string(), bytes);
    commitTemporary(tmp, name);
  }
  std::stable_sort(out.truth.points.begin(), out.truth.points.end(),
                   [](const TrackPoint& a, const TrackPoint& b) { return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame; });
  out.truth.source = tracks.source;
  return out;
}

}  // namespace mmval::tracking
