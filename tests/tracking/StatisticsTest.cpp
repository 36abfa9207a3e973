// Two-sample statistics (Statistics.hpp) against textbook and tabulated values:
// population standard deviation and median, the Wasserstein-1 distance, the
// Kolmogorov distribution's tail Q_KS and the two-sample KS test.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "mmval/tracking/Statistics.hpp"

namespace mmval::tracking {
namespace {

TEST(Statistics, PopulationStdOfTheTextbookSample) {
  // {2,4,4,4,5,5,7,9}: mean 5, population variance 4.
  EXPECT_DOUBLE_EQ(populationStd({2, 4, 4, 4, 5, 5, 7, 9}), 2.0);
  EXPECT_DOUBLE_EQ(median({5, 1, 3}), 3.0);
  EXPECT_DOUBLE_EQ(median({4, 1, 3, 2}), 2.5);
}

TEST(Statistics, WassersteinOfAShiftIsTheShift) {
  std::vector<double> a, b;
  for (int i = 0; i < 1000; ++i) {
    const double x = std::sin(i * 12.9898) * 43758.5453;
    a.push_back(x - std::floor(x));
    b.push_back(a.back() + 0.37);
  }
  EXPECT_NEAR(wasserstein1(a, b), 0.37, 1e-12);
  // Unequal sizes: {0} vs {0, 1}: |F_a - F_b| = 1/2 on [0, 1).
  EXPECT_NEAR(wasserstein1({0.0}, {0.0, 1.0}), 0.5, 1e-15);
}

TEST(Statistics, KolmogorovSeriesMatchesTabulatedValues) {
  // Q_KS(lambda) tabulated: Q(1.0) = 0.2700, Q(0.5) = 0.9639; the classic critical
  // values 1.3581 (5 %) and 1.6276 (1 %).
  EXPECT_NEAR(kolmogorovQ(1.0), 0.26999967, 1e-6);
  EXPECT_NEAR(kolmogorovQ(1.3581), 0.05, 1e-4);
  EXPECT_NEAR(kolmogorovQ(1.6276), 0.01, 1e-4);
  EXPECT_NEAR(kolmogorovQ(0.5), 0.96394, 1e-4);
}

TEST(Statistics, KsStatisticOfSeparatedAndIdenticalSamples) {
  const KsResult apart = kolmogorovSmirnov({1, 2, 3, 4}, {5, 6, 7, 8});
  EXPECT_DOUBLE_EQ(apart.statistic, 1.0);
  EXPECT_LT(apart.p_value, 0.05);
  const KsResult same = kolmogorovSmirnov({1, 2, 3, 4}, {1, 2, 3, 4});
  EXPECT_DOUBLE_EQ(same.statistic, 0.0);
  EXPECT_DOUBLE_EQ(same.p_value, 1.0);
  // {1,2,3} vs {2,3,4}: largest CDF gap is 1/3.
  EXPECT_NEAR(kolmogorovSmirnov({1, 2, 3}, {2, 3, 4}).statistic, 1.0 / 3.0, 1e-15);
}

}  // namespace
}  // namespace mmval::tracking
