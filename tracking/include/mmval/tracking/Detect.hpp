// Particle detection, the paper's pipeline made configurable and measured:
// static background removal (temporal median), Gaussian blur, threshold
// (manual, Otsu or adaptive), morphology, contours with area / circularity
// filters, centroid from moments, and sub-pixel refinement by an
// intensity-weighted centroid on the unthresholded signal.
//
// A second seed finder, `peaks`, takes local maxima of the band-passed signal
// (Gaussian blur minus a boxcar local mean, Crocker & Grier 1996, J. Colloid
// Interface Sci. 179:298) instead of contours: touching particles that one
// threshold merges into a single blob stay apart. Measured on trackpy's real
// frames (tests/tracking/TrackpyPeerTest.cpp) it finds 98 % of trackpy's
// features within 1 px where contours find 82 %.
//
// With peaks and the Gaussian-masked centroid, overlapping spots are then fitted
// jointly (deblend): each spot's centroid and amplitude on the signal minus its
// neighbours' models, spots hidden beside brighter ones looked for in the residual, and
// elongated blobs split in two when two spots fit significantly better (a
// likelihood-ratio test). On the SNR 4 scene of tests/tracking/TrackingValidationTest.cpp this took JSC from 0.938 to 0.979 and
// the RMSE from 0.43 to 0.32 px (with the linker's smoothed velocity).
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/Frames.hpp"

