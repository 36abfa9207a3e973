#include "mmval/tracking/Detect.hpp"

#include "Selection.hpp"
#include "SpotFit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <Eigen/Dense>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/tracking/Background.hpp"
#include "mmval/tracking/SceneDecisions.hpp"

namespace mmval::tracking {

std::vector<int> samplePositions(int count, int samples) {
  const int stride = std::max(1, count / std::max(1, samples));
  std::vector<int> positions;
  for (int pos = 0; pos < count && static_cast<int>(positions.size()) < samples; pos += stride) positions.push_back(pos);
  return positions;
}

std::vector<cv::Mat> sampleFrames(FrameSource& source, int samples) {
  std::vector<cv::Mat> frames;
  cv::Mat f;
  int index = 0;
  for (int pos : samplePositions(source.count(), samples)) {
    source.sample(pos, f, index);
    frames.push_back(f);
  }
  return frames;
}

Polarity guessPolarity(const std::vector<cv::Mat>& frames, const cv::Mat& background) {
  if (frames.empty()) return Polarity::dark;
  if (frames.size() == 1 && background.empty()) return guessPolarity(frames[0], background);
  // The foreground is what moves: each frame minus the static background (grains,
  // deposits, illumination), smoothed at the particle scale so that pixel noise averages
  // out. Deviations beyond 4 noise sigma (robust, per frame) add their excess to the
  // dark or the bright side. A pixel that deviates the same way in more than a quarter of
  // the frames is static, not a passing particle: a deposit that the median background
  // holds but that has not arrived yet in the early frames looks like a bright spot
  // there (the micromodel video's first frame: +0.875 against -0.27), so it is skipped.
  const cv::Mat bg = background.empty() ? quantileOfFrames(frames, 0.5) : background;
  std::vector<cv::Mat> fg(frames.size());
  std::vector<double> noise(frames.size());
  cv::Mat above(bg.size(), CV_32S, cv::Scalar(0)), below(bg.size(), CV_32S, cv::Scalar(0));
  // Each frame's foreground and noise in parallel (independent), the counts in order.
  cv::parallel_for_(cv::Range(0, static_cast<int>(frames.size())), [&](const cv::Range& range) {
    for (int k = range.start; k < range.end; ++k) {
      cv::Mat f;
      frames[k].convertTo(f, CV_32F);
      cv::GaussianBlur(f - bg, fg[k], cv::Size(0, 0), 1.0);
      // The median absolute value (the exact order statistic nth_element would give).
      thread_local std::vector<float> a, scratch;
      a.resize(fg[k].total());
      const float* p = fg[k].ptr<float>();  // continuous: allocated by the blur
      for (std::size_t i = 0; i < a.size(); ++i) a[i] = std::abs(p[i]);
      noise[k] = std::max(1e-6, 1.4826 * detail::kthSmallest(a.data(), a.size(), a.size() / 2, scratch));
    }
  });
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const float t = static_cast<float>(4 * noise[k]);
    for (int r = 0; r < bg.rows; ++r) {
      const float* f = fg[k].ptr<float>(r);
      int* up = above.ptr<int>(r);
      int* down = below.ptr<int>(r);
      for (int c = 0; c < bg.cols; ++c) {
        up[c] += f[c] > t;
        down[c] += f[c] < -t;
      }
    }
  }
  const int persistent = std::max(1, static_cast<int>(frames.size()) / 4);
  double bright = 0, dark = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const double t = 4 * noise[k];
    for (int r = 0; r < bg.rows; ++r) {
      const float* f = fg[k].ptr<float>(r);
      const int* up = above.ptr<int>(r);
      const int* down = below.ptr<int>(r);
      for (int c = 0; c < bg.cols; ++c) {
        const double v = f[c];
        if (v > t && up[c] <= persistent) bright += v - t;
        if (v < -t && down[c] <= persistent) dark += -v - t;
      }
    }
  }
  if (bright == 0 && dark == 0) return guessPolarity(frames.front(), bg);
  return dark >= bright ? Polarity::dark : Polarity::bright;
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

