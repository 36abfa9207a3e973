// Pore bodies and throats of a geometry mask, and particle speeds per region.
//
// Rule (documented in metrics.json too): the local pore width at a pore pixel
// is its local thickness, the diameter of the largest disc that fits in the
// pore space and covers the pixel (Hildebrand & Ruegsegger 1997, "A new method
// for the model-independent assessment of thickness in three-dimensional
// images", J. Microsc. 185(1)); a disc centred on pore pixel c has diameter
// 2 d(c), d the Euclidean distance transform (distance to the nearest grain
// pixel). A pore pixel whose local width is at or below the threshold is throat,
// the rest pore body. The default threshold is the median inscribed diameter
// 2 d along the medial axis (pixels where d is a local maximum), so narrow
// passages between grains are throats and the wide chambers bodies; corners
// of chambers, which only thin discs reach, count as throat as well.
#pragma once
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "mmval/compare/Registration.hpp"
#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::compare {

enum class Region : int { outside = -1, grain = 0, body = 1, throat = 2 };

struct RegionMap {
  cv::Mat label;        ///< CV_8U per mask pixel: 0 grain, 1 pore body, 2 throat
  cv::Mat width_px;     ///< CV_32F local pore width (mask pixels), 0 in grains
  double threshold_px = 0;  ///< throat at or below this width
  MaskFrame frame;
  std::string rule;
  /// Region of a point in the simulation frame (m).
  Region at(double x, double y) const;
  /// Colour picture: grains black, bodies blue, throats orange.
  cv::Mat picture() const;
};

struct RegionOptions {
  double throat_width = 0;  ///< m; 0: the median inscribed diameter along the medial axis
};

/// `pore`: CV_8U, non-zero in pore space (readPoreMask); `frame` gives its
/// pixel size and orientation. Throws InputError naming "pore mask" when it
/// holds no pore pixel.
RegionMap classifyPoreSpace(const cv::Mat& pore, const MaskFrame& frame, const RegionOptions& options = {});

struct RegionSpeeds {
  double body_mean = 0, throat_mean = 0;  ///< m/s, NaN with no step in the region
  int body_steps = 0, throat_steps = 0, grain_steps = 0, outside_steps = 0;
  nlohmann::json toJson() const;
};

/// Mean speed of the steps whose mid-point lies in each region.
RegionSpeeds regionSpeeds(const std::vector<tracking::Step>& steps, const RegionMap& map);

}  // namespace mmval::compare
