#include "mmval/core/Resources.hpp"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <thread>

#include <fmt/format.h>

#include "mmval/core/Case.hpp"

namespace mmval {

double physicalMemoryBytes() {
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page <= 0) return 0.0;
  return static_cast<double>(pages) * static_cast<double>(page);
}

double defaultMaxMemoryBytes() {
  const double ram = physicalMemoryBytes();
  return ram > 0 ? 0.5 * ram : 8.0 * 1024 * 1024 * 1024;
}

double maxMemoryBytes(const Case& c) { return c.has("run.max_memory") ? c.quantity("run.max_memory") : defaultMaxMemoryBytes(); }

std::string formatBytes(double bytes) {
  if (!std::isfinite(bytes)) return "an unbounded amount of memory";
  if (bytes >= 1e12) return fmt::format("{:.3g} TB", bytes / 1e12);
  if (bytes >= 1e9) return fmt::format("{:.3g} GB", bytes / 1e9);
  if (bytes >= 1e6) return fmt::format("{:.3g} MB", bytes / 1e6);
  if (bytes >= 1e3) return fmt::format("{:.3g} kB", bytes / 1e3);
  return fmt::format("{:.0f} B", bytes);
}

void requireMemory(double estimate_bytes, double limit_bytes, const std::string& what, const InputLocation& where,
                   const std::string& advice) {
  if (std::isfinite(estimate_bytes) && estimate_bytes <= limit_bytes) return;
  throw InputError(where,
                   fmt::format("{} needs about {}, more than run.max_memory ({}){}", what, formatBytes(estimate_bytes),
                               formatBytes(limit_bytes), advice.empty() ? "" : "; " + advice),
                   {}, fmt::format("a run that fits in run.max_memory (default: half of this machine's {} of memory)",
                                   formatBytes(physicalMemoryBytes())));
}

void requireMemory(const Case& c, double estimate_bytes, const std::string& what, const std::string& key, const std::string& advice) {
  requireMemory(estimate_bytes, maxMemoryBytes(c), what, c.where(key), advice);
}

void requireCount(double count, double limit, const std::string& what, const InputLocation& where, const std::string& advice) {
  if (std::isfinite(count) && count <= limit) return;
  throw InputError(where, fmt::format("{} would be {:.3g}, more than the limit of {:.3g}", what, count, limit),
                   {}, advice);
}

int autoThreads(int max_threads) {
  if (const char* share = std::getenv(kAutoThreadsVariable)) {
    char* end = nullptr;
    const long n = std::strtol(share, &end, 10);
    if (end != share && *end == '\0' && n >= 1 && n <= max_threads) return static_cast<int>(n);
  }
  return static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 2u, 8u));
}

}  // namespace mmval
