#include "MicromodelPicture.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/AtomicFile.hpp"

namespace mmval::particles {

namespace {
constexpr long long kMaxPaths = 600;  // more paths than this hide the chip under them
constexpr int kLongSide = 1200;       // px: the picture's long side at most (the scale is whole)
const cv::Scalar kPore(250, 250, 250), kGrain(128, 128, 128), kMoving(215, 140, 40), kStopped(40, 140, 240), kRetained(30, 30, 220);
}  // namespace

DepositPictureCounts writeDepositPicture(const std::filesystem::path& file, const PixelMask& grains, const Tracks& trajectories,
                                         double radius_px) {
  const int rows = static_cast<int>(grains.rows()), cols = static_cast<int>(grains.cols());
  if (rows < 1 || cols < 1) throw std::invalid_argument("writeDepositPicture: empty mask");
  const int s = std::max(1, kLongSide / std::max(rows, cols));
  cv::Mat img(rows * s, cols * s, CV_8UC3, kPore);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      if (grains(r, c)) img(cv::Rect(c * s, r * s, s, s)).setTo(kGrain);
  // A pixel column x_px (0 at the first pixel's centre) spans [x_px, x_px + 1) * s - s / 2 in the picture.
  const auto at = [&](const TrackPoint& p) { return cv::Point2d((p.x_px + 0.5) * s - 0.5, (p.y_px + 0.5) * s - 0.5); };
  // Each particle's rows are consecutive (sorted by particle, then frame).
  std::vector<std::pair<std::size_t, std::size_t>> spans;
  for (std::size_t i = 0; i < trajectories.points.size();) {
    std::size_t j = i + 1;
    while (j < trajectories.points.size() && trajectories.points[j].particle == trajectories.points[i].particle) ++j;
    spans.emplace_back(i, j);
    i = j;
  }
  DepositPictureCounts n;
  n.particles = static_cast<long long>(spans.size());
  const long long stride = std::max<long long>(1, (n.particles + kMaxPaths - 1) / kMaxPaths);
  constexpr int kShift = 4;  // sub-pixel drawing: coordinates in 1/16 px
  const auto fixed = [](const cv::Point2d& p) { return cv::Point(static_cast<int>(std::lround(p.x * 16)), static_cast<int>(std::lround(p.y * 16))); };
  std::vector<cv::Point> line;
  // The moving paths first, the deposited ones over them (fewer, and the ones a reader looks for).
  for (const bool deposited : {false, true})
    for (std::size_t k = 0; k < spans.size(); ++k) {
      const auto [i, j] = spans[k];
      if (static_cast<long long>(k) % stride != 0 || (trajectories.points[j - 1].state == "deposited") != deposited) continue;
      line.clear();
      for (std::size_t m = i; m < j; ++m)
        if (std::isfinite(trajectories.points[m].x_px) && std::isfinite(trajectories.points[m].y_px)) line.push_back(fixed(at(trajectories.points[m])));
      if (line.size() < 2) continue;
      cv::polylines(img, line, false, deposited ? kStopped : kMoving, 1, cv::LINE_AA, kShift);
      ++n.paths;
    }
  const int disc = std::max(3, static_cast<int>(std::lround(radius_px * s)));  // 3 px at least: visible at any scale
  for (const auto& [i, j] : spans) {
    const TrackPoint& last = trajectories.points[j - 1];
    if (last.state != "deposited" || !std::isfinite(last.x_px) || !std::isfinite(last.y_px)) continue;
    cv::circle(img, fixed(at(last)), disc * 16, kRetained, cv::FILLED, cv::LINE_AA, kShift);
    ++n.retained;
  }
  const std::string legend = fmt::format("flow left to right | grains grey | {} of {} paths: blue moving or left, orange deposited | red: the {} retained",
                                         n.paths, n.particles, n.retained);
  const double font = std::max(0.4, img.cols / 2400.0);
  int base = 0;
  const cv::Size box = cv::getTextSize(legend, cv::FONT_HERSHEY_SIMPLEX, font, 1, &base);
  cv::rectangle(img, cv::Rect(0, 0, std::min(img.cols, box.width + 12), box.height + base + 10), cv::Scalar(255, 255, 255), cv::FILLED);
  cv::putText(img, legend, cv::Point(6, box.height + 5), cv::FONT_HERSHEY_SIMPLEX, font, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  std::vector<unsigned char> png;
  if (!cv::imencode(".png", img, png)) throw std::runtime_error("PNG encoding failed for " + file.string());
  writeFileAtomic(file, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
  return n;
}

}  // namespace mmval::particles
