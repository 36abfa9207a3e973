// A synthetic brightfield video of colloids diffusing in a slab, with ground
// truth: the realistic reference for Brownian tracking.
//
// Physics and optics, each a stated model:
// - Motion: free 3D Brownian motion with the Stokes-Einstein coefficient
//   D = kB T / (6 pi eta a) (Einstein 1905), or a given D; each frame interval
//   adds exact Gaussian increments N(0, 2 D dt) per axis, plus a uniform drift
//   v(t) = v0 + (dv/dt) t in x, y. The centre height z is confined to [0, H]
//   by reflecting walls (reflected Brownian motion: its stationary density is
//   uniform, so particles drawn uniformly stay uniform). Hindered diffusion
//   near the walls and sedimentation are not modelled.
// - Lateral box: particles live in the field of view plus a margin of four
//   blur widths, periodic in x and y; one that wraps around is a new particle
//   (new id), as a real one entering the field is.
// - Defocus: the image of a particle at height z is a Gaussian spot of width
//   sigma(z)^2 = sigma0^2 + (c |z - z_f|)^2. sigma0 combines the projected
//   sphere (per-axis variance a^2 / 5 of an opaque sphere's shadow) with the
//   Gaussian approximation of the Airy pattern, 0.21 lambda / NA (Zhang,
//   Zerubia and Olivo-Marin 2007, Appl. Opt. 46:1819). The defocus term is the
//   geometric blur circle of radius |dz| tan(theta), sin(theta) = NA / n,
//   whose uniform disc has sigma = radius / 2: c = tan(asin(NA / n)) / 2. The
//   quadrature sum of in-focus size and defocus blur is the form of Olsen and
//   Adrian (2000, Exp. Fluids 29:S166) for micro-PIV particle images.
// - Contrast: the spot's integrated darkening is conserved (the shadow
//   spreads, no light is lost or gained), so its peak contrast is
//   contrast * sigma0^2 / sigma(z)^2: far-out-of-focus particles are faint wide blobs.
// - Depth of field (the truth's in_focus flag): |z - z_f| <= dof / 2 with the
//   wave-optical term dof = lambda n / NA^2 (Inoue and Spring, Video
//   Microscopy, 2nd ed. 1997, ch. 2).
// - Image: I = f_t * b * (1 - sum_i C_i g_i) for dark particles on a bright
//   background b = 0.8 of full scale (I = f_t * b * (1 + sum_i C_i g_i) with
//   b = 0.25 for bright ones), f_t = 1 + flicker * N(0, 1) per frame
//   (illumination flicker: the frame mean varies with relative std `flicker`).
//   Shot noise: Poisson with `photons` at full scale (Gaussian with the same
//   variance above 50 photons per pixel); read noise: Gaussian, std `noise`.
// - Motion blur: with exposure t_e > 0, each frame averages the spots at
//   `exposure_substeps` equally spaced times in [t, t + t_e] and the truth
//   holds the same average position, so its per-axis frame-to-frame step
//   variance is 2 D (dt - t_e (1 - 1/K^2) / 3) (K sub-steps; t_e / 3 as
//   K -> infinity, Savin and Doyle 2005, Biophys. J. 88:623).
//
// Deterministic per seed: trajectories draw from one stream, flicker and
// camera noise from another, so changing the noise keeps the trajectories.
#pragma once
#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/tracking/Synth.hpp"

