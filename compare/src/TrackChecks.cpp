#include "mmval/compare/TrackChecks.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace mmval::compare {

namespace {

std::string fileOf(const Tracks& tracks, const std::string& role) { return tracks.source.empty() ? "(" + role + " tracks)" : tracks.source; }

/// Counts of the rows of each particle (points are sorted by particle, then frame).
struct RowCounts {
  std::size_t particles = 0;
  std::size_t particles_with_two_rows = 0;
  std::size_t particles_with_advancing_time = 0;
};

RowCounts countRows(const Tracks& tracks) {
  RowCounts n;
  const auto& pts = tracks.points;
  for (std::size_t i = 0; i < pts.size();) {
    std::size_t j = i;
    bool advances = false;
    while (j < pts.size() && pts[j].particle == pts[i].particle) {
      advances = advances || pts[j].t > pts[i].t;
      ++j;
    }
    ++n.particles;
    if (j - i >= 2) ++n.particles_with_two_rows;
    if (advances) ++n.particles_with_advancing_time;
    i = j;
  }
  return n;
}

void checkOneRowPerFrame(const Tracks& tracks, const std::string& file) {
  const auto& pts = tracks.points;
  for (std::size_t k = 1; k < pts.size(); ++k)
    if (pts[k].particle == pts[k - 1].particle && pts[k].frame == pts[k - 1].frame)
      throw InputError({file, 0, 0, "particle"}, fmt::format("particle {} has two rows at frame {}", pts[k].particle, pts[k].frame),
                       fmt::format("(t_s {:g}, x_um {:g}) and (t_s {:g}, x_um {:g})", pts[k - 1].t, pts[k - 1].x * 1e6, pts[k].t, pts[k].x * 1e6),
                       "one row per particle per frame (distinct particle ids for distinct particles)");
}

}  // namespace

void checkComparable(const Tracks& tracks, const std::string& role) {
  const std::string file = fileOf(tracks, role);
  const std::string wanted = "rows of particles seen in two or more frames, t_s increasing with frame";
  if (tracks.points.empty()) throw InputError({file, 0, 0, {}}, "no track rows: the file has only its header", "0 rows", wanted);
  checkOneRowPerFrame(tracks, file);
  const RowCounts n = countRows(tracks);
  if (n.particles_with_two_rows == 0)
    throw InputError({file, 0, 0, "particle"}, "every particle has a single row: no motion to measure",
                     fmt::format("{} row(s) of {} particle(s)", tracks.points.size(), n.particles), wanted);
  if (n.particles_with_advancing_time == 0) {
    const double t0 = tracks.points.front().t;
    const bool all_equal = std::all_of(tracks.points.begin(), tracks.points.end(), [&](const TrackPoint& p) { return p.t == t0; });
    throw InputError({file, 0, 0, "t_s"}, "time does not advance within any particle",
                     all_equal ? fmt::format("t_s = {:g} s in every row", t0) : std::string("t_s constant within each particle"),
                     "t_s in seconds, increasing from frame to frame");
  }
}

void checkReferenceMoves(const Tracks& tracks, const tracking::TrackStats& stats, const tracking::TrackOptions& options) {
  if (!stats.steps.empty()) return;
  throw InputError({fileOf(tracks, "experiment"), 0, 0, {}}, "no step to measure a speed from: every relative error would divide by zero",
                   fmt::format("{} particle(s): {} immobile (never farther than {:g} um from their start), {} shorter than {} rows, {} mobile", stats.particles,
                               stats.immobile, options.immobile_distance * 1e6, stats.short_tracks, options.min_points, stats.mobile),
                   "at least one particle that moves and is seen in enough frames");
}

}  // namespace mmval::compare
