// Nothing is lost: outputs are written under a temporary name and renamed
// into place when complete, so a reader never sees a half-written file and an
// interrupted run leaves the previous result intact.
//
// Only replace what mmval wrote: every output folder mmval completes carries
// a marker file (kOutputMarker) listing the files it wrote. An existing --out
// folder is replaced only when it is empty or marked and holds nothing beyond
// its list; anything else (a user's folder, a regular file, a symbolic link)
// is refused with an InputError before any work starts.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

namespace mmval {

/// Writes `content` to `path` atomically (same-directory temporary + rename).
/// Creates parent directories. Throws std::runtime_error naming the path on failure.
/// Under mpirun only rank 0 writes; on the other ranks this does nothing.
void writeFileAtomic(const std::filesystem::path& path, std::string_view content);

/// False on the ranks other than 0 of a run started by mpirun (Open MPI and
/// MPICH/PMI name the rank in the environment); true otherwise. Every rank
/// computes the same outputs; only the primary one writes and prints them.
bool primaryRank();

/// A temporary path beside `final_path` for writers that need a file name
/// (OpenCV, CSV streams); call commitTemporary() when the file is complete.
std::filesystem::path temporaryPathFor(const std::filesystem::path& final_path);
void commitTemporary(const std::filesystem::path& temporary, const std::filesystem::path& final_path);

/// Name of the marker file in every folder mmval writes (its manifest).
inline constexpr const char* kOutputMarker = ".mmval-output";

/// The output folder a user named, made safe to use: "" and "/" are refused;
/// "out/x/" becomes "out/x"; "." and ".." become the folder they name (which
/// is then refused by checkReplaceable unless it is an mmval output folder).
/// `option` names the command-line option or key in messages ("--out").
std::filesystem::path normaliseOutputPath(const std::string& given, const std::string& option = "--out");

/// Throws InputError (exit 2) unless `dir` may be replaced by an mmval output:
/// it does not exist, or it is an empty folder, or an mmval-marked folder that
/// holds only the files its marker lists.
void checkReplaceable(const std::filesystem::path& dir, const std::string& option = "--out");

/// Marks `dir` as an mmval output folder, listing every file now in it.
void writeOutputMarker(const std::filesystem::path& dir);

/// An exclusive, non-blocking lock on a folder (flock on the folder itself),
/// held while the object lives; a second mmval on the same folder gets an
/// InputError naming the folder instead of silently racing the first.
class FolderLock {
 public:
  FolderLock() = default;
  FolderLock(const std::filesystem::path& dir, const std::string& shown_as);
  FolderLock(FolderLock&& other) noexcept;
  FolderLock& operator=(FolderLock&& other) noexcept;
  FolderLock(const FolderLock&) = delete;
  FolderLock& operator=(const FolderLock&) = delete;
  ~FolderLock();

 private:
  int m_fd = -1;
};

/// A staging directory for a whole run: work happens in `<dir>.partial`, and
/// commit() swaps it into place. The constructor normalises `final_dir`,
/// refuses a target that is not mmval's (checkReplaceable) and locks the
/// staging folder, all before any work. If the object is destroyed without
/// commit(), the staging folder is removed unless it holds a checkpoint
/// (checkpoint.*) to resume from; either way a line on stderr says what
/// happened, and the old `dir` is untouched.
class StagedDirectory {
 public:
  /// With `resume`, an existing `<dir>.partial` from an interrupted run is kept
  /// so the runner can pick up its checkpoints; otherwise it is cleared.
  explicit StagedDirectory(const std::filesystem::path& final_dir, bool resume = false);
  StagedDirectory(const StagedDirectory&) = delete;
  StagedDirectory& operator=(const StagedDirectory&) = delete;
  ~StagedDirectory();
  const std::filesystem::path& path() const { return m_staging; }
  const std::filesystem::path& finalPath() const { return m_final; }
  void commit();

 private:
  std::filesystem::path m_final;
  std::filesystem::path m_staging;
  bool m_primary = true;  ///< false on MPI ranks other than 0: they only use the folder
  bool m_committed = false;
  FolderLock m_lock;
};

}  // namespace mmval
