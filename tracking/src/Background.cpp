#include "mmval/tracking/Background.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "Selection.hpp"

namespace mmval::tracking {

cv::Mat quantileOfFrames(const std::vector<cv::Mat>& frames, double q) {
  if (frames.empty()) return {};
  if (!(q >= 0 && q <= 1)) throw std::invalid_argument("quantileOfFrames: q must be in [0, 1]");
  const std::size_t n = frames.size();
  const std::size_t rank = std::min(n - 1, static_cast<std::size_t>(std::floor(q * static_cast<double>(n))));
  cv::Mat bg(frames[0].size(), CV_32F);
  // Rows in parallel (OpenCV's pool, cv::setNumThreads): each pixel is independent.
  cv::parallel_for_(cv::Range(0, bg.rows), [&](const cv::Range& range) {
    std::vector<const float*> rows(n);
    std::vector<float> v(n), scratch;
    for (int r = range.start; r < range.end; ++r) {
      for (std::size_t i = 0; i < n; ++i) rows[i] = frames[i].ptr<float>(r);
      float* out = bg.ptr<float>(r);
      for (int c = 0; c < bg.cols; ++c) {
        for (std::size_t i = 0; i < n; ++i) v[i] = rows[i][c];
        out[c] = detail::kthSmallest(v.data(), n, rank, scratch);
      }
    }
  });
  return bg;
}

cv::Mat RollingBackground::at(int index) const {
  if (backgrounds.empty()) return {};
  if (index <= centres.front()) return backgrounds.front();
  if (index >= centres.back()) return backgrounds.back();
  const auto hi = static_cast<std::size_t>(std::upper_bound(centres.begin(), centres.end(), index) - centres.begin());
  const std::size_t lo = hi - 1;
  const double w = static_cast<double>(index - centres[lo]) / (centres[hi] - centres[lo]);
  cv::Mat out;
  cv::addWeighted(backgrounds[lo], 1.0 - w, backgrounds[hi], w, 0.0, out);
  return out;
}

std::vector<std::vector<int>> rollingSamplePositions(int count, int window, int samples) {
  if (window < 1 || samples < 1) throw std::invalid_argument("rollingBackground: window and samples must be >= 1");
  const int stride = std::max(1, window / samples);
  std::vector<std::vector<int>> blocks;
  for (int first = 0; first < count; first += window) {
    std::vector<int>& b = blocks.emplace_back();
    for (int pos = first; pos < std::min(count, first + window) && static_cast<int>(b.size()) < samples; pos += stride) b.push_back(pos);
  }
  return blocks;
}

RollingBackground rollingBackground(FrameSource& source, int window, int samples, double q) {
  RollingBackground rb;
  const int n = source.count();
  const std::vector<std::vector<int>> blocks = rollingSamplePositions(n, window, samples);
  std::vector<cv::Mat> block;
  cv::Mat f;
  int index = 0;
  for (std::size_t b = 0; b < blocks.size(); ++b) {
    block.clear();
    for (int pos : blocks[b]) {
      source.sample(pos, f, index);
      block.push_back(f);
    }
    // The block's centre: the middle of its first and last input frame.
    const int first = static_cast<int>(b) * window, last = std::min(n, first + window) - 1;
    rb.centres.push_back((source.indexOf(first) + source.indexOf(last)) / 2);
    rb.backgrounds.push_back(quantileOfFrames(block, q));
  }
  return rb;
}

}  // namespace mmval::tracking