namespace {

using detail::deblend;
using detail::gaussianRow;
using detail::maskedSums;

/// Least-squares fit of b + A exp(-|p - c|^2 / (2 s^2)) to `signal` in a window
/// around `d` (Levenberg-Marquardt on x, y, A, s, b). Keeps `d` when the fit fails
/// or wanders off: more than 1.5 px, a sigma outside [0.3, 4] x the start, A <= 0.
void fitGaussian(const cv::Mat& signal, double sigma0, Detection& d) {
  const int w = std::max(3, static_cast<int>(std::ceil(2.5 * sigma0)));
  const int cx = static_cast<int>(std::lround(d.x)), cy = static_cast<int>(std::lround(d.y));
  const int x0 = std::max(0, cx - w), x1 = std::min(signal.cols - 1, cx + w);
  const int y0 = std::max(0, cy - w), y1 = std::min(signal.rows - 1, cy + w);
  if (x1 - x0 < 4 || y1 - y0 < 4) return;
  Eigen::Matrix<double, 5, 1> q;  // x, y, A, s, b
  double amplitude = 0;
  for (int y = y0; y <= y1; ++y)
    for (int x = x0; x <= x1; ++x) amplitude = std::max(amplitude, static_cast<double>(signal.at<float>(y, x)));
  q << d.x, d.y, amplitude, sigma0, 0.0;
  auto residuals = [&](const Eigen::Matrix<double, 5, 1>& p, Eigen::Matrix<double, 5, 5>* jtj, Eigen::Matrix<double, 5, 1>* jtr) {
    double cost = 0;
    if (jtj) jtj->setZero();
    if (jtr) jtr->setZero();
    const double inv2s2 = 1.0 / (2 * p(3) * p(3));
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double dx = x - p(0), dy = y - p(1), r2 = dx * dx + dy * dy;
        const double g = std::exp(-r2 * inv2s2);
        const double r = signal.at<float>(y, x) - (p(4) + p(2) * g);
        cost += r * r;
        if (!jtj) continue;
        Eigen::Matrix<double, 5, 1> j;  // d model / d parameter
        // Sigma and the constant stay fixed (the background is already removed, the
        // spot size known): freeing them measured worse on noisy spots.
        j << p(2) * g * dx / (p(3) * p(3)), p(2) * g * dy / (p(3) * p(3)), g, 0.0, 0.0;
        *jtj += j * j.transpose();
        *jtr += j * r;
      }
    return cost;
  };
  double lambda = 1e-3;
  Eigen::Matrix<double, 5, 5> jtj;
  Eigen::Matrix<double, 5, 1> jtr;
  double cost = residuals(q, &jtj, &jtr);
  for (int it = 0; it < 30; ++it) {
    Eigen::Matrix<double, 5, 5> a = jtj;
    a.diagonal() *= 1 + lambda;
    a(3, 3) = a(4, 4) = 1.0;
    const Eigen::Matrix<double, 5, 1> step = a.ldlt().solve(jtr);
    if (!step.allFinite()) return;
    const Eigen::Matrix<double, 5, 1> trial = q + step;
    if (trial(3) <= 0.1) {
      lambda *= 10;
      continue;
    }
    const double c = residuals(trial, nullptr, nullptr);
    if (c < cost) {
      q = trial;
      lambda = std::max(1e-7, lambda / 10);
      const bool done = step.head<2>().norm() < 1e-4;
      cost = residuals(q, &jtj, &jtr);
      if (done) break;
    } else {
      lambda *= 10;
      if (lambda > 1e8) break;
    }
  }
  if (std::hypot(q(0) - d.x, q(1) - d.y) > 1.5 || q(2) <= 0 || q(3) < 0.3 * sigma0 || q(3) > 4 * sigma0) return;
  d.x = q(0);
  d.y = q(1);
}

