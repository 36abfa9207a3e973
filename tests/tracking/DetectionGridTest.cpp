// The radius-query grids of the detector and the linker (tracking/src/DetectionGrid.hpp)
// against a brute-force search over all points: the same points, the same distances.
// GrowingGrid is queried after every point added, as the joint spot fit's search for
// hidden spots does (instead of comparing each new spot with every earlier one).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

// An internal header of the tracking library (no installed interface).
#include "../../tracking/src/DetectionGrid.hpp"

namespace mmval::tracking::detail {
namespace {

// Distances are computed the same way by the grid and the reference; round-off class.
constexpr double kDistanceTolerance = 1e-12;

struct Hit {
  int item;
  double dist;
  bool operator<(const Hit& o) const { return item < o.item; }
};

std::vector<Hit> bruteForce(const std::vector<Detection>& d, std::size_t count, double x, double y, double r) {
  std::vector<Hit> out;
  for (std::size_t i = 0; i < count; ++i) {
    const double dx = d[i].x - x, dy = d[i].y - y;
    if (dx * dx + dy * dy <= r * r) out.push_back({static_cast<int>(i), std::sqrt(dx * dx + dy * dy)});
  }
  return out;
}

void expectSame(std::vector<Hit> got, const std::vector<Hit>& want, double x, double y, double r) {
  std::sort(got.begin(), got.end());
  ASSERT_EQ(got.size(), want.size()) << "query (" << x << ", " << y << ") r " << r;
  for (std::size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(got[k].item, want[k].item);
    EXPECT_NEAR(got[k].dist, want[k].dist, kDistanceTolerance);
  }
}

/// Points in and around a 200 x 120 px frame (some outside it, some on cell borders).
std::vector<Detection> points(std::size_t n, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> ux(-10, 210), uy(-10, 130);
  std::vector<Detection> d(n);
  for (std::size_t i = 0; i < n; ++i) {
    d[i].x = i % 7 == 0 ? std::round(ux(rng)) : ux(rng);  // integer positions, as the hidden spots have
    d[i].y = i % 7 == 0 ? std::round(uy(rng)) : uy(rng);
  }
  return d;
}

TEST(DetectionGrid, RadiusQueriesMatchBruteForce) {
  const std::vector<Detection> d = points(1500, 3);
  for (double cell : {2.0, 7.5}) {
    const DetectionGrid grid(d, cell);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> ux(-20, 220), uy(-20, 140), ur(0.5, 12);
    for (int q = 0; q < 300; ++q) {
      const double x = ux(rng), y = uy(rng), r = ur(rng);
      std::vector<Hit> got;
      grid.near(x, y, r, [&](int i, double dist) { got.push_back({i, dist}); });
      expectSame(got, bruteForce(d, d.size(), x, y, r), x, y, r);
    }
  }
}

TEST(DetectionGrid, GrowingGridQueriesAfterEachAddMatchBruteForce) {
  const std::vector<Detection> d = points(1200, 11);
  GrowingGrid grid(200, 120, 2.0);
  std::mt19937 rng(13);
  std::uniform_real_distribution<double> ux(-20, 220), uy(-20, 140), ur(0.5, 9);
  for (std::size_t i = 0; i < d.size(); ++i) {
    grid.add(static_cast<int>(i), d[i].x, d[i].y);
    // Around the point just added (as the hidden-spot search asks) and anywhere.
    for (int q = 0; q < 2; ++q) {
      const double x = q == 0 ? d[i].x + 0.7 : ux(rng), y = q == 0 ? d[i].y - 1.1 : uy(rng), r = ur(rng);
      std::vector<Hit> got;
      grid.near(x, y, r, [&](int item, double dist) { got.push_back({item, dist}); });
      expectSame(got, bruteForce(d, i + 1, x, y, r), x, y, r);
    }
  }
}

TEST(DetectionGrid, GrowingGridNeverFindsNaNPositions) {
  GrowingGrid grid(50, 50, 2.0);
  grid.add(0, std::nan(""), 3.0);
  grid.add(1, 1.0, 1.0);
  std::vector<int> found;
  grid.near(0.5, 0.5, 5.0, [&](int item, double) { found.push_back(item); });
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0], 1);
}

}  // namespace
}  // namespace mmval::tracking::detail
