#include "mmval/compare/Scene.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "mmval/compare/TrackChecks.hpp"
#include "mmval/core/Error.hpp"

namespace mmval::compare {

double pixelSizeOf(const Tracks& tracks) {
  std::vector<double> s;
  for (const auto& p : tracks.points) {
    if (std::isfinite(p.x_px) && std::abs(p.x_px) > 1.0) s.push_back(p.x / p.x_px);
    if (s.size() >= 1001) break;
  }
  if (s.empty()) return 0.0;
  std::nth_element(s.begin(), s.begin() + s.size() / 2, s.end());
  return s[s.size() / 2];
}

Comparison compareScene(const Tracks& experiment_in, const Tracks& simulation, const SceneSpec& spec, CompareOptions options) {
  // Cheap checks first: a degenerate file fails before a registration is attempted.
  checkComparable(experiment_in, "experiment");
  checkComparable(simulation, "simulation");
  const std::string where = spec.mask.empty() ? std::string("(scene)") : spec.mask.string();
  if (!spec.register_frame.empty() && spec.window)
    throw InputError({spec.register_frame.string(), 0, 0, "registration"}, "both a frame to register and the imaged window were given", {},
                     "one of the two: registration to the mask, or the window's origin, rotation and pixel size");
  if (!spec.register_frame.empty() && spec.mask.empty())
    throw InputError({spec.register_frame.string(), 0, 0, "mask"}, "a frame to register needs the geometry mask", {}, "the mask image as well");
  if (!spec.mask.empty() && !(spec.mask_pixel_size > 0))
    throw InputError({where, 0, 0, "mask pixel size"}, "the geometry mask needs its pixel size", {}, "a positive length per mask pixel");

  cv::Mat pore;
  MaskFrame frame;
  if (!spec.mask.empty()) {
    pore = readPoreMask(spec.mask, spec.grains_dark);
    if (spec.crop) {
      if (!spec.register_frame.empty())
        throw InputError({where, 0, 0, "crop"}, "a cropped mask cannot be registered to", {}, "registration to the whole mask, or the window given directly");
      if ((*spec.crop & cv::Rect(0, 0, pore.cols, pore.rows)) != *spec.crop || spec.crop->area() == 0)
        throw InputError({where, 0, 0, "crop"}, "the crop is not a window inside the mask", {},
                         fmt::format("[x, y, width, height] inside {} x {} px", pore.cols, pore.rows));
      pore = pore(*spec.crop).clone();
    }
    frame = MaskFrame{spec.mask_pixel_size, pore.rows, pore.cols, spec.y_up};
  }

  Tracks experiment = experiment_in;
  nlohmann::json alignment;
  cv::Mat registration_picture;
  const double tracks_px = pixelSizeOf(experiment_in);
  if (!spec.register_frame.empty()) {
    const double frame_px = spec.frame_pixel_size > 0 ? spec.frame_pixel_size : (tracks_px > 0 ? tracks_px : spec.mask_pixel_size);
    const RegistrationResult r = registerFiles(spec.register_frame, spec.mask, spec.registration, frame_px / spec.mask_pixel_size);
    const FrameToSimulation map = FrameToSimulation::fromRegistration(r, frame);
    experiment = applyToTracks(experiment_in, map, frame_px);
    alignment = map.details;
    alignment["frame"] = spec.register_frame.string();
    alignment["mask"] = spec.mask.string();
    alignment["frame_pixel_size_um"] = frame_px * 1e6;
    registration_picture = registrationOverlay(spec.register_frame, pore, r);
  } else if (spec.window) {
    const FrameToSimulation map = FrameToSimulation::fromWindow(spec.window->origin_x, spec.window->origin_y, spec.window->angle,
                                                                spec.window->pixel_size, spec.y_up);
    experiment = applyToTracks(experiment_in, map, tracks_px > 0 ? tracks_px : spec.window->pixel_size);
    alignment = map.details;
  } else {
    alignment = {{"method", "none: both files taken to be in the same frame"}};
  }
  options.alignment = alignment;

  std::optional<RegionMap> regions;
  if (!pore.empty() && spec.regions) {
    regions = classifyPoreSpace(pore, frame, spec.region_options);
    options.regions = &*regions;
  }
  Comparison c = compareTracks(experiment, simulation, options);
  c.registration_picture = registration_picture;
  if (alignment.contains("dx_px")) {
    // The fitted motion and its residual also as (informational) metrics, so reports and diffs show them.
    auto add = [&](const char* name, double value, const char* unit, const char* reason) {
      MetricResult m;
      m.name = name;
      m.value = value;
      m.unit = unit;
      m.reason = reason;
      c.metrics.push_back(m);
    };
    add("registration_dx", alignment["dx_um"].get<double>(), "um", "fitted shift of the frame in the mask frame, x (frame pixel -> mask pixel)");
    add("registration_dy", alignment["dy_um"].get<double>(), "um", "fitted shift, y (image rows, down)");
    add("registration_rotation", alignment["rotation_deg"].get<double>(), "deg", "fitted rotation, counter-clockwise in image axes");
    add("registration_ecc_correlation", alignment["ecc_correlation"].get<double>(), "1", "ECC correlation coefficient at the fit (1: perfect)");
    add("registration_rms_residual", alignment["rms_residual"].get<double>(), "1", "RMS of frame - (gain x registered mask + bias), grey levels in [0, 1]");
  }
  return c;
}

}  // namespace mmval::compare