namespace mmval::tracking {

/// Boltzmann constant, J/K (exact in the 2019 SI).
inline constexpr double kBoltzmannJPerK = 1.380649e-23;

/// Stokes-Einstein translational diffusion coefficient of a sphere, m^2/s.
double stokesEinsteinDiffusion(double temperature_K, double viscosity_Pa_s, double radius_m);

/// The slab scene's settings; the defaults are the class of a real video the
/// tracker must handle: 640 x 424 px, 300 frames at 24 fps, ~600 dark 1-um
/// polystyrene spheres in water at 22 C, drifting at 0.6 um/s, 20 um deep.
struct BrownianSlabOptions {
  int width = 640, height = 424, frames = 300;
  double fps_hz = 24;
  double pixel_size_um = 0.15;
  int particles = 600;            ///< mean number with their centre in the field of view (all depths)
  double diffusion_um2_s = 0;     ///< > 0: used as given; 0: Stokes-Einstein from the three below
  double temperature_K = 295.15;
  double viscosity_Pa_s = 0.9544e-3;  ///< water at 22 C (IAPWS 2008 formulation, CRC Handbook table)
  double radius_um = 0.5;
  double slab_um = 20;            ///< H: range of the particle centres' height
  double focus_um = -1;           ///< z_f in [0, H]; < 0: mid-slab
  std::array<double, 2> drift_um_s{0.6, 0.0};
  std::array<double, 2> drift_change_um_s2{0.0, 0.0};  ///< the drift's rate of change (slow drift change)
  double numerical_aperture = 0.4;
  double medium_index = 1.33;     ///< refractive index of the sample medium (water)
  double wavelength_um = 0.55;
  double contrast = 0.5;          ///< peak darkening (brightening) of an in-focus spot, fraction of the background
  double flicker = 0.01;          ///< relative std of the per-frame illumination
  double noise = 0.01;            ///< read noise std, fraction of full scale
  double photons = 5000;          ///< photons at full scale for shot noise; 0: none
  double exposure_s = 0;          ///< motion blur: exposure time (0: instantaneous), at most 1 / fps_hz
  int exposure_substeps = 8;      ///< spot positions averaged over the exposure
  bool dark_particles = true;
  SynthFormat format = SynthFormat::png8;
  std::uint64_t seed = 1;
};

/// The optics derived from the options (see the header comment), in um.
struct SlabOptics {
  double sigma0_um = 0;        ///< in-focus spot width
  double blur_slope = 0;       ///< c: d sigma / d |z - z_f|
  double depth_of_field_um = 0;
  double focus_um = 0;
  double sigmaUm(double z_um) const;     ///< spot width at height z
  double peakContrast(double z_um, double contrast) const;  ///< contrast * sigma0^2 / sigma^2
  bool inFocus(double z_um) const;
};
SlabOptics slabOptics(const BrownianSlabOptions& o);

/// D used by the scene, um^2/s: the given one or Stokes-Einstein's.
double slabDiffusion(const BrownianSlabOptions& o);

/// One particle in one frame: the position averaged over the exposure.
struct SlabRecord {
  std::int64_t frame = 0, particle = 0;
  double x_px = 0, y_px = 0, z_um = 0;
  bool in_view = false;  ///< centre inside the frame (only these go to truth.csv)
};

struct SlabSimulation {
  std::vector<SlabRecord> records;  ///< by frame, then particle
  /// Sub-step samples (x px, y px, z um) of every record, exposure_substeps per record (1 without exposure).
  std::vector<cv::Point3d> samples;
  int samples_per_record = 1;
  int particles_in_box = 0;
  double box_margin_px = 0;
};

/// The trajectories alone (no image), all particles of the periodic box.
/// Throws std::invalid_argument for options out of range (message names the field).
SlabSimulation simulateBrownianSlab(const BrownianSlabOptions& o);

/// Renders one frame (CV_32F, fraction of full scale, no noise) from sub-step
/// samples with illumination factor `brightness` (1 + flicker term).
cv::Mat renderSlabFrame(const BrownianSlabOptions& o, const SlabOptics& optics, const cv::Point3d* samples, std::size_t count,
                        int samples_per_record, double brightness);

struct BrownianSlabResult {
  SlabSimulation simulation;
  std::vector<std::string> files;      ///< frame files, or the video
  std::vector<double> brightness;      ///< illumination factor per frame
  double diffusion_um2_s = 0;
  double mean_in_view = 0, mean_in_focus = 0;  ///< particles per frame
  std::int64_t distinct_in_view = 0;  ///< distinct particle ids in truth.csv
};

/// Writes the frames (as o.format says), truth.csv (frame, particle, x, y, x_um,
/// y_um, t_s, z_um, dz_um, sigma_px, peak_contrast, in_focus; the shared tracks
/// schema plus columns, positions averaged over the exposure, t_s at the frame's
/// start), truth_in_focus.csv (its rows within the depth of field: what `mmval track
/// --truth` should be scored against) and truth.json (inputs, derived D and optics,
/// drift, counts) into `dir`.
/// Throws std::invalid_argument for options out of range, InputError beyond memory limits.
BrownianSlabResult writeBrownianSlabVideo(const BrownianSlabOptions& o, const std::filesystem::path& dir);

}  // namespace mmval::tracking
