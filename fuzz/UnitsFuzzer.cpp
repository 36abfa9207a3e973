// The units parser (Units.hpp): parseUnit, parseQuantity, fromSi and the names
// of dimensions. Expected outcome of bad input: UnitError. A parsed quantity
// converted back into its own unit must give a finite number.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstdio>
#include <string>

#include "FuzzSupport.hpp"
#include "mmval/core/Units.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = mmval::fuzz::asText(data, size);
  try {
    const mmval::Unit u = mmval::parseUnit(text);
    (void)mmval::dimensionName(u.dim);
    (void)u.dim.siString();
    const double back = mmval::fromSi(u.to_si, text);
    if (std::isfinite(u.to_si) && u.to_si != 0.0 && std::isnormal(u.to_si) && !std::isfinite(back)) {
      std::fprintf(stderr, "fromSi(to_si, unit) is not finite for unit '%.*s'\n", static_cast<int>(size), text.data());
      std::abort();
    }
  } catch (const mmval::UnitError&) {
  }
  try {
    const mmval::Quantity q = mmval::parseQuantity(text);
    (void)mmval::dimensionName(q.dim);
  } catch (const mmval::UnitError&) {
  }
  return 0;
}
