#include "mmval/tracking/Background.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace mmval::tracking {

cv::Mat quantileOfFrames(const std::vector<cv::Mat>& frames, double q) {
  if (frames.empty()) return {};
  if (!(q >= 0 && q <= 1)) throw std::invalid_argument("quantileOfFrames: q must be in [0, 1]");
  const std::size_t n = frames.size();
  const std::size_t rank = std::min(n - 1, static_cast<std::size_t>(std::floor(q * static_cast<double>(n))));
  cv::Mat bg(frames[0].size(), CV_32F);
  std::vector<const float*> rows(n);
  std::vector<float> v(n);
  for (int r = 0; r < bg.rows; ++r) {
    for (std::size_t i = 0; i < n; ++i) rows[i] = frames[i].ptr<float>(r);
    float* out = bg.ptr<float>(r);
    for (int c = 0; c < bg.cols; ++c) {
      for (std::size_t i = 0; i < n; ++i) v[i] = rows[i][c];
      std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(rank), v.end());
      out[c] = v[rank];
    }
  }
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

RollingBackground rollingBackground(FrameSource& source, int window, int samples, double q) {
  if (window < 1 || samples < 1) throw std::invalid_argument("rollingBackground: window and samples must be >= 1");
  RollingBackground rb;
  const int stride = std::max(1, window / samples);
  std::vector<cv::Mat> block;
  int first = -1, last = -1, pos = 0;
  const auto close = [&] {
    if (block.empty()) return;
    rb.centres.push_back((first + last) / 2);
    rb.backgrounds.push_back(quantileOfFrames(block, q));
    block.clear();
  };
  cv::Mat f;
  int index = 0;
  source.rewind();
  while (source.next(f, index)) {
    if (pos % window == 0) {
      close();
      first = index;
    }
    last = index;
    if ((pos % window) % stride == 0 && static_cast<int>(block.size()) < samples) block.push_back(f.clone());
    ++pos;
  }
  close();
  source.rewind();
  return rb;
}

}  // namespace mmval::tracking
