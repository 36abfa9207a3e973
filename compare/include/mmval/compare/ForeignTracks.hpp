// Tracks written by other trackers, read into the shared tracks schema
// (core/Tracks.hpp) so that `mmval compare` takes them as they come:
//
//   mmval     mmval's own tracks.csv / trajectories.csv (readTracksCsv).
//   trackpy   a linked DataFrame saved with pandas' to_csv (trackpy.link or
//             trackpy.link_df output): columns x, y (pixels, y down from the
//             image's top-left, as trackpy's locate gives them), frame,
//             particle, and any of trackpy's feature columns (mass, size, ecc,
//             signal, raw_mass, ep), optionally after an unnamed index column.
//             trackpy stores frames, not times: the frame rate is needed, and
//             the pixel size to give micrometres.
//   trackmate the "Spots" table TrackMate (Fiji) exports as CSV: a header of
//             feature keys (TRACK_ID, FRAME, POSITION_X, POSITION_Y,
//             POSITION_T, ...), then, in TrackMate 7 and later, three rows of
//             feature names, short names and units such as "(micron)" and
//             "(sec)". Positions are in the calibrated unit of the image (y down
//             from the top-left, as ImageJ); spots outside any track have an
//             empty TRACK_ID and are skipped, as are tracks that split or merge
//             (two spots of one track in one frame): mmval compares simple tracks.
//
// trackpy's quality columns are not mapped onto mmval's (its size is a radius
// of gyration, its mass is in the video's grey levels): they are left unmeasured.
#pragma once
#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>

#include "mmval/core/Tracks.hpp"

namespace mmval::compare {

enum class TrackFormat { automatic, mmval, trackpy, trackmate };

/// "auto", "mmval", "trackpy", "trackmate"; throws std::invalid_argument otherwise.
TrackFormat parseTrackFormat(std::string_view name);
const char* trackFormatName(TrackFormat f);

struct TrackImport {
  TrackFormat format = TrackFormat::automatic;
  double pixel_size = 0.0;  ///< m; converts pixel positions (trackpy; TrackMate in pixels); 0: none given
  double fps = 0.0;         ///< Hz; frame rate for files that store frames, not times (trackpy); 0: none given
};

struct ImportedTracks {
  Tracks tracks;                     ///< sorted by particle, then frame
  TrackFormat format = TrackFormat::mmval;  ///< the format read (sniffed when asked for automatic)
  std::int64_t skipped_spots = 0;    ///< TrackMate: spots outside any track or in a track that splits or merges
  std::int64_t skipped_tracks = 0;   ///< TrackMate: tracks left out because they split or merge
  std::string note;                  ///< one sentence on what was read and how time and position were derived
};

/// The format of a tracks CSV from its header line: POSITION_X -> trackmate;
/// t_s or x_um -> mmval; x, y, frame, particle without them -> trackpy.
/// Throws InputError naming the file when it cannot tell.
TrackFormat sniffTrackFormat(const std::filesystem::path& file);

/// Reads `file` in `options.format` (sniffed when automatic). Throws InputError
/// naming the file, line and column: a missing column, a value that is not a
/// number, trackpy without `fps` or `pixel_size`, TrackMate positions in pixels
/// without `pixel_size`, a frame below 0.
ImportedTracks readTracksAnyFormat(const std::filesystem::path& file, const TrackImport& options);

}  // namespace mmval::compare
