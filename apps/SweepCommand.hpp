// `mmval sweep`: the command line of a sweep (validate/Sweep.hpp runs it).
#pragma once
#include <CLI/CLI.hpp>

#include "mmval/core/CaseKind.hpp"

namespace mmval::app {

/// Adds the `sweep` subcommand; `registry` must outlive the app.
void registerSweepCommand(CLI::App& app, const CaseKindRegistry& registry);

}  // namespace mmval::app
