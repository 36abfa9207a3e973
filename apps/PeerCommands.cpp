#include "PeerCommands.hpp"

#include <cstdio>
#include <memory>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/openfoam/Peer.hpp"
#include "mmval/reports/Summary.hpp"

namespace mmval::app {

namespace {
struct PeerCli {
  std::string file, out;
  int np = 1;
  std::vector<int> levels;
  std::string mesher = "direct";
  bool quiet = false;
};

/// The ladder's cap is the case file's: the resolution key takes at most kMaxLevel, and
/// --levels (or numerics.levels, which the schema leaves unbounded) may not exceed it either,
/// so that a huge ladder is refused before blockMesh runs. Cylinder levels are cells around the
/// cylinder, multiples of 4 from 8, as its O-grid needs; periodic-array levels are cells along the
/// unit-cell side (numerics.cells_per_side), any integer from 8, from which the peer derives its
/// cells around (openfoam::arrayCellsAround).
constexpr int kMaxLevel = 4096;

/// Refuses, before OpenFOAM starts, a ladder above the case file's cap and a mask image whose
/// reading does not fit in run.max_memory (InputError naming the option or key: exit 2).
void checkPeerLimits(const Case& c, const std::vector<int>& cli_levels) {
  if (c.kind() == "image-permeability") {
    if (!cli_levels.empty())
      throw InputError({}, "option --levels does not apply to image-permeability", fmt::format("--levels {}", fmt::join(cli_levels, ",")),
                       "numerics.cells_per_pixel (one level) or numerics.cells_per_pixel_levels (a ladder) in the case file to set the mesh resolution");
    // The peer's mask reader (openfoam::loadMask: imread, threshold, connected components,
    // the connected-pore image) holds ~12 B per pixel, as mmval's own mask reader does (measured
    // 11.5 B/px, simulate/src/MemoryBudget.hpp); checked from the header, before decoding.
    constexpr double kPeerMaskBytesPerPixel = 12;
    requireImageWithin(c.path("geometry.mask"), c.where("geometry.mask"), maxMemoryBytes(c), kPeerMaskBytesPerPixel,
                       "a smaller image: crop or downscale it");
    return;
  }
  const bool array = c.kind() == "periodic-array";
  auto check = [array](int level, const InputLocation& where, const std::string& shown) {
    if (array && (level < 8 || level > kMaxLevel))
      throw InputError(where, "a resolution level must be from 8 to " + std::to_string(kMaxLevel) + " (the case file's cap)", shown,
                       "8 to " + std::to_string(kMaxLevel) + " cells along the unit-cell side");
    if (!array && (level < 8 || level > kMaxLevel || level % 4 != 0))
      throw InputError(where, "a resolution level must be a multiple of 4 from 8 to " + std::to_string(kMaxLevel) + " (the case file's cap)", shown,
                       "8, 12, 16, ..., " + std::to_string(kMaxLevel) + " cells around");
  };
  for (const int l : cli_levels) check(l, {"", 0, 0, "--levels"}, fmt::format("--levels {}", l));
  if (cli_levels.empty() && c.has("numerics.levels"))
    for (const auto l : c.integers("numerics.levels"))
      check(l > kMaxLevel ? kMaxLevel + 1 : static_cast<int>(l), c.where("numerics.levels"), std::to_string(l));
}

}  // namespace

void registerPeerCommands(CLI::App& app, const CaseKindRegistry& registry) {
  CLI::App* peer = app.add_subcommand("peer", "Run a case through an established peer solver, side by side with mmval");
  peer->require_subcommand(1);
  auto o = std::make_shared<PeerCli>();
  CLI::App* of = peer->add_subcommand("openfoam", "Write, run and read an OpenFOAM v1912 case generated from the case file (kept in DIR)");
  of->add_option("case", o->file, "Case file (cylinder-channel, periodic-array or image-permeability)")->required();
  of->add_option("--out", o->out, "Output folder: result.json and the OpenFOAM case(s)")->required();
  of->add_option("--np", o->np, "MPI ranks (decomposePar + mpirun)")->capture_default_str()->check(CLI::Range(1, 64));
  of->add_option("--levels", o->levels, "Resolution ladder (cells around the cylinder; periodic arrays: cells along the unit-cell side), overrides numerics.levels")->delimiter(',');
  of->add_option("--mesher", o->mesher,
                 "image-permeability: direct (mmval meshes the image: wall vertices snapped to the smooth boundary, or the pixel staircase exactly "
                 "at whole numbers of cells per pixel; default) or snappy (snappyHexMesh on the boundary's STL)")
      ->capture_default_str()
      ->check(CLI::IsMember({"direct", "snappy"}));
  of->add_flag("--quiet", o->quiet, "No progress output");
  of->callback([o, &registry] {
    const Case c = Case::load(o->file, registry);
    openfoam::peerScene(c);  // the case's scene, read before anything runs: refuses other kinds, naming case.kind
    checkPeerLimits(c, o->levels);  // resolution and image size, before OpenFOAM is even looked for
    if (!openfoam::detect().available) {
      std::fprintf(stderr, "mmval: OpenFOAM peer not run: %s\n", openfoam::detect().reason.c_str());
      throw InputError({o->file, 0, 0, {}}, "OpenFOAM is not installed", {}, "the Debian package 'openfoam' (scripts/setup-deps.sh installs it)");
    }
    openfoam::PeerRunOptions options;
    options.ranks = o->np;
    options.snappy_image_mesh = o->mesher == "snappy";
    if (!o->levels.empty()) options.levels = o->levels;
    const RunSummary s = runCaseWith(
        c, [&](const Case& cc, const RunContext& ctx) { return openfoam::runPeer(cc, ctx, options); }, o->out, {o->quiet, false});
    reports::Summary summary;
    summary.results.push_back(s.result);
    std::fputs(summary.text().c_str(), stdout);
    std::printf("peer openfoam: %s in %.1f s -> %s\n", s.all_pass ? "all metrics pass" : "SOME METRICS FAIL", s.wall_seconds, s.result_file.string().c_str());
    if (!s.all_pass) throw MetricsFailed(fmt::format("case '{}' through OpenFOAM: an acceptance metric failed", c.name()));
  });
}

}  // namespace mmval::app
