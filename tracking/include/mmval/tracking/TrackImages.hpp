// Pictures of a tracker run that people look at rather than read:
// the steps of every moving particle drawn over the background, coloured by
// speed, and the mean speed binned on the pore space. Both carry a colour bar
// with its scale in um/s.
#pragma once
#include <opencv2/core.hpp>

#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::tracking {

/// Each step of `stats` (mobile particles) as the segment it covers in one frame
/// interval (s), coloured by speed (viridis, 0 to the 99th percentile of the speeds),
/// over `base` (8-bit grey, e.g. the median background; dimmed). `pixel_size`: m per px.
cv::Mat velocityOverlay(const cv::Mat& base, const TrackStats& stats, double pixel_size, double frame_interval);

/// Mean step speed in square bins of `bin_px` pixels (by step midpoint), coloured on
/// the same scale, blended over `base`; bins without a step show the base only.
/// `counts` (optional) receives the steps per bin (CV_32S).
cv::Mat speedMap(const cv::Mat& base, const TrackStats& stats, double pixel_size, int bin_px, cv::Mat* counts = nullptr);

}  // namespace mmval::tracking
