#include "mmval/core/AtomicFile.hpp"

#include <fstream>
#include <random>
#include <stdexcept>
#include <unistd.h>

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

void writeFileAtomic(const fs::path& path, std::string_view content) {
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

StagedDirectory::StagedDirectory(fs::path final_dir, bool resume)
    : m_final(std::move(final_dir)), m_staging(m_final.string() + ".partial") {
  std::error_code ec;
  if (!resume) fs::remove_all(m_staging, ec);
  fs::create_directories(m_staging);
}

void StagedDirectory::commit() {
  if (m_committed) return;
  fs::path old = m_final.string() + ".old";
  std::error_code ec;
  fs::remove_all(old, ec);
  if (fs::exists(m_final)) fs::rename(m_final, old);
  fs::rename(m_staging, m_final);
  fs::remove_all(old, ec);
  m_committed = true;
}

}  // namespace mmval
