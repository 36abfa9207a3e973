// Subcommands that compare and report: compare, report.
#pragma once
#include <CLI/CLI.hpp>

namespace mmval::app {

void registerReportCommands(CLI::App& app);

}  // namespace mmval::app
