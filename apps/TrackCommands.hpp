// `mmval track` (a video -> tracks and statistics) and `mmval synth` (a
// synthetic micromodel video with ground truth).
#pragma once
#include <CLI/CLI.hpp>

#include "mmval/core/CaseKind.hpp"

namespace mmval::app {

void registerTrackCommands(CLI::App& app, const CaseKindRegistry& registry);

}  // namespace mmval::app
