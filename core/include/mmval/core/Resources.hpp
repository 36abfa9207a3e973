// Resource limits checked before any big allocation, so that a small input
// that asks for a huge run (a 30000 x 30000 mask, a 4096^2 grid, an output
// every picosecond) fails in seconds with a message naming the key, instead of
// growing until the machine runs out of memory.
//
// The limit is the case key `run.max_memory` (every kind has it; default: half
// of this machine's physical memory). Estimates are made by the code that is
// about to allocate, from sizes it already knows (cells x bytes per cell,
// frames x particles x bytes per record, pixels of an image header).
#pragma once

#include <cstdint>
#include <string>

#include "mmval/core/Error.hpp"

namespace mmval {

class Case;

/// Physical memory of this machine in bytes (sysconf), 0 when unknown.
double physicalMemoryBytes();

/// The default `run.max_memory`: half of the physical memory (8 GiB when unknown).
double defaultMaxMemoryBytes();

/// `run.max_memory` of `c` in bytes (its default when the case does not set it).
double maxMemoryBytes(const Case& c);

/// Human form of a byte count: "7.5 GB".
std::string formatBytes(double bytes);

/// Throws InputError at `where` when `estimate_bytes` exceeds `limit_bytes`:
///   "<what> needs about 7.5 GB, more than run.max_memory (12 GB); <advice>"
void requireMemory(double estimate_bytes, double limit_bytes, const std::string& what, const InputLocation& where,
                   const std::string& advice);

/// The same with the limit from `c` and the location of `key` in `c`.
void requireMemory(const Case& c, double estimate_bytes, const std::string& what, const std::string& key, const std::string& advice);

/// The environment variable through which `mmval sweep --jobs N` gives each of its runs its share
/// of the cores (the hardware's cores / N, at least 1), read by autoThreads.
inline constexpr const char* kAutoThreadsVariable = "MMVAL_AUTO_THREADS";

/// A thread count of "auto" (numerics.threads = 0): the share kAutoThreadsVariable names when it is
/// a whole number from 1 to max_threads, else the hardware's cores, 2 to 8.
int autoThreads(int max_threads);

/// Throws InputError at `where` when a count (frames, particles, output
/// records, mesh levels) exceeds `limit`: guards loops whose length comes
/// from user input (run.duration / run.output_interval, --levels).
void requireCount(double count, double limit, const std::string& what, const InputLocation& where, const std::string& advice);

}  // namespace mmval