/// Sub-pixel centre by an iterated intensity-weighted centroid around `d`: of
/// `zero_mean` (the signal before clipping at zero, whose noise averages out) under
/// the Gaussian mask, of `signal` (clipped) under the disc.
void refineCentre(const cv::Mat& signal, const cv::Mat& zero_mean, const DetectOptions& o, Detection& d) {
  if (o.refinement == Refinement::intensity || o.refinement == Refinement::gaussian) {
    // Gaussian-masked intensity centroid (Thompson, Larson & Webb 2002): the mask is
    // re-centred on the current sub-pixel estimate each iteration, which removes the
    // bias a fixed pixel window has for symmetric spots.
    const double sm = o.refine_sigma > 0 ? o.refine_sigma : std::max(1.0, 0.5 * o.refine_radius);
    const int r = std::max(3, static_cast<int>(std::ceil(3 * sm)));  // the mask is < 1.2 % of its peak beyond 3 sigma
    // The mask is separable: exp(-(dx^2 + dy^2) / 2 s^2) = ex(dx) ey(dy).
    if (2 * r + 1 > 64) return;
    float ex[64], ey[64];
    // Over-relaxed iteration: the masked centroid of a Gaussian spot (sigma s, blurred by
    // b) under a mask of sigma m moves a fraction 1 - k of the way to the centre, with
    // k = m^2 / (m^2 + s^2 + b^2) (s = m here); stepping 1 / (1 - k) of the move reaches
    // the same fixed point in far fewer iterations.
    const double omega = 1.0 / (1.0 - sm * sm / (2 * sm * sm + o.blur_sigma * o.blur_sigma));
    const double a = 1 / (2 * sm * sm), c = std::exp(-2 * a);
    for (int it = 0; it < 20; ++it) {
      const int cx = static_cast<int>(std::lround(d.x)), cy = static_cast<int>(std::lround(d.y));
      gaussianRow(ex, 2 * r + 1, cx - r, d.x, a, c);
      gaussianRow(ey, 2 * r + 1, cy - r, d.y, a, c);
      double sw = 0, sx = 0, sy = 0;
      maskedSums(zero_mean, cx, cy, r, ex, ey, sw, sx, sy);
      if (sw <= 0) break;
      const double nx = d.x + omega * (cx + sx / sw - d.x), ny = d.y + omega * (cy + sy / sw - d.y);
      const bool done = (nx - d.x) * (nx - d.x) + (ny - d.y) * (ny - d.y) < 1e-6;
      d.x = nx;
      d.y = ny;
      if (done) break;
    }
    if (o.refinement == Refinement::gaussian) fitGaussian(zero_mean, sm, d);
  } else if (o.refinement == Refinement::disc) {
    // Flat disc of refine_radius on whole pixels (Crocker & Grier 1996): move the disc
    // to the nearest pixel of the centroid until the centroid stays within it.
    const int r = o.refine_radius;
    int cx = static_cast<int>(std::lround(d.x)), cy = static_cast<int>(std::lround(d.y));
    for (int it = 0; it < 10; ++it) {
      double sw = 0, sx = 0, sy = 0;
      for (int y = std::max(0, cy - r); y <= std::min(signal.rows - 1, cy + r); ++y)
        for (int x = std::max(0, cx - r); x <= std::min(signal.cols - 1, cx + r); ++x) {
          if ((x - cx) * (x - cx) + (y - cy) * (y - cy) > r * r) continue;
          const double w = std::max(0.0f, signal.at<float>(y, x));
          sw += w;
          sx += w * x;
          sy += w * y;
        }
      if (sw <= 0) break;
      d.x = sx / sw;
      d.y = sy / sw;
      const int nx = static_cast<int>(std::lround(d.x)), ny = static_cast<int>(std::lround(d.y));
      if (nx == cx && ny == cy) break;
      cx = nx;
      cy = ny;
    }
  }
}

/// The element nth_element would put at v.size() / 2 (v not empty), found through a
/// histogram of the values: only the values in the median's bin are partially sorted.
float middleElement(const std::vector<float>& v) {
  const std::size_t k = v.size() / 2, m = v.size();
  // Extremes and bins 4 values at a time; the counts in 4 interleaved histograms (no
  // increment waits for the one before).
  std::size_t i = 0;
  cv::v_float32x4 lo4 = cv::v_setall_f32(v[0]), hi4 = lo4;
  for (; i + 4 <= m; i += 4) {
    const cv::v_float32x4 x = cv::v_load(v.data() + i);
    lo4 = cv::v_min(lo4, x);
    hi4 = cv::v_max(hi4, x);
  }
  float lo = cv::v_reduce_min(lo4), hi = cv::v_reduce_max(hi4);
  for (; i < m; ++i) {
    lo = std::min(lo, v[i]);
    hi = std::max(hi, v[i]);
  }
  constexpr int kBins = 1024;
  thread_local std::vector<float> in_bin;
  if (!(hi > lo) || !std::isfinite(hi - lo)) {
    in_bin.assign(v.begin(), v.end());
    std::nth_element(in_bin.begin(), in_bin.begin() + static_cast<std::ptrdiff_t>(k), in_bin.end());
    return in_bin[k];
  }
  const float scale = (kBins - 1) / (hi - lo);
  auto bin = [&](float x) { return std::clamp(static_cast<int>((x - lo) * scale), 0, kBins - 1); };
  thread_local std::vector<int> bins;
  bins.resize(m);
  {
    const cv::v_float32x4 vlo = cv::v_setall_f32(lo), vscale = cv::v_setall_f32(scale);
    const cv::v_int32x4 zero = cv::v_setzero_s32(), top = cv::v_setall_s32(kBins - 1);
    for (i = 0; i + 4 <= m; i += 4)
      cv::v_store(bins.data() + i, cv::v_min(cv::v_max(cv::v_trunc((cv::v_load(v.data() + i) - vlo) * vscale), zero), top));
    for (; i < m; ++i) bins[i] = bin(v[i]);
  }
  std::array<std::array<std::size_t, 4>, kBins> counts{};
  for (i = 0; i + 4 <= m; i += 4) {
    ++counts[bins[i]][0];
    ++counts[bins[i + 1]][1];
    ++counts[bins[i + 2]][2];
    ++counts[bins[i + 3]][3];
  }
  for (; i < m; ++i) ++counts[bins[i]][0];
  auto count = [&](int b) { return counts[b][0] + counts[b][1] + counts[b][2] + counts[b][3]; };
  std::size_t below = 0;
  int b = 0;
  while (below + count(b) <= k) below += count(b++);
  // Bins are monotone in the value, so the median is the (k - below)-th of bin b's values.
  in_bin.clear();
  for (i = 0; i < m; ++i)
    if (bins[i] == b) in_bin.push_back(v[i]);
  std::nth_element(in_bin.begin(), in_bin.begin() + static_cast<std::ptrdiff_t>(k - below), in_bin.end());
  return in_bin[k - below];
}

