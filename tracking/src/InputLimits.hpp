// Bounds on the tracking kinds' input files, checked before they are read:
// a tracks CSV that is /dev/zero or a FIFO is never read forever,
// and one too large for memory is refused with its size.
#pragma once

#include <filesystem>
#include <string>
#include <system_error>

#include <fmt/format.h>

#include "mmval/core/Case.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Resources.hpp"

namespace mmval::tracking::detail {

/// A tracks CSV read into memory costs ~5 B per byte of file: 240 B per TrackPoint record held
/// (measured with /usr/bin/time -v on `mmval synth`, 2e6 records) for 48 B per CSV line (its truth.csv).
inline constexpr double kTrackBytesPerCsvByte = 5;

/// Refuses (InputError at `key` of `c`) a tracks file that is not a regular file, or whose
/// records would not fit in run.max_memory. Missing files are left to readTracksCsv's message.
inline void requireTracksFile(const Case& c, const std::filesystem::path& file, const std::string& key) {
  std::error_code ec;
  const auto status = std::filesystem::status(file, ec);
  if (ec || !std::filesystem::exists(status)) return;
  if (!std::filesystem::is_regular_file(status))
    throw InputError(c.where(key), "the tracks file is not a regular file (a device or a pipe is never read to its end)", file.string(),
                     "a CSV file with columns frame, particle, t_s, x_um, y_um");
  const double size = static_cast<double>(std::filesystem::file_size(file, ec));
  if (!ec)
    requireMemory(c, size * kTrackBytesPerCsvByte, fmt::format("reading the tracks file '{}' ({})", file.string(), formatBytes(size)), key,
                  "a smaller tracks file (fewer frames or particles)");
}

}  // namespace mmval::tracking::detail
