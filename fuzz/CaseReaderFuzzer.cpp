// Case::parse with every real kind's schema (apps/Registry.cpp): TOML syntax,
// the schema walk, units, ranges and acceptance entries. Expected outcome of
// bad input: InputError (Case.hpp). On a valid case, resolvedJson() and hash()
// must work too, since `mmval run` writes them into result.json.
#include <cstddef>
#include <cstdint>
#include <string>

#include "FuzzSupport.hpp"
#include "Registry.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"

namespace {

const mmval::CaseKindRegistry& registry() {
  static const mmval::CaseKindRegistry r = [] {
    mmval::CaseKindRegistry reg;
    mmval::app::registerAllKinds(reg);
    return reg;
  }();
  return r;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // A file in cases/, so that the seeds' reference pointers
  // ("../reference-data/...") resolve and are read as well.
  static const std::string file = std::string(MMVAL_SOURCE_DIR) + "/cases/fuzz-input.toml";
  try {
    const mmval::Case c = mmval::Case::parse(mmval::fuzz::asText(data, size), file, registry());
    (void)c.resolvedJson().dump();
    (void)c.hash();
  } catch (const mmval::InputError&) {
  }
  return 0;
}
