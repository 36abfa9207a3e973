// A microscope-like video of given trajectories: the simulation seen through
// a camera. The grains of the geometry image are drawn dark on bright glass,
// each particle as a dark Gaussian spot, with camera noise at a chosen SNR.
// Tracking such a video and comparing the tracks with the trajectories that
// made it measures what the experiment's processing does to every metric.
#pragma once
#include <cstdint>
#include <filesystem>

#include <opencv2/core.hpp>

#include "mmval/core/Tracks.hpp"

namespace mmval::tracking {

struct RenderOptions {
  double scale = 1.0;        ///< video pixels per geometry pixel
  double spot_sigma = 1.3;   ///< px of the video (optics: a particle is a blurred spot)
  double amplitude = 0.35;   ///< spot depth, fraction of full scale
  double snr = 8;            ///< amplitude over the camera noise std
  std::uint64_t seed = 1;
};

struct RenderedVideo {
  Tracks truth;    ///< the trajectories in the video's pixels (x_px, y_px) and metres; frames are video frames
  int frames = 0;
  double fps = 0;  ///< from the trajectories' time step
};

/// Renders `dir`/frames/frame_NNNNN.png for every output step of `tracks`, from step 0
/// when the steps are on the clock t = step * dt (so video frame k is step k, at the same
/// time), else from the first step written
/// (positions x_px, y_px in pixels of `grains` from the first pixel's centre,
/// y down; CV_8U, non-zero =
/// grain). `geometry_pixel` is the size of one geometry pixel, m. Throws
/// std::invalid_argument if the tracks have no pixel columns or fewer than
/// two time steps.
RenderedVideo renderTracksVideo(const Tracks& tracks, const cv::Mat& grains, double geometry_pixel, const RenderOptions& options,
                                const std::filesystem::path& dir);

}  // namespace mmval::tracking
