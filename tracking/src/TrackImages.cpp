#include "mmval/tracking/TrackImages.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

namespace mmval::tracking {
namespace {

/// 99th percentile of the step speeds (m/s), so that a few linking errors do not set the scale.
double speedScale(const TrackStats& s) {
  std::vector<double> v;
  v.reserve(s.steps.size());
  for (const auto& st : s.steps)
    if (std::isfinite(st.speed)) v.push_back(st.speed);
  if (v.empty()) return 1.0;
  const std::size_t k = std::min(v.size() - 1, static_cast<std::size_t>(0.99 * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k] > 0 ? v[k] : 1.0;
}

/// Viridis colour of speed / scale in [0, 1].
cv::Vec3b colourOf(double fraction) {
  static const cv::Mat lut = [] {
    cv::Mat ramp(1, 256, CV_8U);
    for (int i = 0; i < 256; ++i) ramp.at<std::uint8_t>(0, i) = static_cast<std::uint8_t>(i);
    cv::Mat c;
    cv::applyColorMap(ramp, c, cv::COLORMAP_VIRIDIS);
    return c;
  }();
  const int i = std::clamp(static_cast<int>(std::lround(255 * fraction)), 0, 255);
  return lut.at<cv::Vec3b>(0, i);
}

/// Dimmed colour copy of an 8-bit grey base, with room on the right for the colour bar.
cv::Mat canvas(const cv::Mat& base, int bar_width) {
  cv::Mat grey = base;
  if (grey.empty()) grey = cv::Mat(64, 64, CV_8U, cv::Scalar(255));
  cv::Mat colour;
  cv::cvtColor(grey, colour, cv::COLOR_GRAY2BGR);
  colour = colour * 0.55;
  cv::Mat out(colour.rows, colour.cols + bar_width, CV_8UC3, cv::Scalar(255, 255, 255));
  colour.copyTo(out(cv::Rect(0, 0, colour.cols, colour.rows)));
  return out;
}

/// A vertical colour bar at the right edge, labelled 0 and the scale in um/s.
void colourBar(cv::Mat& img, int bar_width, double scale) {
  const int x0 = img.cols - bar_width + 8, w = 14, top = 18, bottom = img.rows - 18;
  if (bottom - top < 20) return;
  for (int y = top; y <= bottom; ++y) {
    const cv::Vec3b c = colourOf(static_cast<double>(bottom - y) / (bottom - top));
    cv::line(img, {x0, y}, {x0 + w, y}, cv::Scalar(c[0], c[1], c[2]));
  }
  const double fs = 0.35;
  cv::putText(img, fmt::format("{:.3g}", scale * 1e6), {x0 - 4, top - 5}, cv::FONT_HERSHEY_SIMPLEX, fs, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(img, "0", {x0 + 2, bottom + 13}, cv::FONT_HERSHEY_SIMPLEX, fs, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  cv::putText(img, "um/s", {x0 + w + 2, (top + bottom) / 2}, cv::FONT_HERSHEY_SIMPLEX, fs, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

constexpr int kBar = 60;

}  // namespace

cv::Mat velocityOverlay(const cv::Mat& base, const TrackStats& stats, double pixel_size, double frame_interval) {
  cv::Mat img = canvas(base, kBar);
  const double scale = speedScale(stats);
  // Each step as the segment its velocity covers in one frame interval, centred on
  // the step's midpoint (consecutive steps of a track join up).
  for (const Step& s : stats.steps) {
    const cv::Point2d mid(s.x / pixel_size, s.y / pixel_size);
    const cv::Point2d half(0.5 * s.vx * frame_interval / pixel_size, 0.5 * s.vy * frame_interval / pixel_size);
    const cv::Vec3b c = colourOf(s.speed / scale);
    cv::line(img, mid - half, mid + half, cv::Scalar(c[0], c[1], c[2]), 1, cv::LINE_AA);
  }
  colourBar(img, kBar, scale);
  return img;
}

cv::Mat speedMap(const cv::Mat& base, const TrackStats& stats, double pixel_size, int bin_px, cv::Mat* counts) {
  cv::Mat img = canvas(base, kBar);
  const int w = img.cols - kBar, h = img.rows, b = std::max(1, bin_px);
  const int nx = (w + b - 1) / b, ny = (h + b - 1) / b;
  cv::Mat sum(ny, nx, CV_64F, cv::Scalar(0)), n(ny, nx, CV_32S, cv::Scalar(0));
  for (const auto& s : stats.steps) {
    const int i = static_cast<int>(std::floor(s.x / pixel_size / b)), j = static_cast<int>(std::floor(s.y / pixel_size / b));
    if (i < 0 || j < 0 || i >= nx || j >= ny || !std::isfinite(s.speed)) continue;
    sum.at<double>(j, i) += s.speed;
    ++n.at<int>(j, i);
  }
  const double scale = speedScale(stats);
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int k = n.at<int>(j, i);
      if (k == 0) continue;
      const cv::Vec3b c = colourOf(sum.at<double>(j, i) / k / scale);
      const cv::Rect r(i * b, j * b, std::min(b, w - i * b), std::min(b, h - j * b));
      cv::Mat roi = img(r);
      cv::Mat fill(roi.size(), CV_8UC3, cv::Scalar(c[0], c[1], c[2]));
      cv::addWeighted(roi, 0.25, fill, 0.75, 0.0, roi);
    }
  colourBar(img, kBar, scale);
  if (counts) *counts = n;
  return img;
}

}  // namespace mmval::tracking
