// Putting the experiment in the simulation's coordinate frame.
//
// The simulation lives in the geometry mask's frame; the experiment's tracks
// are in the camera's pixels. Two ways to map one onto the other:
//  - the case gives the imaged window directly (origin, rotation, pixel size);
//  - the first video frame (or the tracker's background image) is registered
//    to the mask image with OpenCV's ECC alignment (Evangelidis & Psarakis
//    2008, "Parametric image alignment using enhanced correlation coefficient
//    maximization", IEEE TPAMI 30(10)), a rigid (Euclidean) motion found on
//    blurred images, coarse to fine over an image pyramid, starting from a
//    phase-correlation (same size) or template-matching (frame smaller than
//    the mask) estimate of the shift so that large shifts converge.
//
// Coordinates. Frame and mask pixels use OpenCV's convention (the centre of
// pixel (c, r) is at (c, r)). The mask frame in metres is the one mmval's
// fluid solver builds from a mask: origin at the image's lower-left corner,
// x along columns, y up (rows counted from the bottom), so the centre of mask
// pixel (c, r) is at ((c + 0.5) s, (rows - r - 0.5) s). With y_up = false the
// origin is the upper-left corner and y points down the rows.
#pragma once
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include "mmval/core/Tracks.hpp"

namespace mmval::compare {

/// frame pixel -> mask pixel: q = scale R(angle) u + (dx, dy).
struct RigidTransform {
  double dx_px = 0, dy_px = 0;  ///< mask pixels
  double angle_deg = 0;         ///< counter-clockwise in image axes (x right, y down)
  double scale = 1;             ///< mask pixels per frame pixel (fixed from the pixel sizes, not fitted)
  cv::Matx23d matrix() const;
  static RigidTransform fromMatrix(const cv::Matx23d& m, double scale = 1.0);
};

struct RegistrationOptions {
  double blur_sigma_px = 1.5;     ///< Gaussian smoothing of both images before alignment
  int pyramid_levels = -1;        ///< -1: as many halvings as keep the coarsest side >= 48 px (at most 5)
  int iterations = 300;           ///< ECC iterations per level
  double epsilon = 1e-7;          ///< ECC stop: change of the correlation coefficient
  double min_correlation = 0.6;   ///< below this the fit is reported as failed
  double min_overlap = 0.3;       ///< share of the frame that must land inside the mask
  bool initial_guess = true;      ///< phase correlation / template matching before ECC
};

struct RegistrationResult {
  RigidTransform transform;   ///< frame pixel -> mask pixel
  double correlation = 0;     ///< ECC enhanced correlation coefficient at the solution (1: perfect)
  double rms_residual = 0;    ///< RMS of frame - (gain * warped mask + bias) over the overlap, grey levels of [0, 1] images
  double overlap = 0;         ///< share of frame pixels that fall inside the mask
  bool inverted = false;      ///< the frame's contrast was the mask's negative (grains bright)
  int levels = 1;             ///< pyramid levels used
  cv::Point2d initial_shift;  ///< the shift estimate ECC started from, mask px
  nlohmann::json toJson(double mask_pixel_size_m) const;
};

/// Registration failed: no convergence, too little overlap, or a correlation
/// below the minimum. The message says which and what to do.
class RegistrationFailed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Registers `frame` (any depth, grey or colour) to `mask`. `frame_to_mask_scale`
/// (mask pixels per frame pixel, = frame pixel size / mask pixel size) is
/// applied before fitting the rigid motion. Throws RegistrationFailed.
RegistrationResult registerToMask(const cv::Mat& frame, const cv::Mat& mask, const RegistrationOptions& options = {},
                                  double frame_to_mask_scale = 1.0);

/// Same on files: the first frame of `frame_input` (image, video, folder,
/// multi-page TIFF) against the mask image. Throws InputError naming the file
/// that cannot be read, or naming both files when the registration fails.
RegistrationResult registerFiles(const std::filesystem::path& frame_input, const std::filesystem::path& mask_file,
                                 const RegistrationOptions& options = {}, double frame_to_mask_scale = 1.0);

/// The first frame of `frame_input` (BGR) with the grain outlines of `pore`
/// (readPoreMask), carried into the frame by the fitted motion, drawn in green:
/// the picture to check a registration by eye.
cv::Mat registrationOverlay(const std::filesystem::path& frame_input, const cv::Mat& pore, const RegistrationResult& result);

/// The mask frame in metres (see the header comment).
struct MaskFrame {
  double pixel_size = 0;  ///< m per mask pixel
  int rows = 0, cols = 0;
  bool y_up = true;
  cv::Point2d toMetres(cv::Point2d mask_px) const;
  cv::Point2d toPixels(cv::Point2d metres) const;
};

/// Frame pixels -> mask-frame metres: p = M (u, v, 1).
struct FrameToSimulation {
  cv::Matx23d m_per_px;  ///< metres per frame pixel, and the offset in metres
  std::string method;    ///< "registration" or "window"
  nlohmann::json details;
  /// From a registration result.
  static FrameToSimulation fromRegistration(const RegistrationResult& r, const MaskFrame& mask);
  /// From the imaged window: where the frame's pixel (0, 0) lies in the
  /// simulation frame (m), the window's rotation (counter-clockwise, rad) and
  /// its pixel size (m). With y_up the frame's rows run along -y at zero rotation.
  static FrameToSimulation fromWindow(double origin_x, double origin_y, double angle_rad, double pixel_size, bool y_up);
};

/// Moves experiment tracks into the simulation frame. Pixel columns are used
/// when present, else positions / `frame_pixel_size` (m); throws InputError
/// naming the tracks file when neither is available.
Tracks applyToTracks(const Tracks& tracks, const FrameToSimulation& map, double frame_pixel_size = 0.0);

/// Reads a geometry mask: pore = true. `grains_dark`: grains are the dark
/// pixels (threshold at the midpoint of the image's range). Throws InputError.
cv::Mat readPoreMask(const std::filesystem::path& file, bool grains_dark = true);

}  // namespace mmval::compare
