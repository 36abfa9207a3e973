// mmval: validate pore-scale simulations of fines migration against
// micromodel experiments. One command, one subcommand per capability.
#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>
#include <exception>
#include <filesystem>
#include <new>

#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include "CaseCommands.hpp"
#include "PeerCommands.hpp"
#include "Registry.hpp"
#include "ReportCommands.hpp"
#include "TrackCommands.hpp"
#include "mmval/core/BuildInfo.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Strings.hpp"
#include "mmval/core/Units.hpp"

namespace {

/// Thrown by subcommands to leave with a given status after printing their own message.
int toStatus(mmval::ExitCode code) { return static_cast<int>(code); }

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"mmval: validate pore-scale simulations of fine-particle migration against micromodel experiments"};
  app.require_subcommand(1);
  app.set_version_flag("--version", fmt::format("mmval {} ({}, {}, {})", mmval::build::kVersion, mmval::build::kGitHash,
                                                mmval::build::kCompiler, mmval::build::kBuildType));
  mmval::CaseKindRegistry registry;
  mmval::app::registerAllKinds(registry);
  mmval::app::registerCaseCommands(app, registry);
  mmval::app::registerReportCommands(app);
  mmval::app::registerPeerCommands(app, registry);
  mmval::app::registerTrackCommands(app, registry);
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
