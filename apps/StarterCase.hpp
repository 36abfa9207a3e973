// `mmval init KIND`: a commented starter case file written from the kind's
// schema declarations, so it can never disagree with what `case-check` accepts.
#pragma once
#include <string>

#include "mmval/core/Schema.hpp"

namespace mmval::app {

/// A TOML case file for `schema`'s kind: every declared key under its table,
/// each preceded by its meaning, type, unit, range and default. case.kind is
/// set; keys with a default are commented out with that default (uncomment to
/// change); keys without one are commented-out lines `#key =` marked REQUIRED
/// (or optional), for the user to fill. The declared metrics close the file
/// with a commented [[acceptance]] example.
std::string starterCase(const Schema& schema);

}  // namespace mmval::app
