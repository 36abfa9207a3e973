// Internals of the particles-micromodel kind shared by its source files.
#pragma once
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/Schema.hpp"
#include "mmval/particles/MicromodelFlow.hpp"

namespace mmval::particles::detail {

/// Declares every key of the kind.
void declareMicromodel(Schema& s);
/// The mask file: relative to the case file, else to the folder above it; InputError when missing.
std::filesystem::path maskPath(const Case& c);
/// Reads, crops and dilates the mask and closes pores cut off from the inlet or
/// outlet; fills `details` (image, porosity) and `porosity` (connected). InputError on bad input.
PixelMask loadGeometry(const Case& c, nlohmann::json& details, double& porosity);
/// Grains grown by a disc of `radius_px` pixels (Euclidean, centre to centre).
PixelMask dilate(const PixelMask& m, int radius_px);

}  // namespace mmval::particles::detail
