// `mmval chip`: a micromodel mask from target statistics (porosity, depth-averaged permeability,
// grain-size distribution, mean throat), with its statistics report (docs/chip-generator.md).
#pragma once
#include <CLI/CLI.hpp>

namespace mmval::app {

void registerChipCommand(CLI::App& app);

}  // namespace mmval::app
