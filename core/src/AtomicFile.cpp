#include "mmval/core/AtomicFile.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <vector>

#include "mmval/core/Error.hpp"

namespace mmval {
namespace fs = std::filesystem;

fs::path temporaryPathFor(const fs::path& final_path) {
  // Keep the extension last so that writers choosing a format by extension
  // (cv::imwrite) still work.
  static thread_local std::mt19937_64 rng{std::random_device{}() ^ static_cast<unsigned>(::getpid())};
  fs::path dir = final_path.parent_path();
  std::string stem = final_path.stem().string();
  std::string tag = std::to_string(rng() % 1000000000ULL);
  return dir / ("." + stem + ".tmp" + tag + final_path.extension().string());
}

void commitTemporary(const fs::path& temporary, const fs::path& final_path) {
  std::error_code ec;
  fs::rename(temporary, final_path, ec);
  if (ec) throw std::runtime_error("cannot rename " + temporary.string() + " to " + final_path.string() + ": " + ec.message());
}

bool primaryRank() {
  const char* rank = std::getenv("OMPI_COMM_WORLD_RANK");
  if (rank == nullptr) rank = std::getenv("PMI_RANK");
  return rank == nullptr || std::string(rank) == "0";
}

void writeFileAtomic(const fs::path& path, std::string_view content) {
  // Under mpirun every rank computes the same outputs and only rank 0 writes them: a
  // second writer would race rank 0's rename of the finished staging folder.
  if (!primaryRank()) return;
  if (path.has_parent_path()) fs::create_directories(path.parent_path());
  fs::path tmp = temporaryPathFor(path);
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot open " + tmp.string() + " for writing");
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.flush();
    if (!out) throw std::runtime_error("write failed for " + tmp.string() + " (disk full?)");
  }
  commitTemporary(tmp, path);
}

namespace {

constexpr const char* kMarkerHeader = "mmval output folder: mmval wrote the files listed below and may replace this folder";

InputLocation commandLine(const std::string& option) { return {"(command line)", 0, 0, option}; }

/// Files (not folders) under `dir`, relative, sorted; the marker itself left out.
std::vector<std::string> filesUnder(const fs::path& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, fs::directory_options::none, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec)) {
    if (it->is_directory() && !it->is_symlink()) continue;
    const std::string rel = fs::relative(it->path(), dir).generic_string();
    if (rel != kOutputMarker) out.push_back(rel);
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// The files a marker lists, or nullopt when `dir` has no marker.
std::optional<std::set<std::string>> markerManifest(const fs::path& dir) {
  std::ifstream in(dir / kOutputMarker);
  if (!in) return std::nullopt;
  std::string line;
  std::getline(in, line);
  if (line != kMarkerHeader) return std::nullopt;
  std::set<std::string> files;
  while (std::getline(in, line))
    if (!line.empty()) files.insert(line);
  return files;
}

bool holdsCheckpoint(const fs::path& dir) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.path().filename().string().rfind("checkpoint", 0) == 0) return true;
  return false;
}

/// Empties a staging folder of ours (its contents only, so a lock on it holds).
void clearContents(const fs::path& dir) {
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(dir, ec)) fs::remove_all(e.path(), ec);
}

}  // namespace

fs::path normaliseOutputPath(const std::string& given, const std::string& option) {
  const std::string expected = "a folder name such as out/run1 (created if missing)";
  if (given.empty()) throw InputError(commandLine(option), "empty output folder", "\"\"", expected);
  fs::path p = fs::path(given).lexically_normal();
  if (!p.empty() && p.filename().empty()) p = p.parent_path();  // "out/x/" -> "out/x"
  if (p.empty() || p == "." || p == ".." || p.filename() == "..") {
    p = fs::absolute(p.empty() ? fs::path(".") : p).lexically_normal();
    if (!p.empty() && p.filename().empty()) p = p.parent_path();
  }
  if (p.empty() || p == p.root_path())
    throw InputError(commandLine(option), "the root folder cannot be an output folder", "\"" + given + "\"", expected);
  return p;
}