namespace mmval::tracking {

/// ring: brightfield colloids imaged as a bright centre inside a dark ring (on a grey
/// field), detected at the centre by a matched filter of the ring (SceneDecisions.hpp).
enum class Polarity { dark, bright, automatic, ring };
/// Static background: decided from the video (auto), always the temporal median, or none.
enum class BackgroundMode { automatic, median, none };
enum class ThresholdMode { manual, otsu, adaptive };
enum class Morphology { none, erode, dilate, open, close };
enum class Refinement { moments, intensity, disc, gaussian };
enum class SeedMethod { contours, peaks };

struct DetectOptions {
  bool subtract_background = true;  ///< false: no temporal background whatever background_mode says
  /// auto: the temporal median is subtracted unless the particles barely move (then the
  /// median is the particles; decideBackground in SceneDecisions.hpp).
  BackgroundMode background_mode = BackgroundMode::automatic;
  int background_samples = 60;      ///< frames sampled for the median
  Polarity polarity = Polarity::automatic;
  double blur_sigma = 1.0;          ///< px; 0 disables
  ThresholdMode threshold = ThresholdMode::otsu;
  double threshold_value = 0.08;    ///< manual: fraction of full scale of the background-removed signal
  int adaptive_block = 31;          ///< px, odd
  double adaptive_offset = 0.04;    ///< fraction of full scale above the local mean
  Morphology morphology = Morphology::open;
  int kernel = 3;                   ///< px, odd
  int iterations = 1;
  double min_area = 3, max_area = 2000;  ///< px^2
  double min_circularity = 0.2;     ///< 4 pi A / P^2
  double min_contrast = 0.02;       ///< peak signal, fraction of full scale
  double min_snr = 5.0;             ///< peak above the frame's noise floor (robust std of the smoothed signal); 0 disables
  /// intensity: Gaussian-masked centroid; disc: flat disc of refine_radius (Crocker & Grier);
  /// gaussian: least-squares fit of a Gaussian spot plus a constant (Levenberg-Marquardt),
  /// started from the Gaussian-masked centroid; near the Cramer-Rao bound on noisy spots.
  Refinement refinement = Refinement::intensity;
  SeedMethod method = SeedMethod::peaks;          ///< local maxima of the band-passed signal, or contours (the paper)
  int local_background = 0;         ///< px half-width of a boxcar local mean subtracted from the signal (spatial high-pass); 0: off
  int separation = 0;               ///< peaks: minimum distance between maxima, px (0: refine_radius)
  double min_mass = 0;              ///< smallest integrated signal inside refine_radius, fraction of full scale x px^2; 0: off
  /// Smallest mass relative to the frame's largest band-passed value, px^2: trackpy's
  /// minmass / 255 for 8-bit frames (trackpy sums the mass on the band-passed frame rescaled
  /// so that its maximum fills the integer range); 0: off.
  double min_mass_relative = 0;
  /// peaks: maxima must exceed this percentile of the band-passed frame's pixels
  /// (trackpy's `percentile`, 64 in its locate); 0: off.
  double min_percentile = 0;
  /// peaks with intensity/gaussian refinement: fit overlapping spots jointly and look for
  /// spots hidden beside brighter ones in the residual (see detect())
  bool deblend = true;
  bool find_stuck = false;          ///< also find particles stuck for the whole video in the median background (off: grain features can pass for particles)
  int stuck_kernel = 9;             ///< px: black/top-hat size, larger than a particle, smaller than a grain
  int refine_radius = 4;            ///< px, half window of the intensity-weighted centroid
  /// px, sigma of the Gaussian mask of `intensity` refinement (best equal to the spot's:
  /// then the centroid's fixed point is the least-squares position). 0: automatic, from
  /// the frame's median half-maximum area with `peaks`, refine_radius / 2 with contours.
  double refine_sigma = 0;
  /// Focus filter: drop spots whose measured sigma exceeds this multiple of the in-focus
  /// sigma, the mode of the frame's spot sigmas (out-of-focus particles are blurred, dim,
  /// and localised worse: the uncertainty grows as sigma^2 at constant light). 0: off.
  /// A spot counts as blurred when its sigma exceeds the limit by 3 of its standard errors
  /// (~ep_px) and it is round or dim (a wide, elongated, bright spot is a blend of sharp
  /// ones). Needs kFocusMinSpots spots in the frame; a blurred spot with a sharp one within
  /// 3 modal sigmas is kept (its sigma is their pair's). See docs/trackpy-mapping.md.
  double max_size_ratio = 1.5;
  /// Polarity ring: the matched filter (ringKernel) and the ring radius, px; empty / 0:
  /// a generic ring of refine_radius.
  cv::Mat ring_kernel;
  double ring_radius_px = 0;
};

/// Fewest spots in a frame for the focus filter to judge their modal sigma.
constexpr int kFocusMinSpots = 10;

struct Detection {
  double x = 0, y = 0;  ///< px; the centre of pixel (column i, row j) is (i, j)
  double area = 0;      ///< px^2 of the thresholded blob
  double mass = 0;      ///< integrated background-removed signal
  double peak = 0;      ///< peak signal
  /// Size, shape, amplitude, local background and localisation uncertainty of the spot
  /// (measured for every detection; quality.mass is `mass`).
  SpotQuality quality;
};

/// Positions (in the selected range of `count` frames) of up to `samples` frames spread
/// evenly: 0, s, 2 s, ... with stride s = max(1, count / samples).
std::vector<int> samplePositions(int count, int samples);

/// The frames at samplePositions(source.count(), samples), each decoded only (read with
/// FrameSource::sample, so the main pass takes them from its cache); the frames share
/// their pixels with the cache: do not write into them. next()'s position is unchanged.
std::vector<cv::Mat> sampleFrames(FrameSource& source, int samples);

/// Dark or bright particles from one frame: the sign of the strongest deviation from the
/// background (the frame's mean when `background` is empty). Static features that the
/// background holds but the frame lacks (a deposit not yet arrived) can fool it: prefer
/// the overload below.
Polarity guessPolarity(const cv::Mat& frame, const cv::Mat& background);

/// Dark or bright particles from frames spread over a video: the side (darker or brighter
/// than the background) that holds more of the moving foreground, i.e. deviations beyond
/// 4 robust noise sigma after a 1 px blur, leaving out pixels that deviate the same way in
/// more than a quarter of the frames (static: grains, deposits, illumination).
/// `background` empty: the frames' temporal median. Dark when nothing deviates.
Polarity guessPolarity(const std::vector<cv::Mat>& frames, const cv::Mat& background);

/// Particles in one frame (float grey in [0, 1]); `background` may be empty. Each
/// detection carries its measured quality (SpotQuality), and the focus filter
/// (max_size_ratio) has dropped the blurred ones.
std::vector<Detection> detect(const cv::Mat& frame, const cv::Mat& background, Polarity polarity, const DetectOptions& options);

/// Particles that sit still for the whole video are part of the median
/// background: find them there as spots smaller than `stuck_kernel`
/// (morphological black-hat for dark particles, top-hat for bright ones).
std::vector<Detection> detectStuck(const cv::Mat& background, Polarity polarity, const DetectOptions& options);

Polarity parsePolarity(const std::string& s);
std::string polarityName(Polarity p);
BackgroundMode parseBackgroundMode(const std::string& s);
std::string backgroundModeName(BackgroundMode m);
ThresholdMode parseThreshold(const std::string& s);
Morphology parseMorphology(const std::string& s);
Refinement parseRefinement(const std::string& s);
SeedMethod parseSeedMethod(const std::string& s);

}  // namespace mmval::tracking
