// Internal to mmval::tracking: the Gaussian-spot arithmetic shared by the centroid
// refinement (Detect.cpp) and the joint fit of overlapping spots (SpotFit.cpp).
#pragma once
#include <cmath>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking::detail {

/// out[k] = exp(-(first + k - mu)^2 a) for k < n by the recurrence of successive ratios
/// (two exponentials per row instead of n; relative error ~1e-15 per step).
/// `c` = exp(-2 a), hoisted by callers that build many rows with the same `a`.
template <class T>
void gaussianRow(T* out, int n, int first, double mu, double a, double c) {
  const double t0 = first - mu;
  double g = std::exp(-t0 * t0 * a), ratio = std::exp(-(2 * t0 + 1) * a);
  for (int k = 0; k < n; ++k) {
    out[k] = static_cast<T>(g);
    g *= ratio;
    ratio *= c;
  }
}
template <class T>
void gaussianRow(T* out, int n, int first, double mu, double a) {
  gaussianRow(out, n, first, mu, a, std::exp(-2 * a));
}

/// Columns of the fixed-width windows that SpotFit.cpp sums and updates 4 lanes at a time.
constexpr int kLanes = 16;

/// Sums of img x mask under the separable mask ex(x - cx + r) ey(y - cy + r) over the
/// window of half-width r (clipped to the image): weight, and weight x offset from (cx, cy).
/// Float within the window (exact to ~1e-7 relative).
void maskedSums(const cv::Mat& img, int cx, int cy, int r, const float* ex, const float* ey, double& sw, double& sx, double& sy);

/// Joint refinement of spots that overlap (a Gauss-Seidel least-squares fit of a sum of
/// Gaussian spots of sigma `sm`): each spot's Gaussian-masked centroid and amplitude are
/// taken on the signal minus its neighbours' current models, sweep after sweep. A lone
/// spot's masked centroid already is its least-squares position (Thompson, Larson & Webb
/// 2002); next to a neighbour it is pulled towards it by up to a pixel, which this removes.
/// Then spots hidden beside a brighter one (closer than the seeds' separation) are looked
/// for in the residual, pairs merged into one elongated blob are split when two spots fit
/// significantly better than one, and fits that merged are dropped.
/// The residual (signal minus every spot's model) is kept as an image and updated spot by
/// spot, with separable Gaussian tables, so a sweep costs O(spots x window).
///
/// `zero_mean`: the smoothed, unclipped signal; `sm`: the spots' sigma (px); `blur`: the
/// smoothing's sigma (px); `level`: the seeds' threshold on the smoothed signal; `sep`: the
/// seeds' separation (px); `noise`: the robust std of `zero_mean` (0: no split test).
/// Its stages and their numbers (window, reach, convergence, split test): DeblendTuning
/// (TrackerTuning.hpp).
void deblend(const cv::Mat& zero_mean, double sm, double blur, double level, int sep, double noise, std::vector<Detection>& dets);

// Per-detection quality (SpotQuality.cpp).

/// Per-pixel noise std of `img` (float): 1.4826 x the median |difference of horizontal
/// neighbours| / sqrt(2), which smooth structure (spots, illumination) barely moves.
double pixelNoise(const cv::Mat& img);

/// Fills d.quality but its mass: sigma, eccentricity and amplitude (signal) by adaptive
/// Gaussian-weighted moments of `zero_mean` (the smoothed, background-removed signal,
/// blurred by `blur` px) above the median of a ring around the spot; background: that
/// ring's median in `frame`; ep_px: the Cramer-Rao localisation uncertainty from the
/// amplitude, sigma and `pixel_noise` (the unsmoothed signal's per-pixel noise std).
/// `sigma0`: a first guess of the spot's sigma. Leaves d.quality unmeasured (NaN) when the
/// spot has no positive weight above its background.
void measureSpot(const cv::Mat& zero_mean, const cv::Mat& frame, double sigma0, double blur, double pixel_noise, Detection& d);

/// The half-sample mode of `v` (Bickel & Fruehwirth 2006); NaN when empty.
double halfSampleMode(std::vector<double> v);

/// The focus filter: drops detections whose sigma exceeds `max_ratio` x the half-sample
/// mode of the frame's sigmas by more than 3 x their ep_px (the sigma's standard error) and
/// that are round (eccentricity < 0.6) or dim (peak < 0.5 x the in-focus spots' median),
/// unless a detection that passes lies within 3 modal smoothed sigmas
/// (sqrt(mode^2 + blur^2)). Returns the mode; NaN (nothing dropped) when `max_ratio` <= 0
/// or fewer than kFocusMinSpots spots are measured.
double focusFilter(std::vector<Detection>& dets, double max_ratio, double blur);

}  // namespace mmval::tracking::detail
