// Minimum-cost assignment (rectangular Hungarian method, shortest augmenting
// paths with potentials, O(n^2 m)). Used by the global linker per connected
// component of candidate links, and by the scoring of tracks against truth.
#pragma once
#include <vector>

namespace mmval::tracking {

/// cost[i][j] for rows i < n, columns j < m, n <= m. Returns, for each row,
/// its column. Entries >= kForbidden are never chosen unless unavoidable.
std::vector<int> solveAssignment(const std::vector<std::vector<double>>& cost);

inline constexpr double kForbidden = 1e18;

}  // namespace mmval::tracking