/// Seeds from contours of the thresholded signal (the paper's pipeline).
std::vector<Detection> contourSeeds(const cv::Mat& smooth, double floor_level, const DetectOptions& o) {
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
    out.push_back(d);
  }
  return out;
}

/// Seeds at local maxima of the smoothed signal, at least `separation` apart.
std::vector<Detection> peakSeeds(const cv::Mat& smooth, double floor_level, const DetectOptions& o) {
  const int sep = o.separation > 0 ? o.separation : std::max(1, o.refine_radius);
  double level = std::max(o.min_contrast, floor_level);
  if (o.min_percentile > 0) {
    // trackpy's `percentile`: maxima below this percentile of the band-passed frame's
    // pixels are background texture, not features (crowded frames raise it).
    thread_local std::vector<float> all;
    all.assign(smooth.begin<float>(), smooth.end<float>());
    const auto k = static_cast<std::ptrdiff_t>(std::min(o.min_percentile / 100.0, 1.0) * static_cast<double>(all.size() - 1));
    std::nth_element(all.begin(), all.begin() + k, all.end());
    level = std::max(level, static_cast<double>(all[static_cast<std::size_t>(k)]));
  }
  if (o.threshold == ThresholdMode::manual) level = std::max(level, o.threshold_value);
  // Maxima of the square inscribed in the disc of radius `sep` (clipped to the frame); the
  // greedy suppression below then enforces the round distance. Only pixels above `level`
  // (a few percent of the frame) have their square searched: cheaper than a dilation.
  const int half = std::max(1, static_cast<int>(sep / std::sqrt(2.0)));
  struct Peak {
    int x, y;
    float v;
  };
  thread_local std::vector<Peak> peaks;
  peaks.clear();
  // v > level in float: v > lf for the largest float lf <= level (exactly the same test).
  float lf = static_cast<float>(level);
  if (static_cast<double>(lf) > level) lf = std::nextafter(lf, -std::numeric_limits<float>::infinity());
  const int cols = smooth.cols;
  const cv::v_float32x4 vl = cv::v_setall_f32(lf);
  for (int y = 0; y < smooth.rows; ++y) {
    const float* s = smooth.ptr<float>(y);
    const int y0 = std::max(0, y - half), y1 = std::min(smooth.rows - 1, y + half);
    // A pixel above the level and not below its row neighbours (few: tested 4 at a time)
    // has its whole square searched.
    auto consider = [&](int x) {
      const float v = s[x];
      // Column neighbours next (cheap rejections), then the whole square.
      if ((y > 0 && smooth.ptr<float>(y - 1)[x] > v) || (y + 1 < smooth.rows && smooth.ptr<float>(y + 1)[x] > v)) return;
      const int x0 = std::max(0, x - half), x1 = std::min(cols - 1, x + half);
      bool top = true;
      for (int yy = y0; yy <= y1 && top; ++yy) {
        const float* q = smooth.ptr<float>(yy);
        for (int xx = x0; xx <= x1; ++xx) top = top && !(q[xx] > v);
      }
      if (top) peaks.push_back({x, y, v});
    };
    auto scalar = [&](int x) {
      if (s[x] > lf && !(x > 0 && s[x - 1] > s[x]) && !(x + 1 < cols && s[x + 1] > s[x])) consider(x);
    };
    int x = 0;
    for (; x < std::min(1, cols); ++x) scalar(x);
    for (; x + 5 <= cols; x += 4) {
      if (x % 16 == 0 && x + 17 <= cols &&
          !cv::v_check_any(cv::v_max(cv::v_max(cv::v_load(s + x), cv::v_load(s + x + 4)), cv::v_max(cv::v_load(s + x + 8), cv::v_load(s + x + 12))) > vl)) {
        x += 12;  // 16 pixels below the level
        continue;
      }
      const cv::v_float32x4 v = cv::v_load(s + x);
      int bits = cv::v_signmask((v > vl) & (v >= cv::v_load(s + x - 1)) & (v >= cv::v_load(s + x + 1)));
      for (int k = 0; bits; ++k, bits >>= 1)
        if (bits & 1) consider(x + k);
    }
    for (; x < cols; ++x) scalar(x);
  }
  // Flat tops give several equal maxima: keep the first of any group closer than `sep`.
  std::sort(peaks.begin(), peaks.end(), [](const Peak& a, const Peak& b) { return a.v > b.v; });
  // A peak is taken when it lies in the disc that cv::circle fills around a kept peak
  // (drawn once here; kept peaks found through a grid of cell `sep`).
  thread_local cv::Mat stamp;
  stamp.create(2 * sep + 1, 2 * sep + 1, CV_8U);
  stamp.setTo(0);
  cv::circle(stamp, {sep, sep}, sep, cv::Scalar(1), -1);
  const int gw = smooth.cols / sep + 1, gh = smooth.rows / sep + 1;
  thread_local std::vector<int> head, chain;
  thread_local std::vector<Peak> kept;
  head.assign(static_cast<std::size_t>(gw) * gh, -1);
  chain.clear();
  kept.clear();
  auto taken = [&](const Peak& p) {
    const int gx = p.x / sep, gy = p.y / sep;
    for (int cy = std::max(0, gy - 1); cy <= std::min(gh - 1, gy + 1); ++cy)
      for (int cx = std::max(0, gx - 1); cx <= std::min(gw - 1, gx + 1); ++cx)
        for (int k = head[cy * gw + cx]; k >= 0; k = chain[k]) {
          const int dx = p.x - kept[k].x, dy = p.y - kept[k].y;
          if (std::abs(dx) <= sep && std::abs(dy) <= sep && stamp.at<unsigned char>(dy + sep, dx + sep)) return true;
        }
    return false;
  };
  std::vector<Detection> out;
  for (const auto& p : peaks) {
    if (taken(p)) continue;
    const int cell = (p.y / sep) * gw + p.x / sep;
    chain.push_back(head[cell]);
    head[cell] = static_cast<int>(kept.size());
    kept.push_back(p);
    Detection d;
    d.x = p.x;
    d.y = p.y;
    // Area: pixels within the separation above half the peak (the spot's FWHM area).
    int area = 0;
    const int x0 = std::max(0, p.x - sep), x1 = std::min(smooth.cols - 1, p.x + sep);
    for (int y = std::max(0, p.y - sep); y <= std::min(smooth.rows - 1, p.y + sep); ++y) {
      const float* row = smooth.ptr<float>(y);
      for (int x = x0; x <= x1; ++x) area += row[x] >= 0.5f * p.v;
    }
    d.area = area;
    if (d.area < o.min_area || d.area > o.max_area) continue;
    out.push_back(d);
  }
  return out;
}

