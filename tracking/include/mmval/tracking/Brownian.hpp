// Brownian motion of tracked particles (analysis.motion = "brownian"), and the
// choice between it and flow (analysis.motion = "auto").
//
// Model (per axis, frame interval dt, camera exposure t_E, localisation error
// sigma): a measured position is the exposure-averaged true position plus
// Gaussian noise. Then
//   MSD(t) = 4 D t + 4 sigma^2 - (4/3) D t_E            (2D, t = n dt, n >= 1; Michalet 2010,
//            Phys. Rev. E 82, 041914, with the blur term of Berglund 2010,
//            Phys. Rev. E 82, 011917)
// and successive steps dx_n of one track obey
//   <dx_n^2> = 2 D dt + 2 (sigma^2 - 2 R D dt),  <dx_n dx_n+1> = -(sigma^2 - 2 R D dt)
// with the motion-blur coefficient R = t_E / (6 dt) for an exposure of t_E at
// constant illumination (0: instantaneous, 1/6: exposed over the whole frame
// interval; Vestergaard, Blainey & Flyvbjerg 2014, Phys. Rev. E 89, 022726). D from either estimator does not depend on t_E: the blur only
// moves the offset, i.e. what is read as sigma^2.
//
// All positions in metres, times in seconds, D in m^2/s. Tracks sorted by
// particle, then frame (the tracks schema's order).
#pragma once
#include <cstdint>
#include <limits>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

#include "mmval/core/Tracks.hpp"

