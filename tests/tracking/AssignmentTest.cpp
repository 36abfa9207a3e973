// The linear assignment solver (Assignment.hpp) against brute force over every
// injective row-to-column map.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>
#include <vector>

#include "mmval/tracking/Assignment.hpp"

namespace mmval::tracking {
namespace {

TEST(Assignment, MatchesBruteForceOnRandomMatrices) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(0, 10);
  for (int trial = 0; trial < 50; ++trial) {
    const int n = 1 + trial % 5, m = n + trial % 3;
    std::vector<std::vector<double>> c(n, std::vector<double>(m));
    for (auto& row : c)
      for (auto& x : row) x = U(rng);
    const auto a = solveAssignment(c);
    double got = 0;
    for (int i = 0; i < n; ++i) got += c[i][a[i]];
    // Brute force over all injective maps rows -> columns.
    std::vector<int> cols(m);
    std::iota(cols.begin(), cols.end(), 0);
    double best = 1e300;
    do {
      double s = 0;
      for (int i = 0; i < n; ++i) s += c[i][cols[i]];
      best = std::min(best, s);
    } while (std::next_permutation(cols.begin(), cols.end()));
    EXPECT_NEAR(got, best, 1e-9) << "trial " << trial;
  }
}

}  // namespace
}  // namespace mmval::tracking
