// The exact order statistic behind the ring medians, the temporal median background and
// the noise estimates (tracking/src/Selection.hpp) against std::nth_element: the same
// value, bit for bit, for sizes across its vector blocks and its bin counts, for white
// noise, for neighbour-correlated ring-like samples with a bright outlier run, for ties
// and for constant input.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

// An internal header of the tracking library (no installed interface).
#include "Selection.hpp"

namespace mmval::tracking::detail {
namespace {

float reference(std::vector<float> v, std::size_t k) {
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

// Every k of every sample: the selection must be exact, so equality is the tolerance.
void expectSameAsNthElement(const std::vector<float>& v) {
  std::vector<float> scratch;
  for (std::size_t k = 0; k < v.size(); ++k) {
    const float got = kthSmallest(v.data(), v.size(), k, scratch);
    ASSERT_EQ(got, reference(v, k)) << "n " << v.size() << ", k " << k;
  }
}

TEST(Selection, KthSmallestEqualsNthElementOnWhiteNoise) {
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  for (std::size_t n : {1u, 2u, 3u, 4u, 5u, 7u, 8u, 9u, 15u, 16u, 17u, 31u, 64u, 127u, 128u, 129u, 300u, 601u}) {
    std::vector<float> v(n);
    for (auto& x : v) x = noise(rng);
    expectSameAsNthElement(v);
  }
}

TEST(Selection, KthSmallestEqualsNthElementOnRingLikeSamples) {
  // Neighbouring pixels of a ring are correlated (the signal is smoothed) and a neighbour
  // spot adds a run of high values: many values share a bin, the range is stretched.
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  for (std::size_t n : {60u, 100u, 176u, 477u}) {
    std::vector<float> v(n);
    float a = 0;
    for (std::size_t i = 0; i < n; ++i) {
      a = 0.8f * a + 0.2f * noise(rng);
      v[i] = 0.05f * a + (i % 50 < 6 ? 0.5f : 0.0f);
    }
    expectSameAsNthElement(v);
  }
}

TEST(Selection, KthSmallestHandlesTiesAndConstantInput) {
  std::mt19937 rng(3);
  std::uniform_int_distribution<int> level(0, 4);
  for (std::size_t n : {5u, 33u, 250u}) {
    std::vector<float> ties(n);
    for (auto& x : ties) x = 0.25f * static_cast<float>(level(rng));  // 8-bit-like levels
    expectSameAsNthElement(ties);
    expectSameAsNthElement(std::vector<float>(n, 1.5f));
  }
}

}  // namespace
}  // namespace mmval::tracking::detail
