// A synthetic brightfield video of ring-shaped colloids with ground truth: the
// stand-in for the class of real videos where a sphere of a few microns, seen
// slightly out of focus in transmitted light, images as a bright centre inside a
// dark ring with a faint bright halo outside (the sphere acts as a lens; the
// pattern is the Lorenz-Mie scattering image, Lee et al. 2007, Opt. Express
// 15:18275, whose radial profile oscillates about the background).
//
// Models, each stated:
// - Radial profile of one colloid (a phenomenological fit of that oscillating
//   pattern, not a Mie computation), relative to the local background b:
//     I(r) / b = 1 + C exp(-r^2 / (2 s_c^2)) - K exp(-(r - R)^2 / (2 w^2))
//                  + H exp(-(r - R - 2.5 w)^2 / (2 w^2))
//   centre brightening C, ring darkening K at the ring radius R with width w,
//   halo H just outside the ring.
// - Motion: 2D Brownian, exact Gaussian increments N(0, 2 D dt) per axis per
//   frame (D in px^2 per frame); the colloids stay in view (reflected at a
//   margin of 1.5 R from the edges) and do not overlap (a step that brings two
//   centres closer than 2.5 R is redrawn), so every frame holds all of them.
// - Illumination: b(x) = b0 (1 - g x / W), a linear gradient of g from the
//   left to the right edge; static features (dust on the optics): dark
//   Gaussian specks of sigma 3 px, fixed for the whole video.
// - Camera: Gaussian read noise of std `noise` (fraction of full scale).
#pragma once
#include <cstdint>
#include <filesystem>
#include <vector>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/Synth.hpp"

namespace mmval::tracking {

struct RingSceneOptions {
  int width = 256, height = 192, frames = 80;
  double fps_hz = 10;
  double pixel_size_um = 0.5;
  int particles = 5;
  double ring_radius_px = 7;        ///< R
  double ring_width_px = 1.3;       ///< w
  double centre_sigma_px = 2.0;     ///< s_c
  double centre_contrast = 0.35;    ///< C
  double ring_contrast = 0.45;      ///< K
  double halo_contrast = 0.10;      ///< H
  double diffusion_px2 = 0.5;       ///< D, px^2 per frame
  double background = 0.55;         ///< b0, fraction of full scale
  double illumination_gradient = 0.2;  ///< g
  int static_specks = 3;
  double speck_contrast = 0.25;     ///< darkening of a speck's centre, fraction of b
  double noise = 0.02;              ///< read noise std, fraction of full scale
  SynthFormat format = SynthFormat::png8;
  std::uint64_t seed = 1;
};

struct RingSceneResult {
  Tracks truth;                     ///< px (x_px, y_px) and m, every colloid in every frame
  std::vector<std::string> files;   ///< frame files, or the video
};

/// The radial profile above, I(r) / b - 1.
double ringProfile(const RingSceneOptions& o, double r_px);

/// Writes the frames (as o.format says), truth.csv (frame, particle, x, y in px, x_um,
/// y_um, t_s) and truth.json into `dir`. Throws std::invalid_argument for options out
/// of range (the message names the field).
RingSceneResult writeRingScene(const RingSceneOptions& o, const std::filesystem::path& dir);

}  // namespace mmval::tracking
