// One comparison scene: the geometry mask, how the experiment's camera frame
// sits on it (registration or the window given), and the comparison itself.
// Both `mmval compare` and the compare-tracks case kind go through here.
#pragma once
#include <filesystem>
#include <optional>

#include <opencv2/core.hpp>

#include "mmval/compare/Compare.hpp"
#include "mmval/compare/Regions.hpp"
#include "mmval/compare/Registration.hpp"

namespace mmval::compare {

struct SceneSpec {
  std::filesystem::path mask;        ///< geometry mask; empty: no regions, no registration
  double mask_pixel_size = 0;        ///< m per mask pixel (required with a mask)
  bool grains_dark = true;
  bool y_up = true;                  ///< simulation y runs up the image (as mmval's solver reads masks)
  std::optional<cv::Rect> crop;      ///< window of the mask the simulation used (not with registration)
  std::filesystem::path register_frame;  ///< first frame / background image to register to the mask
  double frame_pixel_size = 0;       ///< m; 0: from the experiment tracks (x_um / x), else the mask's
  RegistrationOptions registration;
  struct Window {
    double origin_x = 0, origin_y = 0;  ///< m: the frame's pixel (0, 0) in the simulation frame
    double angle = 0;                   ///< rad, counter-clockwise
    double pixel_size = 0;              ///< m
  };
  std::optional<Window> window;      ///< the imaged window given directly
  bool regions = true;               ///< classify bodies / throats when a mask is given
  RegionOptions region_options;
};

/// Puts the experiment into the simulation frame (registration or window; as
/// it is when neither is given), classifies the mask's pore space and compares.
/// Throws InputError for inconsistent specs (both registration and window,
/// registration without a mask, a mask without a pixel size) and when the
/// registration fails.
Comparison compareScene(const Tracks& experiment, const Tracks& simulation, const SceneSpec& spec, CompareOptions options);

/// Pixel size of a tracks file from its micrometre and pixel columns (median
/// of x_um / x over points with both); 0 when it has no pixel columns.
double pixelSizeOf(const Tracks& tracks);

}  // namespace mmval::compare
