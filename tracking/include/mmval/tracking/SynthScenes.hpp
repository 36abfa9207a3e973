// The scenes of `mmval synth`, each written into an output folder from typed
// settings: micromodel flow (Synth.hpp), Brownian particles in a slab
// (SynthSlab.hpp), brightfield ring colloids (SynthRings.hpp) and large discs
// (SynthDiscs.hpp). Each function checks its settings (errors name the `mmval
// synth` flag that sets the value, exit 2), writes the frames and the truth into
// `<out>.partial` and swaps it into place (StagedDirectory: a folder that is not
// mmval's is never replaced); the file paths it returns are those in `out`.
//
// The flow through a pore image (`--geometry`) is a Stokes solve of the simulate
// library, which tracking does not link: the caller passes the solver in
// (SynthFlowSolver; mmval/simulate/SynthFlow.hpp provides mmval's).
#pragma once
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "mmval/tracking/Synth.hpp"
#include "mmval/tracking/SynthDiscs.hpp"
#include "mmval/tracking/SynthRings.hpp"
#include "mmval/tracking/SynthSlab.hpp"

namespace mmval::tracking {

/// The settings every scene shares. Each optional holds a value only when it was given,
/// so that a scene keeps its own default otherwise (the slab's 640 x 424 px at 24 fps,
/// the flow's 320 x 240 px at 10 fps, ...).
struct SynthSharedSettings {
  std::optional<int> width, height, frames, particles;  ///< px, px, frames, particles
  std::optional<double> fps_hz;
  std::optional<double> pixel_size_um;
  std::optional<double> noise;  ///< camera (read) noise std, fraction of full scale
  std::uint64_t seed = 1;
  SynthFormat format = SynthFormat::png8;
};

/// Checks the shared values that were given (--fps, --pixel-size-um, --noise) and the flow
/// speed (--speed, px per frame, >= 0): finite and in range, InputError naming the flag otherwise.
void checkSynthSharedSettings(const SynthSharedSettings& shared, double flow_speed_px_per_frame);

/// The given shared values replace the scene's defaults; seed and format are always taken.
void applySharedSettings(const SynthSharedSettings& shared, SynthOptions& o);
void applySharedSettings(const SynthSharedSettings& shared, BrownianSlabOptions& o);
void applySharedSettings(const SynthSharedSettings& shared, RingSceneOptions& o);
void applySharedSettings(const SynthSharedSettings& shared, DiscSceneOptions& o);

/// Velocity in px per frame at image position (x, y) in px (y down).
using SynthFlowField = std::function<cv::Point2d(double, double)>;
/// Solves the flow through `grains` (CV_8U, non-zero = grain) with a mean pore speed of
/// `mean_speed_px_per_frame`; throws std::runtime_error when no pore path crosses the image
/// from left to right. The field it returns owns whatever it samples.
using SynthFlowSolver = std::function<SynthFlowField(const cv::Mat& grains, double mean_speed_px_per_frame)>;

/// `synth --scene flow`: particles carried past grains.
struct FlowSceneSettings {
  SynthOptions video;            ///< shared settings already applied (applySharedSettings)
  std::optional<double> snr;     ///< spot amplitude / noise std; replaces video.noise
  std::filesystem::path geometry;  ///< pore image (grains and Stokes flow from it); empty: random disc grains, potential flow
  bool dark_grains = true;       ///< which pixels of `geometry` are grains (split by mmval's mask rule, core/MaskRule.hpp)
};

/// Writes the flow scene (frames, truth.csv) into `out`. `solve_flow` is used, and then
/// required, only with a geometry. Throws InputError for a bad --snr, a geometry that
/// cannot be read, is beyond the memory limit or has no pore path across.
SynthResult writeFlowScene(FlowSceneSettings settings, const std::filesystem::path& out, const SynthFlowSolver& solve_flow);

/// `synth --scene brownian-slab`. D is either given (diffusion_um2_s) or Stokes-Einstein's
/// from temperature, viscosity and radius, not both: the flags say which were given.
struct SlabSceneSettings {
  BrownianSlabOptions slab;  ///< shared settings already applied
  bool diffusion_given = false;        ///< --diffusion-um2s
  bool stokes_einstein_given = false;  ///< --temperature-K or --viscosity-Pa-s
};

/// Checks every value (InputError naming its flag) and writes the slab scene (frames,
/// truth.csv, truth_in_focus.csv, truth.json) into `out`.
BrownianSlabResult writeSlabScene(const SlabSceneSettings& settings, const std::filesystem::path& out);

/// `synth --scene brightfield-rings` (shared settings already applied): checks the ring's
/// radius, diffusion and illumination gradient and writes the scene into `out`; rings that
/// do not fit are an InputError naming --particles, --ring-radius-px, --width and --height.
RingSceneResult writeRingSceneFolder(const RingSceneOptions& rings, const std::filesystem::path& out);

/// `synth --scene large-discs` (shared settings already applied): writes the scene into
/// `out`; discs that do not fit are an InputError naming --particles, --width and --height.
DiscSceneResult writeDiscSceneFolder(const DiscSceneOptions& discs, const std::filesystem::path& out);

}  // namespace mmval::tracking
