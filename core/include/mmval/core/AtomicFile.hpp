// Nothing is lost: outputs are written under a temporary name and renamed
// into place when complete, so a reader never sees a half-written file and an
// interrupted run leaves the previous result intact.
#pragma once

#include <filesystem>
#include <string_view>

namespace mmval {

/// Writes `content` to `path` atomically (same-directory temporary + rename).
/// Creates parent directories. Throws std::runtime_error naming the path on failure.
void writeFileAtomic(const std::filesystem::path& path, std::string_view content);

/// A temporary path beside `final_path` for writers that need a file name
/// (OpenCV, CSV streams); call commitTemporary() when the file is complete.
std::filesystem::path temporaryPathFor(const std::filesystem::path& final_path);
void commitTemporary(const std::filesystem::path& temporary, const std::filesystem::path& final_path);

/// A staging directory for a whole run: work happens in `<dir>.partial`, and
/// commit() swaps it into place. If the object is destroyed without commit(),
/// the staging directory is left for inspection and the old `dir` is untouched.
class StagedDirectory {
 public:
  /// With `resume`, an existing `<dir>.partial` from an interrupted run is kept
  /// so the runner can pick up its checkpoints; otherwise it is cleared.
  explicit StagedDirectory(std::filesystem::path final_dir, bool resume = false);
  const std::filesystem::path& path() const { return m_staging; }
  const std::filesystem::path& finalPath() const { return m_final; }
  void commit();

 private:
  std::filesystem::path m_final;
  std::filesystem::path m_staging;
  bool m_committed = false;
};

}  // namespace mmval
