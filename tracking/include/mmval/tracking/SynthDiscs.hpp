// A synthetic video of large bright-rimmed discs with ground truth: the stand-in for
// the class of the real discs video (PROVENANCE.md of the real videos: a monolayer of
// discs of radius ~40-60 px, each a thin bright rim around a darker interior, on a
// dark ground).
//
// Models, each stated:
// - One disc of radius R at distance d from its centre, brightness above the ground b:
//     I(d) = (I_in - b) S(R - d) + A exp(-(d - R + o)^2 / (2 s^2))
//   interior level I_in with an edge S smoothed over 0.5 px (a logistic step: the
//   pixel's partial coverage), and a Gaussian rim of height A and sigma s centred o px
//   inside the edge.
// - Motion: 2D Brownian, N(0, step^2) per axis per frame; discs stay whole in view and
//   do not overlap (a step that brings two rims closer than `gap_px` is not taken).
// - Camera: Gaussian read noise of std `noise` (fraction of full scale).
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/Synth.hpp"

namespace mmval::tracking {

struct DiscSceneOptions {
  int width = 512, height = 384, frames = 12;
  double fps_hz = 10;
  double pixel_size_um = 10;
  int particles = 7;
  double radius_min_px = 40, radius_max_px = 60;  ///< radii drawn uniformly in this range
  double rim_sigma_px = 1.5;      ///< s
  double rim_offset_px = 2;       ///< o
  double rim_contrast = 0.45;     ///< A
  double interior = 0.3;          ///< I_in, fraction of full scale
  double ground = 0.1;            ///< b
  double gap_px = 4;              ///< closest approach of two rims
  double step_px = 0.3;           ///< per axis per frame
  double noise = 0.02;
  SynthFormat format = SynthFormat::png8;
  std::uint64_t seed = 1;
};

struct DiscSceneResult {
  Tracks truth;                    ///< every disc in every frame: x_px, y_px (and m)
  std::vector<double> radii_px;    ///< per disc (particle id = index)
  std::vector<std::string> files;  ///< frame files, or the video
};

/// Writes the frames (as o.format says), truth.csv (frame, particle, x, y in px, x_um,
/// y_um, t_s) and truth.json into `dir`. Throws std::invalid_argument for options out of
/// range or discs that do not fit (the message names the field).
DiscSceneResult writeDiscScene(const DiscSceneOptions& o, const std::filesystem::path& dir);

}  // namespace mmval::tracking
