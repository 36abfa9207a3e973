// A synthetic micromodel video with ground truth, the tracker's independent
// reference: static grains, Gaussian-spot particles carried by potential
// flow around the grains (or a given flow), some particles stuck from the
// start, some that deposit (stop) during the video, particles entering at the
// inlet as others leave, optional Brownian motion, defocus (a spread of spot
// sizes at constant integrated brightness), an illumination gradient, and
// camera noise: Gaussian read noise at a chosen SNR plus optional Poisson shot
// noise. Deterministic per seed; options left at their defaults draw no
// random numbers, so older videos are reproduced exactly. The frames are
// written as 8-bit grey PNG (default), RGBA PNG, 16-bit grey TIFF or an mp4
// (SynthFrameWriter, shared with the Brownian slab scene of SynthSlab.hpp).
#pragma once
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "mmval/core/Tracks.hpp"

namespace mmval::tracking {

/// How synthetic frames are stored: frames/frame_NNNNN.png as 8-bit grey,
/// frames/frame_NNNNN.png as RGBA (grey in B, G and R, alpha 255, as some
/// microscope software saves them), frames/frame_NNNNN.tif as 16-bit grey, or
/// one video.mp4 (MPEG-4 part 2 through OpenCV's FFMPEG backend: lossy, for
/// testing video input only).
enum class SynthFormat { png8, rgba_png, tiff16, mp4 };

/// "png", "rgba", "tiff16", "mp4"; throws std::invalid_argument for anything else.
SynthFormat parseSynthFormat(const std::string& name);
std::string synthFormatName(SynthFormat format);

/// Writes rendered frames (CV_32F, brightness as a fraction of full scale,
/// clamped to [0, 1]) in one SynthFormat, each file atomically. An mp4 is
/// written under a temporary name and renamed by finish(); an unfinished one is
/// removed. Throws std::runtime_error when OpenCV cannot write the format.
class SynthFrameWriter {
 public:
  SynthFrameWriter(std::filesystem::path dir, SynthFormat format, double fps_hz);
  SynthFrameWriter(const SynthFrameWriter&) = delete;
  SynthFrameWriter& operator=(const SynthFrameWriter&) = delete;
  ~SynthFrameWriter();
  /// Writes frame number `frame`; returns the path of the file written (the video for mp4).
  std::string write(int frame, const cv::Mat& image);
  /// Completes the output; returns the files written (one per frame, or the video).
  std::vector<std::string> finish();

 private:
  std::filesystem::path m_dir;
  SynthFormat m_format;
  double m_fps_hz;
  std::vector<std::string> m_files;
  std::filesystem::path m_video_tmp;
  struct Video;
  std::unique_ptr<Video> m_video;
};

/// The fields every scene with a truth.json shares.
struct SynthSceneCommon {
  std::string scene;
  std::uint64_t seed = 1;
  int frames = 0, width = 0, height = 0, particles = 0;
  double fps_hz = 0, pixel_size_um = 0;
  SynthFormat format = SynthFormat::png8;
};

/// What such scenes write alike, each file atomically: `truth` sorted by particle, then frame,
/// into truth.csv, and truth.json with the common fields plus the scene's own `model` fields.
void writeSynthTruth(const std::filesystem::path& dir, Tracks& truth, const SynthSceneCommon& common, nlohmann::json model);

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
  SynthFormat format = SynthFormat::png8;
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

/// Writes the frames (frames/frame_NNNNN.png, or as `format` says) and truth.csv into `dir`.
SynthResult writeSyntheticVideo(const SynthOptions& options, const std::filesystem::path& dir);

}  // namespace mmval::tracking
