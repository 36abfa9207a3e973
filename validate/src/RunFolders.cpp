#include "mmval/validate/RunFolders.hpp"

#include <fstream>

#include "mmval/core/AtomicFile.hpp"

namespace fs = std::filesystem;

namespace mmval::validate {

std::optional<nlohmann::json> earlierRun(const Case& c, const fs::path& dir) {
  std::ifstream in(dir / "result.json");
  if (!in) return std::nullopt;
  try {
    nlohmann::json r = nlohmann::json::parse(in);
    if (r.at("case").at("hash") == c.hash()) return r;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

void requireOwnedFolder(const fs::path& out) {
  std::error_code ec;
  const auto st = fs::symlink_status(out, ec);
  if (ec || !fs::exists(st)) return;
  if (fs::is_directory(st) && (fs::is_empty(out, ec) || fs::exists(out / kOutputMarker))) return;
  checkReplaceable(out);  // throws the message that says what is in the way
}

}  // namespace mmval::validate