/// Smallest normalised cross-correlation of a ring detection with the ring's profile.
constexpr double kMinRingMatch = 0.5;

/// Ring colloids: the matched filter's response (zero-mean kernel: the illumination
/// level and linear gradients cancel) holds one bright peak per ring at its centre;
/// peaks are found there, the centre refined by radial symmetry on the frame.
std::vector<Detection> detectRings(const cv::Mat& frame, const cv::Mat& background, const DetectOptions& o) {
  const double radius = o.ring_radius_px > 0 ? o.ring_radius_px : o.refine_radius;
  const cv::Mat kernel = o.ring_kernel.empty() ? ringKernel({}, radius) : o.ring_kernel;
  cv::Mat signal, response, smooth;
  if (background.empty()) frame.convertTo(signal, CV_32F);
  else cv::subtract(frame, background, signal, cv::noArray(), CV_32F);
  cv::filter2D(signal, response, CV_32F, kernel, cv::Point(-1, -1), 0, cv::BORDER_REFLECT);
  DetectOptions r = o;
  r.blur_sigma = 0;          // the filter has smoothed at the ring's scale
  r.local_background = 0;
  r.deblend = false;         // the response's peaks are not Gaussian spots
  r.max_size_ratio = 0;
  // Two rings' centres are at least a ring diameter apart (they do not overlap); nearer
  // maxima are the filter's side lobes.
  r.separation = std::max(o.separation, static_cast<int>(std::lround(2 * radius)));
  r.refine_radius = std::max(2, static_cast<int>(std::lround(0.5 * radius)));
  r.refine_sigma = 0;
  r.min_area = std::min(o.min_area, 1.0);
  r.max_area = std::max(o.max_area, 4 * M_PI * radius * radius);
  r.ring_kernel = cv::Mat();
  std::vector<Detection> found = detect(response, {}, Polarity::bright, r);
  // Shape test: the normalised cross-correlation of the window with the ring (Lewis 1995,
  // "Fast normalized cross-correlation", Vision Interface): the response over the
  // kernel's norm and the window's standard deviation about its own mean. Static specks,
  // edges and noise correlate weakly with a ring; rings near 1.
  const int k = kernel.rows / 2;
  cv::Mat disc(kernel.size(), CV_32F, cv::Scalar(0));
  cv::circle(disc, {k, k}, k, cv::Scalar(1), -1);
  const double n_disc = cv::sum(disc)[0], kernel_norm = std::sqrt(kernel.dot(kernel));
  std::erase_if(found, [&](const Detection& d) {
    const int cx = std::clamp(static_cast<int>(std::lround(d.x)), 0, signal.cols - 1), cy = std::clamp(static_cast<int>(std::lround(d.y)), 0, signal.rows - 1);
    double s1 = 0, s2 = 0;
    for (int y = -k; y <= k; ++y)
      for (int x = -k; x <= k; ++x) {
        if (disc.at<float>(y + k, x + k) == 0) continue;
        const double v = signal.at<float>(cv::borderInterpolate(cy + y, signal.rows, cv::BORDER_REFLECT), cv::borderInterpolate(cx + x, signal.cols, cv::BORDER_REFLECT));
        s1 += v;
        s2 += v * v;
      }
    const double spread = std::sqrt(std::max(0.0, s2 - s1 * s1 / n_disc));
    const double ncc = spread > 0 ? response.at<float>(cy, cx) / (kernel_norm * spread) : 0.0;
    return ncc < kMinRingMatch;
  });
  cv::GaussianBlur(signal, smooth, cv::Size(0, 0), 1.0);
  for (Detection& d : found) {
    radialSymmetryCentre(smooth, radius, d);
    d.x = std::clamp(d.x, 0.0, signal.cols - 1.0);
    d.y = std::clamp(d.y, 0.0, signal.rows - 1.0);
  }
  return found;
}

}  // namespace

