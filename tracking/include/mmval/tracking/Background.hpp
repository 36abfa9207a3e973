// Static background of a microscope video: grains, the chip and stuck particles
// do not move, so a per-pixel quantile of frames spread over time holds them and
// not the particles passing by (the median when particles cover a pixel less than
// half the time; a higher quantile for dark particles in dense flows, a lower one
// for bright particles). Long videos drift (illumination, focus, deposits
// building up): the rolling background takes the quantile per block of frames and
// gives each frame the blend of the two nearest blocks.
#pragma once
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/tracking/Frames.hpp"

namespace mmval::tracking {

/// Per-pixel q-quantile (0 <= q <= 1) of float frames of one size: the value of rank
/// floor(q n) (clamped to n - 1) of each pixel's n samples; q = 0.5 is the (upper) median.
cv::Mat quantileOfFrames(const std::vector<cv::Mat>& frames, double q);

struct RollingBackground {
  std::vector<int> centres;          ///< input frame index at the middle of each block
  std::vector<cv::Mat> backgrounds;  ///< one per block (float)
  /// The background of input frame `index`: linear blend of the two blocks whose centres
  /// bracket it (the first or last block beyond them). Empty when there are no blocks.
  cv::Mat at(int index) const;
};

/// Positions (in a selected range of `count` frames) of the frames each block of `window`
/// frames samples: up to `samples`, stride max(1, window / samples) from the block's
/// first frame. Throws std::invalid_argument unless window, samples >= 1.
std::vector<std::vector<int>> rollingSamplePositions(int count, int window, int samples);

/// Blocks of `window` frames of the source's selected range; each block's background is
/// the q-quantile of the frames rollingSamplePositions() picks (all of them when the
/// block is shorter). Only those frames are decoded (FrameSource::sample, which keeps
/// them for the main pass while its cache has room); next()'s position is unchanged.
RollingBackground rollingBackground(FrameSource& source, int window, int samples, double q);

}  // namespace mmval::tracking
