#include "mmval/core/Checkpoint.hpp"

#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

namespace mmval {

std::string readBinaryFile(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

nlohmann::json checkpointFingerprintJson(const Case& c) {
  nlohmann::json j = c.resolvedJson();
  if (j.contains("run"))
    for (const char* key : {"checkpoint_every", "checkpoint_minutes", "stop_after_frames", "stop_after_steps", "stop_after_levels"}) j["run"].erase(key);
  j.erase("case");
  j.erase("acceptance");
  return j;
}

std::string checkpointFingerprint(const Case& c) { return checkpointFingerprintJson(c).dump(); }

}  // namespace mmval
