// Internal to mmval::tracking: the kernels that have an AVX2 build beside the baseline
// one (Simd.hpp), each reachable by itself so that a test can hold the two builds to the
// same bits (tests/tracking/SimdKernelsTest.cpp). The tracker itself calls the
// dispatching functions (maskedSums in SpotFit.hpp, measureSpot's moments and ring
// medians), never these entry points.
#pragma once
#include <cstddef>
#include <vector>

#include <opencv2/core.hpp>

#include "Simd.hpp"

namespace mmval::tracking::detail {

/// Gaussian-weighted moments of (img - level) over a window (SpotQuality.cpp).
struct WindowMoments {
  double s0 = 0, sxx = 0, syy = 0, sxy = 0;
};

/// The moments of (img - level) under the separable mask ex(x - cx + r) ey(y - cy + r)
/// over the window of half-width r <= 37 around (cx, cy) (clipped to the image), about
/// (mx, my): the baseline build (4-lane vectors, one row at a time).
WindowMoments windowMomentsBaseline(const cv::Mat& img, int cx, int cy, int r, double mx, double my, double level, const float* ex, const float* ey);

/// maskedSums' baseline build (SpotFit.hpp: the same contract).
void maskedSumsBaseline(const cv::Mat& img, int cx, int cy, int r, const float* ex, const float* ey, double& sw, double& sx, double& sy);

#if MMVAL_HAVE_AVX2
/// windowMomentsBaseline's AVX2 build (two rows per register): the same bits. Only on
/// a CPU where cpuHasAvx2().
WindowMoments windowMomentsWide(const cv::Mat& img, int cx, int cy, int r, double mx, double my, double level, const float* ex, const float* ey);

/// maskedSums' AVX2 build (16-column rows in 2 registers): the same bits. Only on a CPU
/// where cpuHasAvx2().
void maskedSumsWide(const cv::Mat& img, int cx, int cy, int r, const float* ex, const float* ey, double& sw, double& sx, double& sy);

/// The ring medians' AVX2 selection: the value std::nth_element would put at position k
/// of v[0, n) (finite values, k < n; of -0 and +0 either may be returned), `v` unchanged,
/// `scratch` reused storage. Only on a CPU where cpuHasAvx2Popcnt().
float kthSmallestAvx2(const float* v, std::size_t n, std::size_t k, std::vector<float>& scratch);
#endif

}  // namespace mmval::tracking::detail
