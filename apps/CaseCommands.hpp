// Subcommands that work on case files: case-check, case-doc, run, validate.
#pragma once
#include <CLI/CLI.hpp>

#include "mmval/core/CaseKind.hpp"

namespace mmval::app {

/// Adds the case subcommands; `registry` must outlive the app.
void registerCaseCommands(CLI::App& app, const CaseKindRegistry& registry);

}  // namespace mmval::app
