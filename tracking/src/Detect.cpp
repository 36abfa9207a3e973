#include "mmval/tracking/Detect.hpp"

#include "SpotFit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

namespace mmval::tracking {

std::vector<cv::Mat> sampleFrames(FrameSource& source, int samples) {
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
  return frames;
}

namespace {

cv::Mat medianOfFrames(const std::vector<cv::Mat>& frames) {
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

}  // namespace

cv::Mat medianBackground(FrameSource& source, int samples) { return medianOfFrames(sampleFrames(source, samples)); }

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
  const cv::Mat bg = background.empty() ? medianOfFrames(frames) : background;
  std::vector<cv::Mat> fg(frames.size());
  std::vector<double> noise(frames.size());
  cv::Mat above(bg.size(), CV_32S, cv::Scalar(0)), below(bg.size(), CV_32S, cv::Scalar(0));
  for (std::size_t k = 0; k < frames.size(); ++k) {
    cv::Mat f;
    frames[k].convertTo(f, CV_32F);
    cv::GaussianBlur(f - bg, fg[k], cv::Size(0, 0), 1.0);
    std::vector<float> a(fg[k].begin<float>(), fg[k].end<float>());
    for (auto& v : a) v = std::abs(v);
    std::nth_element(a.begin(), a.begin() + a.size() / 2, a.end());
    noise[k] = std::max(1e-6, 1.4826 * a[a.size() / 2]);
    const float t = static_cast<float>(4 * noise[k]);
    for (int r = 0; r < bg.rows; ++r)
      for (int c = 0; c < bg.cols; ++c) {
        const float v = fg[k].at<float>(r, c);
        if (v > t) ++above.at<int>(r, c);
        if (v < -t) ++below.at<int>(r, c);
      }
  }
  const int persistent = std::max(1, static_cast<int>(frames.size()) / 4);
  double bright = 0, dark = 0;
  for (std::size_t k = 0; k < frames.size(); ++k)
    for (int r = 0; r < bg.rows; ++r)
      for (int c = 0; c < bg.cols; ++c) {
        const double v = fg[k].at<float>(r, c), t = 4 * noise[k];
        if (v > t && above.at<int>(r, c) <= persistent) bright += v - t;
        if (v < -t && below.at<int>(r, c) <= persistent) dark += -v - t;
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
    for (int it = 0; it < 20; ++it) {
      const int cx = static_cast<int>(std::lround(d.x)), cy = static_cast<int>(std::lround(d.y));
      gaussianRow(ex, 2 * r + 1, cx - r, d.x, 1 / (2 * sm * sm));
      gaussianRow(ey, 2 * r + 1, cy - r, d.y, 1 / (2 * sm * sm));
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
  if (o.threshold == ThresholdMode::manual) level = std::max(level, o.threshold_value);
  thread_local cv::Mat dil;
  // Maxima of the square inscribed in the disc of radius `sep` (a square dilation is
  // separable and fast); the greedy suppression below then enforces the round distance.
  const int half = std::max(1, static_cast<int>(sep / std::sqrt(2.0)));
  cv::dilate(smooth, dil, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(2 * half + 1, 2 * half + 1)));
  struct Peak {
    int x, y;
    float v;
  };
  std::vector<Peak> peaks;
  for (int y = 0; y < smooth.rows; ++y) {
    const float* s = smooth.ptr<float>(y);
    const float* m = dil.ptr<float>(y);
    for (int x = 0; x < smooth.cols; ++x)
      if (s[x] > level && s[x] >= m[x]) peaks.push_back({x, y, s[x]});
  }
  // Flat tops give several equal maxima: keep the first of any group closer than `sep`.
  std::sort(peaks.begin(), peaks.end(), [](const Peak& a, const Peak& b) { return a.v > b.v; });
  thread_local cv::Mat taken;
  taken.create(smooth.size(), CV_8U);
  taken.setTo(0);
  std::vector<Detection> out;
  for (const auto& p : peaks) {
    if (taken.at<unsigned char>(p.y, p.x)) continue;
    cv::circle(taken, {p.x, p.y}, sep, cv::Scalar(1), -1);
    Detection d;
    d.x = p.x;
    d.y = p.y;
    // Area: pixels within the separation above half the peak (the spot's FWHM area).
    for (int y = std::max(0, p.y - sep); y <= std::min(smooth.rows - 1, p.y + sep); ++y)
      for (int x = std::max(0, p.x - sep); x <= std::min(smooth.cols - 1, p.x + sep); ++x)
        if (smooth.at<float>(y, x) >= 0.5f * p.v) d.area += 1;
    if (d.area < o.min_area || d.area > o.max_area) continue;
    out.push_back(d);
  }
  return out;
}

}  // namespace

std::vector<Detection> detect(const cv::Mat& frame, const cv::Mat& background, Polarity polarity, const DetectOptions& o) {
  if (polarity == Polarity::automatic) polarity = guessPolarity(frame, background);
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
  if (o.local_background > 0) {
    // Spatial high-pass: what is left of uneven illumination and slow background
    // drift varies over more than a particle; a boxcar mean wider than the particle removes it.
    cv::blur(signal, local, cv::Size(2 * o.local_background + 1, 2 * o.local_background + 1), cv::Point(-1, -1), cv::BORDER_REFLECT);
    cv::subtract(signal, local, signal);
  }
  if (o.blur_sigma > 0) cv::GaussianBlur(signal, smooth_buf, cv::Size(0, 0), o.blur_sigma);
  else signal.copyTo(smooth_buf);
  cv::Mat& smooth = smooth_buf;
  // Noise floor of the smoothed signal from its median absolute deviation (robust to the
  // particles themselves): nothing fainter than min_snr times it counts as a particle.
  double floor_level = 0, noise_std = 0;
  {
    thread_local std::vector<float> v;
    v.clear();
    const int step = std::max(1, static_cast<int>(smooth.total() / 20000));
    for (std::size_t i = 0; i < smooth.total(); i += step) v.push_back(smooth.at<float>(static_cast<int>(i)));
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    const double med = v[v.size() / 2];
    for (auto& x : v) x = static_cast<float>(std::abs(x - med));
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    noise_std = 1.4826 * v[v.size() / 2];
    if (o.min_snr > 0) floor_level = med + o.min_snr * noise_std;
  }
  // The centroids are taken on the smoothed signal before clipping at zero (its noise
  // averages out); measured on the SNR 4 scene this localises as well as the raw signal
  // and keeps faint spots from jittering between frames.
  thread_local cv::Mat zero_mean_buf;
  smooth.copyTo(zero_mean_buf);
  const cv::Mat& zero_mean = zero_mean_buf;
  // Pixel noise of that smoothed signal, the unit of the split test's residual sums (see
  // deblend): the robust std behind the floor above (the same image, so the same number).
  double noise = noise_std;
  cv::max(smooth, 0.0, smooth);
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
  std::vector<Detection> out;
  out.reserve(seeds.size());
  for (Detection d : seeds) {
    const int px = std::clamp(static_cast<int>(std::lround(d.x)), 0, signal.cols - 1);
    const int py = std::clamp(static_cast<int>(std::lround(d.y)), 0, signal.rows - 1);
    d.peak = smooth.at<float>(py, px);
    if (d.peak < o.min_contrast || d.peak < floor_level) continue;
    double mass = 0;
    const int r = o.refine_radius;
    for (int y = std::max(0, py - r); y <= std::min(signal.rows - 1, py + r); ++y)
      for (int x = std::max(0, px - r); x <= std::min(signal.cols - 1, px + r); ++x)
        if ((x - px) * (x - px) + (y - py) * (y - py) <= r * r) mass += smooth.at<float>(y, x);
    d.mass = mass;
    if (d.mass < o.min_mass) continue;
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
  d.method = SeedMethod::peaks;  // seeds apart even when two stuck particles touch; the area filter in runTracker drops grain residues
  d.deblend = false;
  d.local_background = 0;
  d.find_stuck = false;
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
