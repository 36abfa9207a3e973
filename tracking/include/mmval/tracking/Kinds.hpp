// Case kinds of the tracker.
#pragma once
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Schema.hpp"
#include "mmval/tracking/Pipeline.hpp"

namespace mmval::tracking {

/// "tracking-synthetic": renders a synthetic micromodel video with ground
/// truth, tracks it, and scores the tracks (Chenouard et al. 2014).
void registerTrackingKinds(CaseKindRegistry& registry);

/// "tracking-rendered": a simulation's trajectories drawn as a microscope video
/// over its geometry, tracked, and scored against them (registered by the above).
void registerRenderedKind(CaseKindRegistry& registry);

/// Runs a "tracking-video" case (also what `mmval track` does).
RunOutput runTrackingVideo(const Case& c, const RunContext& ctx);

/// The detection / linking keys ([detect], [link]) shared by every tracking case.
void declareTrackerKeys(Schema& s);
TrackConfig trackerConfig(const Case& c);

/// The run's background and polarity decisions, with their numbers and reasons, as the
/// "background" and "detection" entries of summary.json.
void addSceneDecisions(const TrackRun& run, nlohmann::json& summary);

}  // namespace mmval::tracking
