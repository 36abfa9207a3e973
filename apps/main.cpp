// mmval: validate pore-scale simulations of fines migration against
// micromodel experiments. One command, one subcommand per capability.
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>
#include <exception>
#include <filesystem>
#include <new>

#include <dlfcn.h>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "CaseCommands.hpp"
#include "ChipCommand.hpp"
#include "PeerCommands.hpp"
#include "Registry.hpp"
#include "ReportCommands.hpp"
#include "SweepCommand.hpp"
#include "TrackCommands.hpp"
#include "mmval/core/BuildInfo.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Strings.hpp"
#include "mmval/core/Units.hpp"

namespace {

/// Thrown by subcommands to leave with a given status after printing their own message.
int toStatus(mmval::ExitCode code) { return static_cast<int>(code); }

/// Short examples shown at the end of each subcommand's --help (and so in the man page).
void addExamples(CLI::App& app) {
  static const std::vector<std::pair<std::string, std::string>> examples = {
      {"case-check", "mmval case-check cases/fluid-poiseuille.toml\n  mmval case-check --resolved my-case.toml"},
      {"case-doc", "mmval case-doc channel\n  mmval case-doc --out case-reference.md"},
      {"init", "mmval init channel\n  mmval init image-permeability --out my-chip.toml"},
      {"run", "mmval run cases/fluid-poiseuille.toml --out out/poiseuille\n"
              "  mmval run cases/fluid-poiseuille.toml --out out/poiseuille-wide --set \"geometry.width=200 um\" --set \"numerics.levels=[16, 32, 64]\""},
      {"validate", "mmval validate\n  mmval validate --tag coupled --out out/coupled\n  mmval validate --full --resume"},
      {"peer", "mmval peer openfoam cases/fluid-schaefer-turek-2d1.toml --out out/st-openfoam --np 2"},
      {"openfoam", "mmval peer openfoam cases/fluid-schaefer-turek-2d1.toml --out out/st-openfoam --np 2 --levels 32,64"},
      {"track", "mmval track video.avi --pixel-size-um 10 --fps 2 --out out/tracks\n"
                "  mmval track 'frames/*.png' --config my-tracking.toml --out out/tracks"},
      {"synth", "mmval synth --out out/synth"},
      {"compare", "mmval compare --experiment out/tracks/tracks.csv --simulation out/run/trajectories.csv --out out/compare"},
      {"report", "mmval report out/validate --out out/report\n  mmval report --diff old/metrics.json new/metrics.json"},
  };
  const auto all = [](CLI::App*) { return true; };
  for (CLI::App* sub : app.get_subcommands(all)) {
    std::vector<CLI::App*> with_nested{sub};
    for (CLI::App* nested : sub->get_subcommands(all)) with_nested.push_back(nested);
    for (CLI::App* s : with_nested)
      for (const auto& [name, text] : examples)
        if (s->get_name() == name) s->footer("\nExamples:\n  " + text);
  }
  app.footer(
      "\nExamples:\n  mmval init channel --out my-channel.toml\n  mmval run my-channel.toml --out out/my-channel\n  mmval validate --out out/validate\n"
      "\nData: reference-data/ and the example cases/ are read from $MMVAL_DATA_DIR, else from ../share/mmval beside the\n"
      "executable (an installed mmval), else from the source tree (a binary in its build tree).\n"
      "Exit status: 0 ok, 1 usage, 2 invalid input, 3 a metric outside its tolerance, 4 a bug in mmval, 5 a numerical failure.");
}

}  // namespace

namespace {

/// One BLAS thread unless the user asks for more. OpenBLAS (Debian's default BLAS) starts a
/// worker per core whose idle wait spins on sched_yield: measured on Schaefer-Turek 2D-2 (0.2 s
/// of flow, 2 cores) 7.5 s of system CPU beside 15.8 s of user CPU, 0.3 s with one thread and
/// the same user time. mmval's own parallelism is its ranks and tracker threads, so the BLAS
/// inside the direct solvers runs on one. OPENBLAS_NUM_THREADS or OMP_NUM_THREADS in the
/// environment is respected; with another BLAS the symbol is absent and nothing happens.
void limitBlasThreads() {
  if (std::getenv("OPENBLAS_NUM_THREADS") != nullptr || std::getenv("OMP_NUM_THREADS") != nullptr) return;
  using SetThreads = void (*)(int);
  if (auto* set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(1);
}

}  // namespace

int main(int argc, char** argv) {
  limitBlasThreads();
  // Named, so that help and the man page say "mmval" whatever path ran it.
  CLI::App app{"mmval: validate pore-scale simulations of fine-particle migration against micromodel experiments", "mmval"};
  app.require_subcommand(1);
  app.set_version_flag("--version", fmt::format("mmval {} ({}, {}, {})", mmval::build::kVersion, mmval::build::kGitHash,
                                                mmval::build::kCompiler, mmval::build::kBuildType));
  mmval::CaseKindRegistry registry;
  mmval::app::registerAllKinds(registry);
  mmval::app::registerCaseCommands(app, registry);
  mmval::app::registerReportCommands(app);
  mmval::app::registerPeerCommands(app, registry);
  mmval::app::registerTrackCommands(app, registry);
  mmval::app::registerSweepCommand(app, registry);
  mmval::app::registerChipCommand(app);
  addExamples(app);
  if (argc > 1 && argv[1][0] != '-') {
    std::vector<std::string> names;
    for (const CLI::App* sub : app.get_subcommands([](CLI::App*) { return true; })) names.push_back(sub->get_name());
    if (std::find(names.begin(), names.end(), argv[1]) == names.end()) {
      const std::string near = mmval::nearest(argv[1], names);
      std::fprintf(stderr, "mmval: unknown subcommand '%s'%s; the subcommands are: %s (see mmval --help)\n", argv[1],
                   near.empty() ? "" : fmt::format("; did you mean '{}'?", near).c_str(), mmval::join(names, ", ").c_str());
      return toStatus(mmval::ExitCode::usage);
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int status = app.exit(e);
    return status == 0 ? 0 : toStatus(mmval::ExitCode::usage);
  } catch (const mmval::InputError& e) {
    std::fprintf(stderr, "mmval: error: %s\n", e.what());
    return toStatus(mmval::ExitCode::bad_input);
  } catch (const mmval::UnitError& e) {
    std::fprintf(stderr, "mmval: error: %s\n", e.what());
    return toStatus(mmval::ExitCode::bad_input);
  } catch (const mmval::NumericalFailure& e) {
    std::fprintf(stderr, "mmval: numerical failure: %s\n", e.what());
    return toStatus(mmval::ExitCode::numerical);
  } catch (const mmval::MetricsFailed& e) {
    std::fprintf(stderr, "mmval: %s\n", e.what());
    return toStatus(mmval::ExitCode::metric_failed);
  } catch (const std::filesystem::filesystem_error& e) {
    // A folder or file the user named cannot be read or written (permissions,
    // a full disk, a read-only mount): the user's to fix, not a bug.
    std::fprintf(stderr, "mmval: error: %s (check the path, its permissions and the free space)\n", e.what());
    return toStatus(mmval::ExitCode::bad_input);
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "mmval: internal error: out of memory although the run's estimate fitted run.max_memory; please report this "
                         "with the case file\n");
    return toStatus(mmval::ExitCode::internal);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "mmval: internal error: %s\n", e.what());
    return toStatus(mmval::ExitCode::internal);
  }
  return 0;
}
