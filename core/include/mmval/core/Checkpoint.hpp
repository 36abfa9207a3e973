// Checkpoints of long runs (particle runs, unsteady flow): kill and resume
// gives the same result as an uninterrupted run. A checkpoint is one file written under
// a temporary name and renamed into place (writeFileAtomic), so a run killed
// while writing leaves the previous checkpoint intact. The format is private to
// one build: raw little-endian values with a magic, a version and a
// fingerprint of the scene, so a checkpoint of another scene is refused.
#pragma once
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "mmval/core/Case.hpp"

namespace mmval {

class CheckpointWriter {
 public:
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    const auto* p = reinterpret_cast<const char*>(&v);
    m_buf.append(p, sizeof(T));
  }
  template <class T>
  void putVector(const std::vector<T>& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    put<std::uint64_t>(v.size());
    if (!v.empty()) m_buf.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void putString(const std::string& s) {
    put<std::uint64_t>(s.size());
    m_buf.append(s);
  }
  void putBytes(const void* data, std::size_t n) {
    put<std::uint64_t>(n);
    m_buf.append(static_cast<const char*>(data), n);
  }
  const std::string& bytes() const { return m_buf; }

 private:
  std::string m_buf;
};

/// Reads what CheckpointWriter wrote; throws std::runtime_error (naming the
/// file) when the data end early.
class CheckpointReader {
 public:
  CheckpointReader(std::string bytes, std::string name) : m_buf(std::move(bytes)), m_name(std::move(name)) {}
  template <class T>
  T get() {
    static_assert(std::is_trivially_copyable_v<T>);
    need(sizeof(T));
    T v;
    std::memcpy(&v, m_buf.data() + m_pos, sizeof(T));
    m_pos += sizeof(T);
    return v;
  }
  template <class T>
  std::vector<T> getVector() {
    const auto n = get<std::uint64_t>();
    need(n * sizeof(T));
    std::vector<T> v(n);
    if (n) std::memcpy(v.data(), m_buf.data() + m_pos, n * sizeof(T));
    m_pos += n * sizeof(T);
    return v;
  }
  std::string getString() {
    const auto n = get<std::uint64_t>();
    need(n);
    std::string s = m_buf.substr(m_pos, n);
    m_pos += n;
    return s;
  }
  const std::string& name() const { return m_name; }

 private:
  void need(std::size_t n) const {
    if (m_pos + n > m_buf.size()) throw std::runtime_error("checkpoint " + m_name + " is truncated (needs " + std::to_string(m_pos + n) + " bytes, has " + std::to_string(m_buf.size()) + ")");
  }
  std::string m_buf;
  std::string m_name;
  std::size_t m_pos = 0;
};

/// Whole file as bytes; throws std::runtime_error naming the file.
std::string readBinaryFile(const std::filesystem::path& file);

/// What a checkpoint must match to be resumed: the resolved case without its
/// [case] table, its acceptance entries and the run-control keys (run.checkpoint_every,
/// run.checkpoint_minutes, run.stop_after_frames, run.stop_after_steps, run.stop_after_levels),
/// which change neither the physics nor the numerics.
std::string checkpointFingerprint(const Case& c);
/// The same as JSON, for a runner that leaves out keys of its own (e.g. a ladder's level list).
nlohmann::json checkpointFingerprintJson(const Case& c);

/// Thrown when a run stops on purpose (run.stop_after_frames, run.stop_after_steps:
/// tests of checkpoint and restart); the checkpoint is on disk.
class RunStopped : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace mmval
