// Tracking accuracy against ground truth, after Chenouard et al. (2014),
// Nature Methods 11:281 (the particle tracking challenge): tracks are paired
// by optimal assignment under a gate; the track distance sums, over the union
// of time points, min(|x - y|, gate) with a missing position counting as the
// gate. Reported: alpha (1 - d(X,Y) / d(X,0)), beta (also penalising
// spurious tracks), Jaccard of points and of whole tracks, and the RMSE of
// matched points. That RMSE (the challenge's) mixes two errors: localisation
// (a fraction of a pixel) and a paired track that follows a neighbour for a
// few frames (errors up to the gate). Both are also reported apart.
#pragma once
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/TrackMetrics.hpp"

namespace mmval::tracking {

struct Scores {
  double alpha = 0, beta = 0;
  double jaccard_points = 0, jaccard_tracks = 0;
  double rmse_px = 0;  ///< over every matched point (error < gate): the challenge's RMSE
  /// Over the matched points within `localisation_gate` of the truth: the localisation
  /// error alone. The points beyond it (`gross_points`) are counted, not averaged.
  double rmse_localisation_px = 0;
  long long gross_points = 0;
  long long tp = 0, fp = 0, fn = 0;
  int truth_tracks = 0, estimated_tracks = 0, paired_tracks = 0;
};

/// Both track sets in pixels (x_px, y_px). `gate` in px (5 in the challenge).
/// `localisation_gate` (px) splits the matched points into localisation errors and
/// gross errors: 1 px is > 4 standard deviations of a spot's position at SNR 4
/// (Cramer-Rao ~0.2 px per axis), so a matched point beyond it is a wrong particle,
/// not noise.
Scores scoreTracks(const Tracks& truth, const Tracks& estimated, double gate = 5.0, double localisation_gate = 1.0);

/// The scores as a result.json object ("scores") and as a case's metrics (jaccard_points,
/// jaccard_tracks, rmse, rmse_localisation, gross_points; alpha and beta are the caller's).
nlohmann::json scoresJson(const Scores& s);
void addScoreMetrics(const Scores& s, std::map<std::string, double>& metrics);

/// Share of the truth particles `immobile_ids` (stuck all video long) on which an
/// estimated track flagged immobile by `stats` sits: its first point within
/// `gate` px of the truth particle's first point. 1 when there are none.
double immobileRecall(const Tracks& truth, const std::vector<std::int64_t>& immobile_ids, const Tracks& estimated, const TrackStats& stats,
                      double gate = 5.0);

}  // namespace mmval::tracking
