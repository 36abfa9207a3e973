// Small string helpers used for messages (nearest-key suggestions).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace mmval {

/// Levenshtein distance (insertions, deletions, substitutions each cost 1).
std::size_t editDistance(std::string_view a, std::string_view b);

/// The candidate closest to `word`, or "" when none is close enough to be a
/// plausible typo (distance above max(2, |word| / 3)).
std::string nearest(std::string_view word, const std::vector<std::string>& candidates);

/// Joins with a separator.
std::string join(const std::vector<std::string>& parts, std::string_view separator);

}  // namespace mmval
