// `mmval peer openfoam CASE`: the same case file through the OpenFOAM peer.
#pragma once
#include <CLI/CLI.hpp>

#include "mmval/core/CaseKind.hpp"

namespace mmval::app {

void registerPeerCommands(CLI::App& app, const CaseKindRegistry& registry);

}  // namespace mmval::app
