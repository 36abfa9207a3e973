// Internal to mmval::tracking: whether the tracker's AVX2 kernels (SpotFit.cpp,
// SpotQuality.cpp) are compiled, and whether the CPU running them has AVX2.
//
// The build targets the baseline of its architecture; on x86-64 the hot loops also have
// AVX2 builds (`__attribute__((target("avx2")))`), chosen at run time, that give the
// baseline's results bit for bit. Elsewhere (aarch64, ...), or with -DMMVAL_NO_AVX2, only
// the baseline path is compiled: MMVAL_HAVE_AVX2 is 0 and the AVX2 code is left out by
// `#if MMVAL_HAVE_AVX2` (not merely skipped at run time).
#pragma once

#if defined(__x86_64__) && !defined(MMVAL_NO_AVX2)
#define MMVAL_HAVE_AVX2 1
#include <immintrin.h>
/// A function compiled for AVX2 (no FMA: the AVX2 kernels keep the baseline's separate
/// products and sums).
#define MMVAL_TARGET_AVX2 __attribute__((target("avx2")))
/// The same with POPCNT (the quickselect's counts).
#define MMVAL_TARGET_AVX2_POPCNT __attribute__((target("avx2,popcnt")))
#else
#define MMVAL_HAVE_AVX2 0
#define MMVAL_TARGET_AVX2
#define MMVAL_TARGET_AVX2_POPCNT
#endif

namespace mmval::tracking::detail {

/// Whether the AVX2 kernels are compiled and this CPU runs them (asked once).
inline bool cpuHasAvx2() {
#if MMVAL_HAVE_AVX2
  static const bool yes = __builtin_cpu_supports("avx2");
  return yes;
#else
  return false;
#endif
}

/// cpuHasAvx2() and POPCNT (every AVX2 CPU has it; asked separately all the same).
inline bool cpuHasAvx2Popcnt() {
#if MMVAL_HAVE_AVX2
  static const bool yes = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("popcnt");
  return yes;
#else
  return false;
#endif
}

}  // namespace mmval::tracking::detail
