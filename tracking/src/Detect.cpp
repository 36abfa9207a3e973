#include "mmval/tracking/Detect.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

namespace mmval::tracking {

cv::Mat medianBackground(FrameSource& source, int samples) {
  const int n = source.count();
  const int stride = std::max(1, n / std::max(1, samples));
  std::vector<cv::Mat> frames;
  cv::Mat f;
  int index = 0, k = 0;
  source.rewind();
  while (source.next(f, index)) {
    if (k++ % stride == 0) frames.push_back(f.clone());
    if (static_cast<int>(frames.size()) >= samples) break;
  }
  source.rewind();
  if (frames.empty()) return {};
  cv::Mat bg(frames[0].size(), CV_32F);
  std::vector<float> v(frames.size());
  for (int r = 0; r < bg.rows; ++r)
    for (int c = 0; c < bg.cols; ++c) {
      for (std::size_t i = 0; i < frames.size(); ++i) v[i] = frames[i].at<float>(r, c);
      std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
      bg.at<float>(r, c) = v[v.size() / 2];
    }
  return bg;
}

Polarity guessPolarity(const cv::Mat& frame, const cv::Mat& background) {
  cv::Mat diff;
  if (background.empty()) {
    const double med = cv::mean(frame)[0];
    diff = frame - med;
  } else {
    diff = frame - background;
  }
  double lo = 0, hi = 0;
  cv::minMaxLoc(diff, &lo, &hi);
  return -lo > hi ? Polarity::dark : Polarity::bright;
}

std::vector<Detection> detect(const cv::Mat& frame, const cv::Mat& background, Polarity polarity, const DetectOptions& o) {
  if (polarity == Polarity::automatic) polarity = guessPolarity(frame, background);
  // Signal: how much darker (or brighter) than the background, >= 0.
  cv::Mat signal;
  if (!background.empty()) {
    signal = polarity == Polarity::dark ? cv::Mat(background - frame) : cv::Mat(frame - background);
  } else {
    const double level = cv::mean(frame)[0];
    signal = polarity == Polarity::dark ? cv::Mat(level - frame) : cv::Mat(frame - level);
  }
  cv::Mat smooth = signal;
  if (o.blur_sigma > 0) cv::GaussianBlur(signal, smooth, cv::Size(0, 0), o.blur_sigma);
  // Noise floor of the smoothed signal from its median absolute deviation (robust to the
  // particles themselves): nothing fainter than min_snr times it counts as a particle.
  double floor_level = 0;
  if (o.min_snr > 0) {
    std::vector<float> v;
    const int step = std::max(1, static_cast<int>(smooth.total() / 20000));
    for (std::size_t i = 0; i < smooth.total(); i += step) v.push_back(smooth.at<float>(static_cast<int>(i)));
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    const double med = v[v.size() / 2];
    for (auto& x : v) x = static_cast<float>(std::abs(x - med));
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    floor_level = med + o.min_snr * 1.4826 * v[v.size() / 2];
  }
  cv::max(signal, 0.0, signal);
  cv::max(smooth, 0.0, smooth);
  cv::Mat bytes;
  smooth.convertTo(bytes, CV_8U, 255.0);
  cv::Mat mask;
  switch (o.threshold) {
    case ThresholdMode::manual:
      cv::threshold(bytes, mask, std::clamp(o.threshold_value, 0.0, 1.0) * 255.0, 255, cv::THRESH_BINARY);
      break;
    case ThresholdMode::otsu: {
      double maxv = 0;
      cv::minMaxLoc(bytes, nullptr, &maxv);
      if (maxv < o.min_contrast * 255) return {};
      // Otsu on the stretched signal, but never below the contrast floor.
      cv::Mat stretched;
      bytes.convertTo(stretched, CV_8U, 255.0 / maxv);
      const double t = cv::threshold(stretched, mask, 0, 255, cv::THRESH_BINARY | cv::THRESH_OTSU) * maxv / 255.0;
      const double lowest = std::max(o.min_contrast, floor_level) * 255;
      if (t < lowest) cv::threshold(bytes, mask, lowest, 255, cv::THRESH_BINARY);
      break;
    }
    case ThresholdMode::adaptive:
      cv::adaptiveThreshold(bytes, mask, 255, cv::ADAPTIVE_THRESH_GAUSSIAN_C, cv::THRESH_BINARY, o.adaptive_block | 1,
                            -o.adaptive_offset * 255);
      break;
  }
  if (o.morphology != Morphology::none && o.iterations > 0) {
    const cv::Mat k = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(o.kernel | 1, o.kernel | 1));
    const int op = o.morphology == Morphology::erode ? cv::MORPH_ERODE
                   : o.morphology == Morphology::dilate ? cv::MORPH_DILATE
                   : o.morphology == Morphology::open ? cv::MORPH_OPEN
                                                       : cv::MORPH_CLOSE;
    cv::morphologyEx(mask, mask, op, k, cv::Point(-1, -1), o.iterations);
  }
  std::vector<std::vector<cv::Point>> contours;
  cv::findContours(mask, contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
  std::vector<Detection> out;
  out.reserve(contours.size());
  for (const auto& c : contours) {
    const cv::Moments m = cv::moments(c);
    const double area = std::max(m.m00, static_cast<double>(c.size()) * 0.5);
    if (area < o.min_area || area > o.max_area) continue;
    const double perimeter = cv::arcLength(c, true);
    const double circularity = perimeter > 0 ? 4 * M_PI * m.m00 / (perimeter * perimeter) : 1.0;
    if (c.size() > 8 && circularity < o.min_circularity) continue;
    Detection d;
    if (m.m00 > 0) {
      d.x = m.m10 / m.m00;
      d.y = m.m01 / m.m00;
    } else {
      const cv::Rect b = cv::boundingRect(c);
      d.x = b.x + 0.5 * (b.width - 1);
      d.y = b.y + 0.5 * (b.height - 1);
    }
    d.area = area;
    if (o.refinement == Refinement::intensity) {
      // Gaussian-masked intensity centroid (Thompson, Larson & Webb 2002): the mask is
      // re-centred on the current sub-pixel estimate each iteration, which removes the
      // bias a fixed pixel window has for symmetric spots.
      const double sm = std::max(1.0, 0.5 * o.refine_radius);
      const int r = o.refine_radius + 2;
      for (int it = 0; it < 20; ++it) {
        const int cx = static_cast<int>(std::lround(d.x)), cy = static_cast<int>(std::lround(d.y));
        double sw = 0, sx = 0, sy = 0;
        for (int y = std::max(0, cy - r); y <= std::min(signal.rows - 1, cy + r); ++y)
          for (int x = std::max(0, cx - r); x <= std::min(signal.cols - 1, cx + r); ++x) {
            const double g = std::exp(-((x - d.x) * (x - d.x) + (y - d.y) * (y - d.y)) / (2 * sm * sm));
            const double w = signal.at<float>(y, x) * g;
            sw += w;
            sx += w * x;
            sy += w * y;
          }
        if (sw <= 0) break;
        const double nx = sx / sw, ny = sy / sw;
        const bool done = std::hypot(nx - d.x, ny - d.y) < 1e-4;
        d.x = nx;
        d.y = ny;
        if (done) break;
      }
    }
    const int px = std::clamp(static_cast<int>(std::lround(d.x)), 0, signal.cols - 1);
    const int py = std::clamp(static_cast<int>(std::lround(d.y)), 0, signal.rows - 1);
    d.peak = smooth.at<float>(py, px);
    if (d.peak < o.min_contrast || d.peak < floor_level) continue;
    double mass = 0;
    const int r = o.refine_radius;
    for (int y = std::max(0, py - r); y <= std::min(signal.rows - 1, py + r); ++y)
      for (int x = std::max(0, px - r); x <= std::min(signal.cols - 1, px + r); ++x) mass += signal.at<float>(y, x);
    d.mass = mass;
    out.push_back(d);
  }
  return out;
}

std::vector<Detection> detectStuck(const cv::Mat& background, Polarity polarity, const DetectOptions& o) {
  if (background.empty()) return {};
  const cv::Mat k = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(o.stuck_kernel | 1, o.stuck_kernel | 1));
  cv::Mat hat;
  cv::morphologyEx(background, hat, polarity == Polarity::bright ? cv::MORPH_TOPHAT : cv::MORPH_BLACKHAT, k);
  // `hat` is the small-scale signal of the background; detect on it against a flat zero.
  DetectOptions d = o;
  d.threshold = ThresholdMode::otsu;
  d.find_stuck = false;
  // A stuck particle is a round spot no larger than the hat kernel; narrow grain
  // tips and corners also survive the hat but are elongated or larger.
  d.max_area = std::min(o.max_area, 0.6 * M_PI * 0.25 * o.stuck_kernel * o.stuck_kernel);
  d.min_circularity = std::max(o.min_circularity, 0.7);
  const cv::Mat flat = cv::Mat::zeros(background.size(), CV_32F);
  return detect(flat + hat, flat, Polarity::bright, d);
}

Polarity parsePolarity(const std::string& s) {
  if (s == "dark") return Polarity::dark;
  if (s == "bright") return Polarity::bright;
  if (s == "auto") return Polarity::automatic;
  throw std::invalid_argument("polarity");
}
ThresholdMode parseThreshold(const std::string& s) {
  if (s == "manual") return ThresholdMode::manual;
  if (s == "otsu") return ThresholdMode::otsu;
  if (s == "adaptive") return ThresholdMode::adaptive;
  throw std::invalid_argument("threshold");
}
Morphology parseMorphology(const std::string& s) {
  if (s == "none") return Morphology::none;
  if (s == "erode") return Morphology::erode;
  if (s == "dilate") return Morphology::dilate;
  if (s == "open") return Morphology::open;
  if (s == "close") return Morphology::close;
  throw std::invalid_argument("morphology");
}
Refinement parseRefinement(const std::string& s) {
  if (s == "moments") return Refinement::moments;
  if (s == "intensity") return Refinement::intensity;
  throw std::invalid_argument("refinement");
}

}  // namespace mmval::tracking