std::vector<Detection> detect(const cv::Mat& frame, const cv::Mat& background, Polarity polarity, const DetectOptions& o) {
  if (polarity == Polarity::automatic) polarity = guessPolarity(frame, background);
  if (polarity == Polarity::ring) return detectRings(frame, background, o);
  // Signal: how much darker (or brighter) than the background, >= 0.
  // Frame-sized buffers are per thread and reused from frame to frame.
  thread_local cv::Mat signal, local, smooth_buf;
  if (!background.empty()) {
    if (polarity == Polarity::dark) cv::subtract(background, frame, signal);
    else cv::subtract(frame, background, signal);
  } else {
    const double level = cv::mean(frame)[0];
    if (polarity == Polarity::dark) cv::subtract(cv::Scalar(level), frame, signal);
    else cv::subtract(frame, cv::Scalar(level), signal);
  }
  // The spots' quality is measured on the signal before the high-pass, which carves a
  // negative ring around every spot (measureSpot takes its own local background): with a
  // high-pass, `signal` is the high-passed image and `before_high_pass` the other buffer.
  thread_local cv::Mat signal_high_passed;
  cv::Mat before_high_pass;
  if (o.local_background > 0) {
    // Spatial high-pass: what is left of uneven illumination and slow background
    // drift varies over more than a particle; a boxcar mean wider than the particle removes it.
    cv::blur(signal, local, cv::Size(2 * o.local_background + 1, 2 * o.local_background + 1), cv::Point(-1, -1), cv::BORDER_REFLECT);
    cv::subtract(signal, local, signal_high_passed);
    before_high_pass = signal;
    cv::swap(signal, signal_high_passed);
  }
  if (o.blur_sigma > 0) cv::GaussianBlur(signal, smooth_buf, cv::Size(0, 0), o.blur_sigma);
  else signal.copyTo(smooth_buf);
  // Noise floor of the smoothed signal from its median absolute deviation (robust to the
  // particles themselves): nothing fainter than min_snr times it counts as a particle.
  double floor_level = 0, noise_std = 0;
  {
    thread_local std::vector<float> v;
    v.clear();
    const int step = std::max(1, static_cast<int>(smooth_buf.total() / 20000));
    const float* all = smooth_buf.ptr<float>();  // continuous: allocated by the blur or the copy
    v.resize((smooth_buf.total() + step - 1) / step);
    for (std::size_t i = 0, k = 0; i < smooth_buf.total(); i += step, ++k) v[k] = all[i];
    const double med = middleElement(v);
    for (auto& x : v) x = static_cast<float>(std::abs(x - med));
    noise_std = 1.4826 * middleElement(v);
    if (o.min_snr > 0) floor_level = med + o.min_snr * noise_std;
  }
  // The centroids are taken on the smoothed signal before clipping at zero (its noise
  // averages out); measured on the SNR 4 scene this localises as well as the raw signal
  // and keeps faint spots from jittering between frames.
  const cv::Mat& zero_mean = smooth_buf;
  // Pixel noise of that smoothed signal, the unit of the split test's residual sums (see
  // deblend): the robust std behind the floor above (the same image, so the same number).
  double noise = noise_std;
  thread_local cv::Mat clipped_buf;
  cv::max(smooth_buf, 0.0, clipped_buf);
  const cv::Mat& smooth = clipped_buf;
  std::vector<Detection> seeds = o.method == SeedMethod::peaks ? peakSeeds(smooth, floor_level, o) : contourSeeds(smooth, floor_level, o);
  DetectOptions refine = o;
  if (o.refine_sigma <= 0 && o.method == SeedMethod::peaks && !seeds.empty()) {
    // The spot's sigma from the median half-maximum area of the smoothed spots:
    // area = 2 pi ln2 (sigma^2 + blur^2) for a Gaussian spot.
    std::vector<double> areas;
    for (const auto& d : seeds) areas.push_back(d.area);
    std::nth_element(areas.begin(), areas.begin() + areas.size() / 2, areas.end());
    const double s2 = areas[areas.size() / 2] / (2 * M_PI * std::log(2.0)) - o.blur_sigma * o.blur_sigma;
    refine.refine_sigma = std::clamp(std::sqrt(std::max(s2, 0.0)), 0.8, std::max(1.0, 0.5 * o.refine_radius));
  }
  // The disc centroid and the mass are taken on the band-passed signal, as Crocker & Grier
  // (and trackpy) do; the Gaussian-masked centroid on the unsmoothed signal, whose spot
  // sigma the mask matches.
  for (Detection& d : seeds) refineCentre(smooth, zero_mean, refine, d);
  if (o.deblend && o.method == SeedMethod::peaks && (o.refinement == Refinement::intensity || o.refinement == Refinement::gaussian)) {
    const int sep = o.separation > 0 ? o.separation : std::max(1, o.refine_radius);
    const double sm = refine.refine_sigma > 0 ? refine.refine_sigma : std::max(1.0, 0.5 * o.refine_radius);
    deblend(zero_mean, sm, o.blur_sigma, std::max(o.min_contrast, floor_level), sep, noise, seeds);
  }
  double mass_floor = o.min_mass;
  if (o.min_mass_relative > 0) {
    double top = 0;
    cv::minMaxLoc(smooth, nullptr, &top);
    mass_floor = std::max(mass_floor, o.min_mass_relative * top);
  }
  std::vector<Detection> out;
  out.reserve(seeds.size());
  for (Detection d : seeds) {
    const int px = std::clamp(static_cast<int>(std::lround(d.x)), 0, signal.cols - 1);
    const int py = std::clamp(static_cast<int>(std::lround(d.y)), 0, signal.rows - 1);
    d.peak = smooth.at<float>(py, px);
    if (d.peak < o.min_contrast || d.peak < floor_level) continue;
    double mass = 0;
    const int r = o.refine_radius;
    for (int y = std::max(0, py - r); y <= std::min(signal.rows - 1, py + r); ++y) {
      // The disc's row: |x - px| <= w with w^2 <= r^2 - (y - py)^2.
      int w = 0;
      while ((w + 1) * (w + 1) + (y - py) * (y - py) <= r * r) ++w;
      const float* row = smooth.ptr<float>(y);
      for (int x = std::max(0, px - w); x <= std::min(signal.cols - 1, px + w); ++x) mass += row[x];
    }
    d.mass = mass;
    if (d.mass < mass_floor) continue;
    out.push_back(d);
  }
  // Quality of each spot, then the focus filter on it (SpotQuality.cpp).
  const double sigma0 = refine.refine_sigma > 0 ? refine.refine_sigma : std::max(1.0, 0.5 * o.refine_radius);
  const double pixel_noise = detail::pixelNoise(signal);
  thread_local cv::Mat quality_src;
  if (o.local_background > 0 && !out.empty()) {
    if (o.blur_sigma > 0) cv::GaussianBlur(before_high_pass, quality_src, cv::Size(0, 0), o.blur_sigma);
    else before_high_pass.copyTo(quality_src);
  }
  const cv::Mat& measured = o.local_background > 0 ? quality_src : zero_mean;
  // measureSpot reads a window and the rings around it (to r + 2 px of the centre, r the
  // window's first half-width) in two frame-sized images, mostly from beyond the L2 cache
  // (2 x 1 MB at 640 x 424 px): the next spot's rows are fetched while this one is measured.
  const int reach = std::max(2, static_cast<int>(std::ceil(3 * std::clamp(std::sqrt(sigma0 * sigma0 + o.blur_sigma * o.blur_sigma), 0.7, 12.0)))) + 2;
  auto prefetch = [&](const cv::Mat& img, const Detection& d) {
    if (img.type() != CV_32F) return;
    const int cx = static_cast<int>(std::lround(d.x)), cy = static_cast<int>(std::lround(d.y));
    const int x0 = std::max(0, cx - reach), x1 = std::min(img.cols - 1, cx + reach);
    if (x0 > x1) return;
    for (int y = std::max(0, cy - reach); y <= std::min(img.rows - 1, cy + reach); ++y) {
      const float* row = img.ptr<float>(y);
      for (int x = x0; x <= x1; x += 16) __builtin_prefetch(row + x);
      __builtin_prefetch(row + x1);
    }
  };
  for (std::size_t i = 0; i < out.size(); ++i) {
    if (i + 1 < out.size()) {
      prefetch(measured, out[i + 1]);
      prefetch(frame, out[i + 1]);
    }
    Detection& d = out[i];
    detail::measureSpot(measured, frame, sigma0, o.blur_sigma, pixel_noise, d);
    d.quality.mass = d.mass;
  }
  detail::focusFilter(out, o.max_size_ratio, o.blur_sigma);
  return out;
}

