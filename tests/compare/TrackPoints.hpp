// A track point without the optional columns, for the comparator tests.
#pragma once
#include <cstdint>

#include "mmval/core/Tracks.hpp"

namespace mmval::compare::test_support {

inline TrackPoint pt(std::int64_t frame, std::int64_t particle, double t, double x, double y) {
  TrackPoint q;
  q.frame = frame;
  q.particle = particle;
  q.t = t;
  q.x = x;
  q.y = y;
  return q;
}

}  // namespace mmval::compare::test_support
