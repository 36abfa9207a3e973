// Every case kind the `mmval` command knows, from every library.
#pragma once
#include "mmval/core/CaseKind.hpp"

namespace mmval::app {

/// Registers the kinds of all capabilities that have landed.
void registerAllKinds(CaseKindRegistry& registry);

}  // namespace mmval::app
