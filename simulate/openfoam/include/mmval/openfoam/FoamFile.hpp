// Small helpers for writing OpenFOAM dictionaries by hand-readable text.
#pragma once
#include <string>

namespace mmval::openfoam {

/// The FoamFile header every dictionary starts with.
std::string foamHeader(const std::string& cls, const std::string& object, const std::string& location = {});

}  // namespace mmval::openfoam
