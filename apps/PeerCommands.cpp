#include "PeerCommands.hpp"

#include <cstdio>
#include <memory>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
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
  bool quiet = false;
};
}  // namespace

void registerPeerCommands(CLI::App& app, const CaseKindRegistry& registry) {
  CLI::App* peer = app.add_subcommand("peer", "Run a case through an established peer solver, side by side with mmval");
  peer->require_subcommand(1);
  auto o = std::make_shared<PeerCli>();
  CLI::App* of = peer->add_subcommand("openfoam", "Write, run and read an OpenFOAM v1912 case generated from the case file (kept in DIR)");
  of->add_option("case", o->file, "Case file (cylinder-channel, periodic-array or image-permeability)")->required();
  of->add_option("--out", o->out, "Output folder: result.json and the OpenFOAM case(s)")->required();
  of->add_option("--np", o->np, "MPI ranks (decomposePar + mpirun)")->capture_default_str()->check(CLI::Range(1, 64));
  of->add_option("--levels", o->levels, "Resolution ladder (cells around the cylinder), overrides numerics.levels")->delimiter(',');
  of->add_flag("--quiet", o->quiet, "No progress output");
  of->callback([o, &registry] {
    const Case c = Case::load(o->file, registry);
    openfoam::peerScene(c);  // the case's scene, read before anything runs: refuses other kinds, naming case.kind
    if (!openfoam::detect().available) {
      std::fprintf(stderr, "mmval: OpenFOAM peer not run: %s\n", openfoam::detect().reason.c_str());
      throw InputError({o->file, 0, 0, {}}, "OpenFOAM is not installed", {}, "the Debian package 'openfoam' (scripts/setup-deps.sh installs it)");
    }
    openfoam::PeerRunOptions options;
    options.ranks = o->np;
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
