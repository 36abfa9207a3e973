// mmval's mask rule (core/MaskRule.hpp): one split for every mask reader. References
// worked by hand from the rule's statement (halfway between the darkest and brightest
// grey; at or below is dark).
#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "mmval/core/MaskRule.hpp"

using namespace mmval;

TEST(MaskRule, SplitsHalfwayBetweenTheImagesOwnGreyLevels) {
  const std::vector<std::uint8_t> binary{0, 255, 255, 0}, zero_one{0, 1, 1, 0}, soft{40, 200, 90, 41};
  EXPECT_EQ(maskSplit(binary.data(), binary.size()), 127.5);  // a 0/255 mask: the 128 threshold it always had
  EXPECT_EQ(maskSplit(zero_one.data(), zero_one.size()), 0.5);  // a 0/1 mask is two levels, not all dark
  EXPECT_EQ(maskSplit(soft.data(), soft.size()), 120.0);        // (40 + 200) / 2
  EXPECT_EQ(maskSplit(0.0, 0.25, 1.0), 0.125);                  // normalised 16-bit grey
}

TEST(MaskRule, OneGreyLevelSplitsAtMidScale) {
  const std::vector<std::uint8_t> white(9, 255), black(9, 0);
  EXPECT_EQ(maskSplit(white.data(), white.size()), 127.5);
  EXPECT_FALSE(isGrain(255, 127.5, true));  // an all-white mask with dark grains: all pore
  EXPECT_TRUE(isGrain(0, maskSplit(black.data(), black.size()), true));
}

TEST(MaskRule, AtOrBelowTheSplitIsDark) {
  EXPECT_TRUE(isGrain(120.0, 120.0, true));
  EXPECT_FALSE(isGrain(120.0, 120.0, false));
  EXPECT_TRUE(isGrain(121.0, 120.0, false));
  EXPECT_FALSE(isGrain(121.0, 120.0, true));
}
