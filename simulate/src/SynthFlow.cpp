#include "mmval/simulate/SynthFlow.hpp"

#include <memory>

#include "mmval/simulate/PoreFlowMap.hpp"

namespace mmval::simulate {

std::function<cv::Point2d(double, double)> synthPoreFlow(const cv::Mat& grains, double mean_speed_px_per_frame) {
  // Shared: std::function copies its target, and every copy samples the same solution.
  auto flow = std::make_shared<const PoreFlowMap>(grains, mean_speed_px_per_frame);
  return [flow](double x, double y) { return flow->at(x, y); };
}

}  // namespace mmval::simulate
