// The pore flow of synthetic videos (`mmval synth --geometry`) as a velocity
// field: mmval's Stokes solve through the grain image (PoreFlowMap), in the form
// tracking's flow scene takes (mmval/tracking/SynthScenes.hpp, SynthFlowSolver),
// so that neither library includes the other.
#pragma once
#include <functional>

#include <opencv2/core.hpp>

namespace mmval::simulate {

/// Solves the Stokes flow through `grains` (CV_8U, non-zero = grain) and returns its velocity
/// in px per frame at image position (x, y) px, y down, scaled to a mean pore speed of
/// `mean_speed_px_per_frame` (PoreFlowMap.hpp states the model and the grid). The field owns
/// the solution. Throws std::runtime_error when no pore path crosses the image from left to right.
std::function<cv::Point2d(double, double)> synthPoreFlow(const cv::Mat& grains, double mean_speed_px_per_frame);

}  // namespace mmval::simulate