std::vector<Detection> detectStuck(const cv::Mat& background, Polarity polarity, const DetectOptions& o) {
  if (background.empty()) return {};
  const cv::Mat k = cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(o.stuck_kernel | 1, o.stuck_kernel | 1));
  cv::Mat hat;
  cv::morphologyEx(background, hat, polarity != Polarity::dark ? cv::MORPH_TOPHAT : cv::MORPH_BLACKHAT, k);
  // `hat` is the small-scale signal of the background; detect on it against a flat zero.
  DetectOptions d = o;
  d.threshold = ThresholdMode::otsu;
  d.method = SeedMethod::peaks;  // seeds apart even when two stuck particles touch; the area filter in runTracker drops grain residues
  d.deblend = false;
  d.local_background = 0;
  d.find_stuck = false;
  d.max_size_ratio = 0;  // the hat's residues are judged by runTracker against the moving spots
  // A stuck particle is a round spot no larger than the hat kernel; narrow grain
  // tips and corners also survive the hat but are elongated or larger.
  d.max_area = std::min(o.max_area, 0.6 * M_PI * 0.25 * o.stuck_kernel * o.stuck_kernel);
  d.min_circularity = std::max(o.min_circularity, 0.7);
  const cv::Mat flat = cv::Mat::zeros(background.size(), CV_32F);
  // Faint round residues of grain edges survive the hat too: runTracker keeps only
  // spots as large and as dark as the moving particles.
  return detect(flat + hat, flat, Polarity::bright, d);
}

