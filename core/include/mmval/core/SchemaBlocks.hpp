// Key blocks shared by kinds: one declaration (name, unit, meaning, bounds) for a
// key that several kinds read, composed into each kind's schema with that kind's
// defaults. tests/apps/SchemaBlocksTest.cpp checks that no kind declares these
// keys any other way. (Defined in Schema.cpp.)
#pragma once
#include <string>
#include <vector>

#include "mmval/core/Schema.hpp"

namespace mmval {

/// The fluid: fluid.viscosity, fluid.density and, for kinds with Brownian motion, fluid.temperature.
struct FluidBlock {
  double viscosity = 1e-3;        ///< Pa s (water at about 20 C)
  double density = 998.2;         ///< kg/m3 (water at 20 C)
  double temperature = 293.15;    ///< K
  bool with_density = true;       ///< declare fluid.density (kinds without inertia or buoyancy leave it out)
  bool with_temperature = false;  ///< declare fluid.temperature (kinds with Brownian motion)
};
void declareFluid(Schema& schema, const FluidBlock& block);

/// A binary image of the pore geometry: geometry.mask, geometry.pixel_size and
/// geometry.grains (dark | bright; "light" read as the older spelling of "bright").
struct MaskBlock {
  std::string mask_doc = {};        ///< what the image is to this kind
  std::string pixel_default = {};   ///< e.g. "1 um"; empty: required
  bool optional = false;            ///< the kind runs without an image
};
void declareMask(Schema& schema, const MaskBlock& block);
/// The choices geometry.grains accepts, in the order case-doc lists them.
const std::vector<std::string>& grainChoices();

}  // namespace mmval
