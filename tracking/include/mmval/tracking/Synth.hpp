// A synthetic micromodel video with ground truth, the tracker's independent
// reference: static grains, Gaussian-spot particles carried by potential
// flow around the grains (or a given flow), some particles stuck from the
// start, some that deposit (stop) during the video, particles entering at the
// inlet as others leave, optional Brownian motion, defocus (a spread of spot
// sizes at constant integrated brightness), an illumination gradient, and
// camera noise: Gaussian read noise at a chosen SNR plus optional Poisson shot
// noise. Deterministic per seed; options left at their defaults draw no
// random numbers, so older videos are reproduced exactly.
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/core/Tracks.hpp"

namespace mmval::tracking {

struct SynthOptions {
  int width = 320, height = 240, frames = 60;
  double fps = 10;
  double pixel_size = 1e-6;    ///< m per px (for the truth's micrometre columns)
  int particles = 40;          ///< moving particles present at any time
  int immobile = 4;            ///< stuck to the glass from the start
  double deposit_fraction = 0.15;  ///< moving particles that stop at a random time
  int grains = 10;
  double grain_radius = 14;    ///< px
  double speed = 3.0;          ///< px per frame, mean flow
  double spot_sigma = 1.3;     ///< px
  double spot_amplitude = 0.35;
  double noise = 0.015;        ///< std of the camera noise, fraction of full scale
  double snr = 0;              ///< > 0: noise = spot_amplitude / snr (overrides `noise`)
  double photons = 0;          ///< > 0: Poisson shot noise with this many photons at full scale
  double illumination_gradient = 0;  ///< brightness falls linearly by this fraction from left to right edge
  double brownian_d = 0;       ///< px^2 per frame: each step adds N(0, 2 D) per axis (2D Brownian motion)
  double defocus = 0;          ///< spot sigma drawn in [1, 1 + defocus] x spot_sigma, amplitude scaled by 1/sigma^2
  bool dark_particles = true;
  std::uint64_t seed = 1;
  /// Optional pore geometry (CV_8U, non-zero = grain); sets the frame size and
  /// replaces the random disc grains.
  cv::Mat geometry;
  /// Optional flow (px per frame at (x, y) in px); default: potential flow of
  /// `speed` past the disc grains.
  std::function<cv::Point2d(double, double)> flow;
};

struct SynthResult {
  Tracks truth;                 ///< positions in px (x_px, y_px) and m
  std::vector<std::string> frames;  ///< written frame files
  std::vector<std::int64_t> immobile_ids;  ///< particles stuck from the start
  int deposited = 0, immobile = 0, moving = 0;
};

/// Writes frames/frame_NNNNN.png and truth.csv into `dir`.
SynthResult writeSyntheticVideo(const SynthOptions& options, const std::filesystem::path& dir);

}  // namespace mmval::tracking