Polarity parsePolarity(const std::string& s) {
  if (s == "dark") return Polarity::dark;
  if (s == "bright") return Polarity::bright;
  if (s == "auto") return Polarity::automatic;
  if (s == "ring") return Polarity::ring;
  throw std::invalid_argument("polarity");
}
std::string polarityName(Polarity p) {
  switch (p) {
    case Polarity::dark: return "dark";
    case Polarity::bright: return "bright";
    case Polarity::ring: return "ring";
    case Polarity::automatic: break;
  }
  return "auto";
}
BackgroundMode parseBackgroundMode(const std::string& s) {
  if (s == "auto") return BackgroundMode::automatic;
  if (s == "median") return BackgroundMode::median;
  if (s == "none") return BackgroundMode::none;
  throw std::invalid_argument("detect.background");
}
std::string backgroundModeName(BackgroundMode m) {
  return m == BackgroundMode::median ? "median" : m == BackgroundMode::none ? "none" : "auto";
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
  if (s == "disc") return Refinement::disc;
  if (s == "gaussian") return Refinement::gaussian;
  throw std::invalid_argument("refinement");
}
SeedMethod parseSeedMethod(const std::string& s) {
  if (s == "contours") return SeedMethod::contours;
  if (s == "peaks") return SeedMethod::peaks;
  throw std::invalid_argument("detect.method");
}

}  // namespace mmval::tracking
