// Pore flow for synthetic videos (`synth --geometry`): Stokes flow through a
// grain image from mmval's fluid solver, sampled in pixels per frame.
#pragma once
#include <opencv2/core.hpp>

namespace mmval::simulate {

class PoreFlowMap {
 public:
  /// grains: 8-bit image, non-zero = grain. The image and its mirror side by
  /// side make the domain periodic along x (no inlet or outlet artefacts);
  /// no-slip walls at the top and bottom edges. Solved on a grid a few pixels
  /// coarse (<= ~40,000 cells), cell-centred velocities sampled bilinearly and
  /// scaled so the mean pore speed is `mean_speed` px per frame. Pores that no
  /// flow path reaches stand still. Throws std::runtime_error when no pore path
  /// crosses the image from left to right.
  PoreFlowMap(const cv::Mat& grains, double mean_speed);
  /// Velocity at (x, y), image pixels (y down), px per frame.
  cv::Point2d at(double x, double y) const;

 private:
  cv::Point2d raw(double x, double y) const;
  int m_w, m_h, m_f = 1;
  cv::Mat m_u, m_v;  ///< cell-centred velocities, image orientation (row 0 at the top), CV_64F
  double m_scale = 0;
};

}  // namespace mmval::simulate