void checkReplaceable(const fs::path& dir, const std::string& option) {
  std::error_code ec;
  const auto st = fs::symlink_status(dir, ec);
  if (ec || !fs::exists(st)) return;
  const std::string shown = "'" + dir.string() + "'";
  const std::string advice = "a new folder name, or a folder mmval wrote earlier (mmval replaces only folders it wrote)";
  if (fs::is_symlink(st))
    throw InputError(commandLine(option), "the output folder " + shown + " is a symbolic link; mmval does not replace it", {}, advice);
  if (!fs::is_directory(st))
    throw InputError(commandLine(option), "the output folder " + shown + " exists and is not a folder (a file of yours?); mmval does not replace it",
                     {}, advice);
  const std::vector<std::string> files = filesUnder(dir);
  const auto manifest = markerManifest(dir);
  if (!manifest) {
    if (files.empty() && fs::is_empty(dir, ec)) return;
    const std::string example = files.empty() ? std::string("(folders only)") : "'" + files.front() + "'";
    throw InputError(commandLine(option),
                     "the output folder " + shown + " already holds files mmval did not write (" + std::to_string(files.size()) +
                         " file(s), e.g. " + example + ") and no " + kOutputMarker + " marker; nothing was changed",
                     {}, advice);
  }
  for (const auto& f : files)
    if (manifest->count(f) == 0)
      throw InputError(commandLine(option),
                       "the output folder " + shown + " is an earlier mmval output but also holds '" + f +
                           "', which mmval did not write; nothing was changed",
                       {}, "move that file out, or choose another output folder");
}

void writeOutputMarker(const fs::path& dir) {
  std::string text = std::string(kMarkerHeader) + "\n";
  for (const auto& f : filesUnder(dir)) text += f + "\n";
  writeFileAtomic(dir / kOutputMarker, text);
}

FolderLock::FolderLock(const fs::path& dir, const std::string& shown_as) {
  m_fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (m_fd < 0) throw std::runtime_error("cannot open folder " + dir.string() + " to lock it: " + std::strerror(errno));
  if (::flock(m_fd, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    ::close(m_fd);
    m_fd = -1;
    if (err == EWOULDBLOCK)
      throw InputError(commandLine("--out"), "another mmval is writing to '" + shown_as + "' right now (" + dir.string() + " is locked)",
                       {}, "wait for it to finish, or choose another output folder");
    throw std::runtime_error("cannot lock folder " + dir.string() + ": " + std::strerror(err));
  }
}

FolderLock::FolderLock(FolderLock&& other) noexcept : m_fd(other.m_fd) { other.m_fd = -1; }

FolderLock& FolderLock::operator=(FolderLock&& other) noexcept {
  if (this != &other) {
    if (m_fd >= 0) ::close(m_fd);
    m_fd = other.m_fd;
    other.m_fd = -1;
  }
  return *this;
}

FolderLock::~FolderLock() {
  if (m_fd >= 0) ::close(m_fd);  // closing releases the flock
}

StagedDirectory::StagedDirectory(const fs::path& final_dir, bool resume)
    : m_final(normaliseOutputPath(final_dir.string())), m_staging(m_final.string() + ".partial"), m_primary(primaryRank()) {
  if (!m_primary) {
    std::error_code ec;
    fs::create_directories(m_staging, ec);
    return;
  }
  checkReplaceable(m_final);
  const bool existed = fs::exists(fs::symlink_status(m_staging));
  if (existed && !fs::is_directory(fs::symlink_status(m_staging)))
    throw InputError(commandLine("--out"), "'" + m_staging.string() + "' exists and is not a folder; mmval does not replace it", {},
                     "move it away, or choose another output folder");
  fs::create_directories(m_staging);
  m_lock = FolderLock(m_staging, m_final.string());
  if (existed && !resume) {
    // Clear a staging folder left by an earlier run, if it is ours.
    if (!markerManifest(m_staging) && !fs::is_empty(m_staging))
      throw InputError(commandLine("--out"), "'" + m_staging.string() + "' exists and was not written by mmval; nothing was changed", {},
                       "move it away, or choose another output folder");
    clearContents(m_staging);
  }
  writeOutputMarker(m_staging);
}

StagedDirectory::~StagedDirectory() {
  if (m_committed || !m_primary) return;
  std::error_code ec;
  if (!fs::exists(m_staging, ec)) return;
  if (holdsCheckpoint(m_staging)) {
    std::fprintf(stderr, "mmval: kept %s: it holds a checkpoint; run the same command with --resume to continue from it\n",
                 m_staging.string().c_str());
    return;
  }
  fs::remove_all(m_staging, ec);
  if (!ec) std::fprintf(stderr, "mmval: removed the incomplete %s (no checkpoint in it)\n", m_staging.string().c_str());
}

void StagedDirectory::commit() {
  if (m_committed) return;
  m_committed = true;
  if (!m_primary) return;
  // The target may have changed while the run worked: check it again.
  try {
    checkReplaceable(m_final);
  } catch (const InputError&) {
    m_committed = false;
    throw;
  }
  writeOutputMarker(m_staging);
  std::error_code ec;
  const bool replace = fs::exists(fs::symlink_status(m_final, ec));
  fs::path old;
  if (replace) {
    old = m_final.string() + ".old-" + std::to_string(::getpid());
    fs::remove_all(old, ec);
    fs::rename(m_final, old);
  }
  fs::rename(m_staging, m_final);
  if (replace) fs::remove_all(old, ec);  // checked above: empty, or only files mmval wrote
}

}  // namespace mmval
