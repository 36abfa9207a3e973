// The tracker's AVX2 kernels (tracking/src/SimdKernels.hpp) against independent
// references: the ring medians' quickselect against std::nth_element on random arrays
// (white noise, ties, mixed +0 / -0, ring-like runs with a bright outlier run, constants),
// and the AVX2 window moments and masked sums against the baseline build, bit for bit, on
// random windows (inside the image, at its edges, in a strided view), each also within
// round-off of a double-precision sum. Skipped where the AVX2 kernels are not compiled
// (not x86-64, or MMVAL_NO_AVX2) or the CPU lacks AVX2.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include <opencv2/core.hpp>

// Internal headers of the tracking library (no installed interface).
#include "SimdKernels.hpp"

namespace mmval::tracking::detail {
namespace {

#if MMVAL_HAVE_AVX2
#define MMVAL_SKIP_WITHOUT_AVX2() \
  if (!cpuHasAvx2Popcnt()) GTEST_SKIP() << "this CPU has no AVX2"
#else
#define MMVAL_SKIP_WITHOUT_AVX2() GTEST_SKIP() << "the AVX2 kernels are not compiled (not x86-64, or MMVAL_NO_AVX2)"
#endif

#if MMVAL_HAVE_AVX2

float nthElement(std::vector<float> v, std::size_t k) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// The selection must be exact: the same value as nth_element (compared with ==, which
// takes -0 and +0 as equal: either may be returned, SimdKernels.hpp), and `v` unchanged.
void expectSelectsAsNthElement(const std::vector<float>& v, std::size_t k, std::vector<float>& scratch) {
  const std::vector<float> before = v;
  const float got = kthSmallestAvx2(v.data(), v.size(), k, scratch);
  const float want = nthElement(v, k);
  ASSERT_TRUE(got == want) << "n " << v.size() << ", k " << k << ": got " << got << ", nth_element " << want;
  ASSERT_TRUE(v == before) << "the input was changed, n " << v.size();
}

// Every k of small arrays (the sizes around the 8-wide blocks and the final 16-value
// sort), and k = 0, n / 2 (the ring median), n - 1 and one random k of larger ones.
void checkKinds(std::mt19937& rng, const std::vector<float>& v, std::vector<float>& scratch) {
  const std::size_t n = v.size();
  if (n <= 40) {
    for (std::size_t k = 0; k < n && !::testing::Test::HasFatalFailure(); ++k) expectSelectsAsNthElement(v, k, scratch);
    return;
  }
  for (std::size_t k : {std::size_t{0}, n / 2, n - 1, static_cast<std::size_t>(rng() % n)})
    if (!::testing::Test::HasFatalFailure()) expectSelectsAsNthElement(v, k, scratch);
}

TEST(SimdKernels, QuickselectEqualsNthElement) {
  MMVAL_SKIP_WITHOUT_AVX2();
  std::mt19937 rng(46);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  std::vector<float> scratch;
  int arrays = 0;
  for (int rep = 0; rep < 3000; ++rep) {
    const std::size_t n = rep < 700 ? static_cast<std::size_t>(rep + 1) : 1 + rng() % 700;
    std::vector<float> v(n);
    // White noise.
    for (auto& x : v) x = noise(rng);
    checkKinds(rng, v, scratch);
    // Ties: 5 levels, the middle one a zero of random sign.
    for (auto& x : v) {
      const int level = static_cast<int>(rng() % 5) - 2;
      x = level == 0 ? ((rng() & 1) ? 0.0f : -0.0f) : 0.5f * static_cast<float>(level);
    }
    checkKinds(rng, v, scratch);
    // Only zeros, of either sign.
    for (auto& x : v) x = (rng() & 1) ? 0.0f : -0.0f;
    checkKinds(rng, v, scratch);
    // Ring-like: neighbours correlated (a random walk), one bright run of 10 % of the values.
    float walk = noise(rng);
    for (auto& x : v) x = walk += 0.1f * noise(rng);
    const std::size_t run = n / 10, at = rng() % (n - run + 1);
    for (std::size_t i = at; i < at + run; ++i) v[i] += 50.0f;
    checkKinds(rng, v, scratch);
    // Constant.
    std::fill(v.begin(), v.end(), 0.25f);
    checkKinds(rng, v, scratch);
    if (::testing::Test::HasFatalFailure()) return;  // one array's message is enough
    arrays += 5;
  }
  EXPECT_EQ(arrays, 15000);
}

// A random mask of 2r + 1 weights in (0, 1] (not a Gaussian: any weights must agree).
std::vector<float> randomMask(std::mt19937& rng, int r) {
  std::uniform_real_distribution<float> u(0.01f, 1.0f);
  std::vector<float> m(static_cast<std::size_t>(2 * r + 1));
  for (auto& x : m) x = u(rng);
  return m;
}

// Bit-identical doubles (a different order of the float sums changes the last bits).
bool sameBits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }

// Random signed pixels in a view whose rows are not `cols` floats apart (a region of a
// wider image), as the kernels must follow the row step.
cv::Mat randomImage(std::mt19937& rng, int rows, int cols) {
  cv::Mat wide(rows + 4, cols + 23, CV_32F);
  std::normal_distribution<float> noise(0.1f, 1.0f);
  for (int y = 0; y < wide.rows; ++y)
    for (int x = 0; x < wide.cols; ++x) wide.at<float>(y, x) = noise(rng);
  return wide(cv::Rect(7, 2, cols, rows));
}

TEST(SimdKernels, AvxWindowMomentsEqualBaselineBitForBit) {
  MMVAL_SKIP_WITHOUT_AVX2();
  std::mt19937 rng(4646);
  const cv::Mat img = randomImage(rng, 97, 131);
  ASSERT_NE(img.step[0], img.cols * sizeof(float));
  int checked = 0;
  for (int t = 0; t < 20000; ++t) {
    const int r = 1 + static_cast<int>(rng() % 37);  // measureSpot's windows: r <= 37
    const int cx = static_cast<int>(rng() % (img.cols + 10)) - 5, cy = static_cast<int>(rng() % (img.rows + 10)) - 5;
    const double mx = cx + static_cast<double>(rng() % 1000) / 1000 - 0.5, my = cy + static_cast<double>(rng() % 1000) / 1000 - 0.5;
    const double level = static_cast<double>(rng() % 100) / 300;
    const std::vector<float> ex = randomMask(rng, r), ey = randomMask(rng, r);
    const WindowMoments a = windowMomentsBaseline(img, cx, cy, r, mx, my, level, ex.data(), ey.data());
    const WindowMoments b = windowMomentsWide(img, cx, cy, r, mx, my, level, ex.data(), ey.data());
    ASSERT_TRUE(sameBits(a.s0, b.s0) && sameBits(a.sxx, b.sxx) && sameBits(a.syy, b.syy) && sameBits(a.sxy, b.sxy))
        << "r " << r << ", centre (" << cx << ", " << cy << "): baseline s0 " << a.s0 << " sxx " << a.sxx << " syy " << a.syy << " sxy " << a.sxy
        << "; AVX2 s0 " << b.s0 << " sxx " << b.sxx << " syy " << b.syy << " sxy " << b.sxy;
    // Both are the moments: a double-precision sum agrees within float round-off of the
    // terms (<= 75 float terms per row: 1e-5 of the sum of their magnitudes).
    if (t % 10 == 0) {
      double s0 = 0, sxx = 0, syy = 0, sxy = 0, mag0 = 0, magxx = 0, magyy = 0, magxy = 0;
      for (int y = std::max(0, cy - r); y <= std::min(img.rows - 1, cy + r); ++y)
        for (int x = std::max(0, cx - r); x <= std::min(img.cols - 1, cx + r); ++x) {
          const double w = (static_cast<double>(img.at<float>(y, x)) - static_cast<float>(level)) * ex[static_cast<std::size_t>(x - cx + r)] *
                           ey[static_cast<std::size_t>(y - cy + r)];
          const double dx = static_cast<float>(x - mx), dy = y - my;
          s0 += w, sxx += w * dx * dx, syy += w * dy * dy, sxy += w * dx * dy;
          mag0 += std::abs(w), magxx += std::abs(w) * dx * dx, magyy += std::abs(w) * dy * dy, magxy += std::abs(w * dx * dy);
        }
      EXPECT_NEAR(b.s0, s0, 1e-5 * mag0 + 1e-12);
      EXPECT_NEAR(b.sxx, sxx, 1e-5 * magxx + 1e-12);
      EXPECT_NEAR(b.syy, syy, 1e-5 * magyy + 1e-12);
      EXPECT_NEAR(b.sxy, sxy, 1e-5 * magxy + 1e-12);
    }
    ++checked;
  }
  EXPECT_EQ(checked, 20000);
}

TEST(SimdKernels, AvxMaskedSumsEqualBaselineBitForBit) {
  MMVAL_SKIP_WITHOUT_AVX2();
  std::mt19937 rng(464646);
  const cv::Mat img = randomImage(rng, 61, 83);
  int wide = 0;
  for (int t = 0; t < 100000; ++t) {
    // The joint fit's windows are at most 16 columns (r <= 7: the AVX2 path); wider
    // ones take the scalar path in both builds.
    const int r = t % 10 == 0 ? 8 + static_cast<int>(rng() % 5) : static_cast<int>(rng() % 8);
    const int cx = static_cast<int>(rng() % (img.cols + 6)) - 3, cy = static_cast<int>(rng() % (img.rows + 6)) - 3;
    const std::vector<float> ex = randomMask(rng, r), ey = randomMask(rng, r);
    double aw = 0, ax = 0, ay = 0, bw = 0, bx = 0, by = 0;
    maskedSumsBaseline(img, cx, cy, r, ex.data(), ey.data(), aw, ax, ay);
    maskedSumsWide(img, cx, cy, r, ex.data(), ey.data(), bw, bx, by);
    ASSERT_TRUE(sameBits(aw, bw) && sameBits(ax, bx) && sameBits(ay, by))
        << "r " << r << ", centre (" << cx << ", " << cy << "): baseline " << aw << " " << ax << " " << ay << "; AVX2 " << bw << " " << bx << " " << by;
    if (cx - r >= 0 && 2 * r + 1 <= 16 && cx - r + 16 <= img.cols) ++wide;  // maskedSumsWide's AVX2 path
    if (t % 10 == 0) {
      double sw = 0, sx = 0, sy = 0, magw = 0, magx = 0, magy = 0;
      for (int y = std::max(0, cy - r); y <= std::min(img.rows - 1, cy + r); ++y)
        for (int x = std::max(0, cx - r); x <= std::min(img.cols - 1, cx + r); ++x) {
          const double w = static_cast<double>(img.at<float>(y, x)) * ex[static_cast<std::size_t>(x - cx + r)] * ey[static_cast<std::size_t>(y - cy + r)];
          sw += w, sx += w * (x - cx), sy += w * (y - cy);
          magw += std::abs(w), magx += std::abs(w * (x - cx)), magy += std::abs(w * (y - cy));
        }
      EXPECT_NEAR(bw, sw, 1e-5 * magw + 1e-12);
      EXPECT_NEAR(bx, sx, 1e-5 * magx + 1e-12);
      EXPECT_NEAR(by, sy, 1e-5 * magy + 1e-12);
    }
  }
  EXPECT_GT(wide, 50000) << "too few windows took the AVX2 path";
}

#else

TEST(SimdKernels, NotCompiledHere) { MMVAL_SKIP_WITHOUT_AVX2(); }

#endif  // MMVAL_HAVE_AVX2

}  // namespace
}  // namespace mmval::tracking::detail
