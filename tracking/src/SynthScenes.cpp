#include "mmval/tracking/SynthScenes.hpp"

#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/MaskRule.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"
#include "TrackpyFlagsChecks.hpp"

namespace mmval::tracking {

using detail::requireOptionValue;

void checkSynthSharedSettings(const SynthSharedSettings& shared, double flow_speed_px_per_frame) {
  // NaN passes CLI11's range checks and would write NaN times.
  if (shared.fps_hz) requireOptionValue("--fps", *shared.fps_hz, 0, true, 1e9, "a frame rate in frames per second, finite and > 0 (e.g. --fps 10)");
  if (shared.pixel_size_um) requireOptionValue("--pixel-size-um", *shared.pixel_size_um, 0, true, 1e6, "a pixel size in micrometres, finite and > 0");
  requireOptionValue("--speed", flow_speed_px_per_frame, 0, false, 1e6, "a flow speed in px per frame, finite and >= 0");
  if (shared.noise) requireOptionValue("--noise", *shared.noise, 0, false, 0.5, "a camera noise between 0 and 0.5 of full scale");
}

namespace {

/// The fields the scene options name alike (width, ..., seed, format).
template <class Options>
void applyCommon(const SynthSharedSettings& s, Options& o) {
  if (s.width) o.width = *s.width;
  if (s.height) o.height = *s.height;
  if (s.frames) o.frames = *s.frames;
  if (s.particles) o.particles = *s.particles;
  if (s.noise) o.noise = *s.noise;
  o.seed = s.seed;
  o.format = s.format;
}

template <class Options>
void applyWithUnits(const SynthSharedSettings& s, Options& o) {
  applyCommon(s, o);
  if (s.fps_hz) o.fps_hz = *s.fps_hz;
  if (s.pixel_size_um) o.pixel_size_um = *s.pixel_size_um;
}

}  // namespace

void applySharedSettings(const SynthSharedSettings& s, SynthOptions& o) {
  applyCommon(s, o);
  if (s.fps_hz) o.fps = *s.fps_hz;
  if (s.pixel_size_um) o.pixel_size = *s.pixel_size_um * 1e-6;
}
void applySharedSettings(const SynthSharedSettings& s, BrownianSlabOptions& o) { applyWithUnits(s, o); }
void applySharedSettings(const SynthSharedSettings& s, RingSceneOptions& o) { applyWithUnits(s, o); }
void applySharedSettings(const SynthSharedSettings& s, DiscSceneOptions& o) { applyWithUnits(s, o); }

namespace {

/// Runs `write` into a staging folder for `out`, commits it, and returns its result with the
/// file paths of `files` moved from the staging folder to the committed one.
template <class Result, class Write>
Result writeStaged(const std::filesystem::path& out, Write&& write, std::vector<std::string> Result::*files) {
  StagedDirectory staged(out);
  Result r = write(staged.path());
  staged.commit();
  for (std::string& f : r.*files) f = (staged.finalPath() / std::filesystem::path(f).lexically_relative(staged.path())).string();
  return r;
}

/// The pore image as grains (CV_8U, 255 = grain), checked against the memory limit before it is decoded.
cv::Mat readGrainImage(const std::filesystem::path& geometry, bool dark_grains) {
  const InputLocation where{geometry.string(), 0, 0, "--geometry"};
  // synth --geometry peaks at 11.6 B per mask pixel above ~0.5 GB (measured with /usr/bin/time -v:
  // 3000^2 and 6000^2 masks, 588 and 902 MB); the pore analysis' flood-fill stack of the mirrored
  // mask adds up to 8 B/px on an open image.
  constexpr double kSynthGeometryBytesPerPixel = 20;
  requireImageWithin(geometry, where, defaultMaxMemoryBytes(), kSynthGeometryBytesPerPixel,
                     "a smaller image (the flow is solved on ~40000 cells whatever its size): crop or downscale it");
  const cv::Mat img = cv::imread(geometry.string(), cv::IMREAD_GRAYSCALE);
  if (img.empty()) throw InputError(where, "cannot read the image", {}, "a PNG or TIFF mask");
  cv::Mat grains;
  cv::threshold(img, grains, maskSplit(img.ptr<std::uint8_t>(), img.total()), 255,
                dark_grains ? cv::THRESH_BINARY_INV : cv::THRESH_BINARY);  // mmval's mask rule (core/MaskRule.hpp)
  return grains;
}

}  // namespace

SynthResult writeFlowScene(FlowSceneSettings s, const std::filesystem::path& out, const SynthFlowSolver& solve_flow) {
  SynthOptions& o = s.video;
  if (s.snr) {
    requireOptionValue("--snr", *s.snr, 0, true, 1e12, "a signal-to-noise ratio, finite and > 0");
    o.noise = o.spot_amplitude / *s.snr;
  }
  if (!s.geometry.empty()) {
    if (!solve_flow) throw std::invalid_argument("writeFlowScene: a geometry needs a flow solver");
    o.geometry = readGrainImage(s.geometry, s.dark_grains);
    try {
      o.flow = solve_flow(o.geometry, o.speed);
    } catch (const std::runtime_error& e) {
      throw InputError({s.geometry.string(), 0, 0, "--geometry"}, e.what(), {}, "an image with a connected pore path from the left to the right edge");
    }
  }
  return writeStaged(out, [&o](const std::filesystem::path& dir) { return writeSyntheticVideo(o, dir); }, &SynthResult::frames);
}

namespace {

void checkSlab(const SlabSceneSettings& settings) {
  const BrownianSlabOptions& s = settings.slab;
  if (settings.diffusion_given && settings.stokes_einstein_given)
    throw InputError({}, "options --diffusion-um2s and --temperature-K/--viscosity-Pa-s both set D", fmt::format("--diffusion-um2s {:g}", s.diffusion_um2_s),
                     "either D directly (--diffusion-um2s) or Stokes-Einstein's inputs (--temperature-K, --viscosity-Pa-s, --radius-um)");
  if (s.diffusion_um2_s != 0) requireOptionValue("--diffusion-um2s", s.diffusion_um2_s, 0, true, 1e6, "a diffusion coefficient in um^2/s, finite and > 0");
  requireOptionValue("--temperature-K", s.temperature_K, 0, true, 1e4, "an absolute temperature in K, finite and > 0 (e.g. 295.15)");
  requireOptionValue("--viscosity-Pa-s", s.viscosity_Pa_s, 0, true, 1e6, "a viscosity in Pa s, finite and > 0 (water at 22 C: 0.9544e-3)");
  requireOptionValue("--radius-um", s.radius_um, 0, true, 1e4, "a particle radius in um, finite and > 0");
  requireOptionValue("--slab-um", s.slab_um, 0, true, 1e6, "a slab thickness in um, finite and > 0");
  if (!(s.focus_um < 0)) requireOptionValue("--focus-um", s.focus_um, 0, false, s.slab_um, "a focal-plane height from 0 to --slab-um (or < 0 for mid-slab)");
  for (double v : s.drift_um_s) requireOptionValue("--drift-um-s", v, -1e6, false, 1e6, "two finite velocities X,Y in um/s");
  for (double v : s.drift_change_um_s2) requireOptionValue("--drift-change-um-s2", v, -1e6, false, 1e6, "two finite rates X,Y in um/s^2");
  requireOptionValue("--medium-index", s.medium_index, 1, false, 5, "a refractive index from 1 to 5 (water: 1.33)");
  requireOptionValue("--na", s.numerical_aperture, 0, true, s.medium_index * (1 - 1e-9), "a numerical aperture > 0 and below --medium-index");
  requireOptionValue("--wavelength-um", s.wavelength_um, 0, true, 100, "a wavelength in um, finite and > 0 (e.g. 0.55)");
  requireOptionValue("--contrast", s.contrast, 0, false, 1, "a contrast from 0 to 1 of the background");
  requireOptionValue("--flicker", s.flicker, 0, false, 0.5, "a relative brightness std from 0 to 0.5");
  requireOptionValue("--photons", s.photons, 0, false, 1e12, "a photon count at full scale, finite and >= 0 (0: no shot noise)");
  requireOptionValue("--exposure-s", s.exposure_s, 0, false, 1 / s.fps_hz, fmt::format("an exposure time from 0 to one frame interval (1/fps = {:g} s)", 1 / s.fps_hz));
}

}  // namespace

BrownianSlabResult writeSlabScene(const SlabSceneSettings& settings, const std::filesystem::path& out) {
  checkSlab(settings);
  return writeStaged(out, [&settings](const std::filesystem::path& dir) { return writeBrownianSlabVideo(settings.slab, dir); }, &BrownianSlabResult::files);
}

RingSceneResult writeRingSceneFolder(const RingSceneOptions& r, const std::filesystem::path& out) {
  requireOptionValue("--ring-radius-px", r.ring_radius_px, 2, false, 100, "a ring radius from 2 to 100 px");
  requireOptionValue("--diffusion-px2", r.diffusion_px2, 0, false, 1e4, "a diffusion coefficient in px^2 per frame, finite and >= 0");
  requireOptionValue("--illumination-gradient", r.illumination_gradient, -0.89, false, 0.89, "a fraction between -0.89 and 0.89");
  try {
    return writeStaged(out, [&r](const std::filesystem::path& dir) { return writeRingScene(r, dir); }, &RingSceneResult::files);
  } catch (const std::invalid_argument& e) {
    throw InputError({}, e.what(), {}, "fewer or smaller rings (--particles, --ring-radius-px) or a larger frame (--width, --height)");
  }
}

DiscSceneResult writeDiscSceneFolder(const DiscSceneOptions& d, const std::filesystem::path& out) {
  try {
    return writeStaged(out, [&d](const std::filesystem::path& dir) { return writeDiscScene(d, dir); }, &DiscSceneResult::files);
  } catch (const std::invalid_argument& e) {
    throw InputError({}, e.what(), {}, "fewer discs (--particles) or a larger frame (--width, --height)");
  }
}

}  // namespace mmval::tracking
