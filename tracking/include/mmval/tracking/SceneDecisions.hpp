// What the tracker decides from the video itself before detecting, and why:
// whether the particles are ring-shaped brightfield colloids (a bright centre
// inside a dark ring: polarity "ring"), and whether a static background should be
// subtracted. Both are reported in summary.json with their numbers.
#pragma once
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking {

/// Ring-shaped colloids found (or not) in sampled frames.
struct RingGuess {
  bool rings = false;
  double radius_px = 0;         ///< radius of the dark ring (median over the ringed spots)
  int candidates = 0;           ///< bright local maxima examined (strongest first, halos of accepted rings skipped)
  int ringed = 0;               ///< of them: a bright centre inside a dark ring that is dark all the way round
  int dark_ringed = 0;          ///< the same test with the signs swapped (dark particles ringed by bright gaps)
  double share = 0;             ///< ringed / candidates
  std::vector<float> profile;   ///< mean radial profile of the ringed spots about their local level, r = 0, 1, ... px
  std::string reason;
};

/// Looks for ring colloids in `frames` (float grey, up to 8 of them are used): each
/// bright local maximum of the band-passed frame (a difference of Gaussians of sigma 1
/// and 10 px, above 6 robust noise sigma) counts as ringed when its azimuthal profile
/// about the local level (median of the annulus 22-25 px out) is brighter than the
/// level at the centre and darker at some radius of 2-20 px, and every one of 16
/// angular sectors of that radius is at least half as dark as the ring's mean: a closed
/// ring, not the gap between dark neighbours. Rings when at least 3 spots are ringed,
/// they are at least half of the bright maxima, and dark-centred rings (dark particles
/// separated by bright gaps) are fewer.
RingGuess guessRings(const std::vector<cv::Mat>& frames);

/// Zero-mean, radially symmetric matched filter of the ring profile (sum of squares
/// normalised so that a ring with the measured profile responds with its centre-to-
/// ring contrast). Without a measured profile, a generic one of the given radius: a
/// bright centre of sigma radius / 3 inside a dark ring of width radius / 5.
cv::Mat ringKernel(const std::vector<float>& profile, double radius_px);

/// Sub-pixel centre of a radially symmetric spot (any profile: rings, discs, Gaussian
/// spots) by Parthasarathy's radial symmetry method (2012, Nat. Methods 9:724): the
/// point nearest, in the weighted least-squares sense, to the lines through every
/// half-pixel of the window along the local intensity gradient, weighted by the
/// gradient's square over the distance to the current centre. Moves `d` when the
/// estimate stays within `radius_px` / 2 of the seed.
void radialSymmetryCentre(const cv::Mat& image, double radius_px, Detection& d);

/// How the static background was chosen.
struct BackgroundDecision {
  bool subtract = true;
  std::string requested = "auto";   ///< auto, median or none
  std::string reason;
  int frames_compared = 0;
  double spots_per_frame = 0;       ///< round spots per sampled frame, detected against a spatial (not temporal) background
  double spots_in_median = 0;       ///< the same detector on the temporal median
  double static_share = 0;          ///< share of the frames' spots that sit (within 1.5 px) on a spot of the median
  double moving_energy_share = 0;   ///< band-passed energy of frame - median over the frame's (1: all of it moves)
  int persistent_spots = 0;         ///< spots of the median found in at least 3/4 of the sampled frames (static structure)
};

/// Static share above which subtracting the median would remove the particles.
constexpr double kStaticShareLimit = 0.5;

/// Auto background: the temporal median is subtracted when the video has static
/// structure (a spot of the median found in at least 3/4 of the sampled frames: grains,
/// stuck particles) and most of what the frames show is not in the median at the same
/// place. Not subtracted when the particles barely move over the sampled frames (then
/// the median is the particles: subtracting it removes them). With nothing static the
/// median is nearly flat: subtracted for spots (it evens the illumination), not for
/// rings (their zero-mean matched filter needs no level; the median would only add
/// ghosts of slowly moving rings).
/// Round spots (eccentricity <= 0.8: grain edges are elongated) are found with `options`
/// (polarity `polarity`) on up to 8 frames and on `median` against a spatial high-pass (a
/// boxcar of refine_radius) instead of the median; "the same place" is within
/// max(1.5, refine_radius / 4) px. Polarity automatic: dark and bright are both tried in
/// one pass over the frames; the side with more spots per frame decides (dark on a tie).
BackgroundDecision decideBackground(const std::vector<cv::Mat>& frames, const cv::Mat& median, Polarity polarity, const DetectOptions& options);

/// Dark or bright particles of a video whose particles barely move (no temporal
/// background to compare with): the side with more excess beyond 4 robust noise sigma
/// of the band-passed frames (difference of Gaussians of sigma 1 and 10 px). Dark when
/// nothing deviates.
Polarity guessPolaritySpatial(const std::vector<cv::Mat>& frames);

}  // namespace mmval::tracking
