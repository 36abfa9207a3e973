// Particle detection, the paper's pipeline made configurable and measured:
// static background removal (temporal median), Gaussian blur, threshold
// (manual, Otsu or adaptive), morphology, contours with area / circularity
// filters, centroid from moments, and sub-pixel refinement by an
// intensity-weighted centroid on the unthresholded signal.
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/tracking/Frames.hpp"

namespace mmval::tracking {

enum class Polarity { dark, bright, automatic };
enum class ThresholdMode { manual, otsu, adaptive };
enum class Morphology { none, erode, dilate, open, close };
enum class Refinement { moments, intensity };

struct DetectOptions {
  bool subtract_background = true;  ///< temporal median of the video (grains and stuck particles vanish)
  int background_samples = 60;      ///< frames sampled for the median
  Polarity polarity = Polarity::automatic;
  double blur_sigma = 1.0;          ///< px; 0 disables
  ThresholdMode threshold = ThresholdMode::otsu;
  double threshold_value = 0.08;    ///< manual: fraction of full scale of the background-removed signal
  int adaptive_block = 31;          ///< px, odd
  double adaptive_offset = 0.04;    ///< fraction of full scale above the local mean
  Morphology morphology = Morphology::open;
  int kernel = 3;                   ///< px, odd
  int iterations = 1;
  double min_area = 3, max_area = 2000;  ///< px^2
  double min_circularity = 0.2;     ///< 4 pi A / P^2
  double min_contrast = 0.02;       ///< peak signal, fraction of full scale
  double min_snr = 5.0;             ///< peak above the frame's noise floor (robust std of the smoothed signal); 0 disables
  Refinement refinement = Refinement::intensity;
  bool find_stuck = false;          ///< also find particles stuck for the whole video in the median background (off: grain features can pass for particles)
  int stuck_kernel = 9;             ///< px: black/top-hat size, larger than a particle, smaller than a grain
  int refine_radius = 4;            ///< px, half window of the intensity-weighted centroid
};

struct Detection {
  double x = 0, y = 0;  ///< px; the centre of pixel (column i, row j) is (i, j)
  double area = 0;      ///< px^2 of the thresholded blob
  double mass = 0;      ///< integrated background-removed signal
  double peak = 0;      ///< peak signal
};

/// Temporal median of up to `samples` frames spread over the source (rewinds it).
cv::Mat medianBackground(FrameSource& source, int samples);

/// Dark or bright particles: the sign of the strongest deviations from the background.
Polarity guessPolarity(const cv::Mat& frame, const cv::Mat& background);

/// Particles in one frame (float grey in [0, 1]); `background` may be empty.
std::vector<Detection> detect(const cv::Mat& frame, const cv::Mat& background, Polarity polarity, const DetectOptions& options);

/// Particles that sit still for the whole video are part of the median
/// background: find them there as spots smaller than `stuck_kernel`
/// (morphological black-hat for dark particles, top-hat for bright ones).
std::vector<Detection> detectStuck(const cv::Mat& background, Polarity polarity, const DetectOptions& options);

Polarity parsePolarity(const std::string& s);
ThresholdMode parseThreshold(const std::string& s);
Morphology parseMorphology(const std::string& s);
Refinement parseRefinement(const std::string& s);

}  // namespace mmval::tracking
