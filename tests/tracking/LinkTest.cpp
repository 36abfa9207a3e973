// The frame-to-frame linker (Link.hpp): gap closing, neighbour velocity for
// new tracks, and a dense field that must stay linear in cost.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "mmval/tracking/Detect.hpp"
#include "mmval/tracking/Link.hpp"

namespace mmval::tracking {
namespace {

TEST(Link, GapClosingBridgesMissedFrames) {
  // One particle moving 2 px per frame, missing in frames 3 and 4.
  TrackLinker with({Linker::global, 5.0, 2, Prediction::automatic});
  TrackLinker without({Linker::global, 5.0, 0, Prediction::automatic});
  for (int f = 0; f < 8; ++f) {
    std::vector<Detection> d;
    if (f != 3 && f != 4) d.push_back({10.0 + 2 * f, 20.0, 5, 1, 1});
    with.push(f, d);
    without.push(f, d);
  }
  auto ids = [](const std::vector<LinkedPoint>& pts) {
    std::vector<std::int64_t> v;
    for (const auto& p : pts) v.push_back(p.particle);
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
    return v.size();
  };
  EXPECT_EQ(ids(with.points()), 1u);
  EXPECT_EQ(with.stats().gap_closures, 1);
  EXPECT_EQ(ids(without.points()), 2u);
}

TEST(Link, NewTracksFollowTheirNeighboursVelocity) {
  // Two lanes moving 6 px per frame along x. Lane B (y = 30) is sparse (20 px apart),
  // tracked from the start and fed at x = 0 as it leaves at x = 300. Into lane A (y = 20) a particle enters at x = 0 every frame
  // from frame 5, so its particles are 6 px apart: a particle's first link is ambiguous,
  // the newcomer appears exactly where it was (distance 0) while it moved 6 px. Without a
  // velocity of its own a new track takes the newcomer; borrowing the velocity of its
  // neighbours in lane B (10 px away) it takes itself.
  auto run = [](double neighbour_radius) {
    LinkOptions o;
    o.search_radius = 8.0;
    o.memory = 0;
    o.neighbour_radius = neighbour_radius;
    TrackLinker linker(o);
    for (int f = 0; f < 40; ++f) {
      std::vector<Detection> d;
      const auto add = [&](double x, double y) {
        Detection q;
        q.x = x;
        q.y = y;
        if (x < 300) d.push_back(q);
      };
      for (int k = 0; k < 15; ++k) add(std::fmod(20.0 * k + 6.0 * f, 300.0), 30.0);  // lane B: re-enters at x = 0
      for (int k = 5; k <= f; ++k) add(6.0 * (f - k), 20.0);      // lane A: particle k entered at frame k
      linker.push(f, d);
    }
    // Links of lane A: right when consecutive points of one track are 6 px apart along x.
    int right = 0, wrong = 0;
    const auto pts = linker.points();
    for (std::size_t i = 1; i < pts.size(); ++i)
      if (pts[i].particle == pts[i - 1].particle && pts[i].y == 20.0) (std::abs(pts[i].x - pts[i - 1].x - 6.0) < 1e-9 ? right : wrong)++;
    return std::make_pair(right, wrong);
  };
  const auto [right_n, wrong_n] = run(20.0);
  const auto [right_0, wrong_0] = run(0.0);
  std::printf("lane A: with neighbours %d right / %d wrong links; without %d / %d\n", right_n, wrong_n, right_0, wrong_0);
  EXPECT_GT(right_n, 300);
  EXPECT_EQ(wrong_n, 0);
  EXPECT_GT(wrong_0, 30);
}

TEST(Link, DenseFieldStaysLinear) {
  // 2,500 particles per frame on a lattice drifting 1 px per frame: every one linked,
  // components stay small (no combinatorial blow-up).
  TrackLinker linker({Linker::global, 3.0, 0, Prediction::automatic});
  for (int f = 0; f < 5; ++f) {
    std::vector<Detection> d;
    for (int i = 0; i < 50; ++i)
      for (int j = 0; j < 50; ++j) d.push_back({i * 8.0 + f, j * 8.0, 5, 1, 1});
    linker.push(f, d);
  }
  EXPECT_EQ(linker.stats().new_tracks, 2500);
  EXPECT_EQ(linker.stats().links, 4 * 2500);
  EXPECT_LE(linker.stats().largest_component, 4);
}

}  // namespace
}  // namespace mmval::tracking