namespace mmval::tracking {

/// How tracks are analysed: carried by a flow (velocities, dispersion, retention,
/// deposits) or diffusing (drift removed, D, exponent, localisation error).
enum class MotionModel { flow, brownian, automatic };
/// "flow", "brownian", "auto".
const char* motionModelName(MotionModel m);
/// Inverse of motionModelName; throws std::invalid_argument naming the choices.
MotionModel parseMotionModel(const std::string& name);

struct BrownianOptions {
  double exposure = 0;   ///< s: camera exposure t_E (motion blur); 0: instantaneous (blur then reads as a smaller sigma)
  int min_points = 10;   ///< tracks with fewer points are "short": in no D estimate
  /// frames: lags of the D fit; 0: the number that minimises D's standard error
  /// (Michalet 2010: the optimum is a few lags, more as sigma^2 / (D dt) grows), at most 20
  int max_lag = 0;
  double immobile_level = 0.01;  ///< one-sided significance level of both halves of the immobile test
  std::vector<int> van_hove_lags = {1, 4, 16};  ///< frames
};

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// Frame interval (s): the median over successive points of a track of dt / dframe; NaN without any.
double frameInterval(const Tracks& tracks);

/// Per-frame ensemble drift: the mean displacement, between each frame and the next one
/// that holds points, of the particles present in both, cumulated from 0 at the first frame.
struct EnsembleDrift {
  std::vector<std::int64_t> frame;  ///< every frame that holds a point, increasing
  std::vector<double> t;            ///< s
  std::vector<double> x, y;         ///< m, cumulative
  std::vector<int> pairs;           ///< particles averaged for the step into this frame (0: none, drift held)
  /// Cumulative drift at `frame` (the last known frame's at or before it; 0 before the first).
  void at(std::int64_t frame, double& dx, double& dy) const;
};

/// The ensemble drift of `tracks`, leaving out the particles in `excluded`.
EnsembleDrift ensembleDrift(const Tracks& tracks, const std::unordered_set<std::int64_t>& excluded = {});

/// `tracks` with the cumulative drift at each point's frame subtracted.
Tracks driftCorrected(const Tracks& tracks, const EnsembleDrift& drift);

/// The ensemble MSD of a set of tracks and its fits. Standard errors come from a
/// delete-a-group jackknife over groups of whole tracks (the displacements of one track
/// are correlated across lags and with each other; whole tracks are independent).
struct MsdFit {
  std::vector<double> lag;            ///< s
  std::vector<double> msd, msd_se;    ///< m^2 (x + y)
  std::vector<long long> samples;     ///< displacements averaged at each lag
  int tracks = 0;
  int lags_d = 0;      ///< lags 1..lags_d in the fit of D and the offset
  int lags_alpha = 0;  ///< lags 1..lags_alpha in the fit of the exponent
  double d = kNaN, d_se = kNaN;            ///< m^2/s
  double offset = kNaN, offset_se = kNaN;  ///< m^2: 4 sigma^2 - (4/3) D t_E
  double sigma2 = kNaN, sigma2_se = kNaN;  ///< m^2 per axis (localisation variance)
  /// Exponent of MSD(t) = c + 4 K t^alpha (K in m^2/s^alpha), c fitted with it.
  double alpha = kNaN, alpha_se = kNaN, k_alpha = kNaN;
  double reduced_error = kNaN;  ///< Michalet's x = sigma^2 / (D dt)
  /// The fitted line at lag t (s): offset + 4 D t.
  double fitAt(double t) const { return offset + 4.0 * d * t; }
};

/// Ensemble MSD of every track in `tracks` (already drift-corrected), fitted by
/// weighted least squares (weights: 1 / jackknife variance of each lag's MSD) over lags
/// 1..p for D and the offset, p = options.max_lag or the one of smallest D standard
/// error. The exponent comes from MSD = c + 4 K t^alpha with its own offset c over lags
/// 1..lags_alpha (a quarter of the median track length, at least 10 and p), same
/// weights: for each alpha, c and K are a linear fit against t^alpha; alpha minimises
/// the weighted residual. A free offset keeps the localisation error (which lifts the
/// short lags) from reading as alpha < 1, or, subtracted as a fixed number taken from
/// a line, from distorting a curved (anomalous) MSD.
MsdFit fitEnsembleMsd(const Tracks& tracks, double frame_interval, const BrownianOptions& options);

/// Covariance-based estimate of one track's D (Vestergaard et al. 2014),
/// both axes averaged, from steps between consecutive frames only.
struct CveEstimate {
  int steps = 0;             ///< steps per axis
  int pairs = 0;             ///< pairs of successive steps per axis
  double d = kNaN;           ///< m^2/s: <dx^2> / (2 dt) + <dx_n dx_n+1> / dt
  double d_se = kNaN;        ///< m^2/s: cveVariance at the track's own D (>= 0) and noise
  double sigma2 = kNaN;      ///< m^2: R <dx^2> + (2 R - 1) <dx_n dx_n+1>
  double mean_square = kNaN; ///< m^2: <dx^2> per axis
  double covariance = kNaN;  ///< m^2: <dx_n dx_n+1> per axis
};

/// [first, last) index ranges of each track in points sorted by particle, then frame.
std::vector<std::pair<std::size_t, std::size_t>> trackRanges(const std::vector<TrackPoint>& points);

/// CVE of points [first, last) of one track (sorted by frame).
CveEstimate cveEstimate(const std::vector<TrackPoint>& points, std::size_t first, std::size_t last, double frame_interval, double exposure);

/// Variance of the CVE of D from one axis of n steps (Vestergaard et al. 2014):
/// D^2 [(6 + 4 e + 2 e^2) / n + 4 (1 + e)^2 / n^2], e = sigma^2 / (D dt) - 2 R, written as
/// [(6 D^2 + 4 D s + 2 s^2) / n + 4 (D + s)^2 / n^2] with s = (sigma^2 - 2 R D dt) / dt so
/// that D = 0 stays finite. The mean of two axes has half of it.
double cveVariance(double d, double sigma2, double frame_interval, double blur_r, int n);

/// Immobile when the track's CVE D is both significantly below the ensemble D (a free
/// particle is called immobile at most at `level`) and not significantly above zero (a
/// particle at rest, whose D estimate scatters about 0 with the standard error of pure
/// localisation noise, sigma^2 = <dx^2> / 2). One-sided z-tests at `level` each.
struct ImmobileTest {
  double z_zero = kNaN;  ///< D / SE(D | D = 0)
  double z_free = kNaN;  ///< (D - D_ensemble) / SE(D | D_ensemble)
  bool immobile = false;
};
ImmobileTest immobileTest(const CveEstimate& e, double d_ensemble, double frame_interval, double level);

/// The flow-or-Brownian decision of analysis.motion = "auto", with its numbers.
/// Flow when the drift-corrected steps are directed: the pooled lag-1 correlation of
/// successive steps, c = sum dr_n . dr_n+1 / sum |dr_n|^2, exceeds the largest value
/// Brownian motion can give (R / (1 - 2 R) = 0.25 at R = 1/6, exposure over the whole
/// frame; localisation noise only lowers it) by more than `z_directed` standard errors
/// (ratio estimator over whole tracks); or when the ensemble as a whole is carried: its
/// rms drift per frame exceeds `peclet` times the rms drift-corrected step (noise of the
/// ensemble mean removed); or when nothing diffuses: the correlation is not above the
/// -1/2 of localisation noise about fixed places by `z_directed` standard errors (a
/// video of stuck particles stays with flow, the default); or when more tracks keep
/// their direction than diffusion allows: per track of n >= 4 successive steps, R =
/// |sum of steps|^2 / sum of |step|^2 is exactly (1 - R / n)^(n - 1) likely to be
/// exceeded for Gaussian diffusive steps (F(2, 2(n - 1)) tail; the +0.25 correlation of
/// full-frame exposure widens it by at most 1 + 2 x 0.25, localisation noise and rests
/// only narrow it), so a track is persistent above the R that diffusion exceeds with
/// probability `persistent_alpha`, and the count of persistent tracks is flow when
/// diffusion would give it with less than the one-sided normal tail of `z_directed`
/// (exact binomial). This judges the tracks that move, whatever share of the steps
/// deposits at rest contribute. Otherwise Brownian.
struct MotionDecision {
  MotionModel requested = MotionModel::flow;
  MotionModel model = MotionModel::flow;
  std::string reason = "analysis.motion = \"flow\"";
  double step_correlation = kNaN, step_correlation_se = kNaN;
  double correlation_bound = 0.25;
  double z_directed = kNaN;
  double z_diffusing = kNaN;  ///< (correlation + 1/2) / its standard error
  double drift_peclet = kNaN;
  long long step_pairs = 0;
  int tracks = 0;
  double persistent_alpha = 0.01;    ///< a diffusing track's chance to count as persistent
  int persistence_tracks = 0;        ///< tracks with >= 4 successive steps, judged for persistence
  int persistent_tracks = 0;         ///< of them, persistent
  double persistent_p = kNaN;        ///< binomial chance of as many persistent tracks under diffusion
  bool relinked = false;  ///< the tracker linked again without prediction after deciding Brownian
};
MotionDecision decideMotion(const Tracks& tracks, double z_directed = 3.0, double peclet = 1.0);

/// One track of a Brownian analysis.
struct TrackDiffusion {
  std::int64_t particle = 0;
  int points = 0;
  CveEstimate cve;
  ImmobileTest test;
  std::string state;  ///< mobile, immobile, short
};

/// Distribution of drift-corrected displacements along x and y (pooled) at one lag,
/// beside the Gaussian of the fitted model (variance MSD_fit(t) / 2 per axis).
struct VanHove {
  int lag_frames = 0;
  double lag = 0;                  ///< s
  long long samples = 0;
  double bin_width = 0;            ///< m
  std::vector<double> centre;      ///< m
  std::vector<double> density;     ///< 1/m
  std::vector<double> gaussian;    ///< 1/m
  double variance = kNaN, model_variance = kNaN;  ///< m^2 per axis
};

struct BrownianStats {
  double frame_interval = kNaN;  ///< s
  EnsembleDrift drift;           ///< of the tracks not found immobile
  MsdFit msd;                    ///< drift-corrected, mobile tracks of at least min_points
  std::vector<TrackDiffusion> tracks;
  int particles = 0, mobile = 0, immobile = 0, short_tracks = 0;
  double cve_mean = kNaN, cve_median = kNaN;  ///< m^2/s over the mobile tracks
  double cve_mean_se = kNaN;                  ///< m^2/s: standard error of cve_mean from the tracks' spread
  std::vector<VanHove> van_hove;
};

/// The whole Brownian analysis. Twice: drift, MSD fit and CVE over all tracks of at
/// least min_points, the immobile test against that D; then drift and fit again without
/// the immobile tracks (particles stuck to a wall neither drift nor diffuse with the rest).
BrownianStats analyseBrownian(const Tracks& tracks, const BrownianOptions& options);

}  // namespace mmval::tracking
