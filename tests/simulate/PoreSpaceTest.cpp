#include <cstring>

#include <gtest/gtest.h>

#include "mmval/simulate/PoreSpace.hpp"

using namespace mmval::simulate;

namespace {
BoolArray grid(std::initializer_list<const char*> rows) {
  BoolArray m(static_cast<Eigen::Index>(rows.size()), static_cast<Eigen::Index>(std::strlen(*rows.begin())));
  int r = 0;
  for (const char* row : rows) {
    for (int c = 0; row[c] != 0; ++c) m(r, c) = row[c] == '#';
    ++r;
  }
  return m;
}
}  // namespace

TEST(PoreSpace, IsolatedPoreExcluded) {
  const auto m = grid({"######",
                       "......",
                       "######",
                       "#..###",
                       "######"});
  const auto rep = analysePoreSpace(m);
  EXPECT_EQ(rep.components, 2);
  EXPECT_EQ(rep.spanning_components, 1);
  EXPECT_NEAR(rep.porosity_total, 8.0 / 30, 1e-15);
  EXPECT_NEAR(rep.porosity_connected, 6.0 / 30, 1e-15);
  EXPECT_TRUE(rep.solid_connected(3, 1));
  EXPECT_FALSE(rep.solid_connected(1, 1));
}

TEST(PoreSpace, DiagonalContactIsNoPath) {
  const auto m = grid({"..##",
                       "##..",});
  EXPECT_THROW(analysePoreSpace(m), NoFlowPath);
}

TEST(PoreSpace, AllSolidAndAllFluid) {
  EXPECT_THROW(analysePoreSpace(BoolArray::Constant(5, 5, true)), NoFlowPath);
  const auto rep = analysePoreSpace(BoolArray::Constant(5, 5, false));
  EXPECT_DOUBLE_EQ(rep.porosity_total, 1.0);
  EXPECT_DOUBLE_EQ(rep.porosity_connected, 1.0);
}

TEST(PoreSpace, OnePixelThroatConnects) {
  const auto m = grid({"##.##",
                       "..#..",
                       "..#..",});
  EXPECT_THROW(analysePoreSpace(m), NoFlowPath);  // the gap at the top touches no side pore
  const auto m2 = grid({"..#..",
                        ".....",
                        "..#..",});
  EXPECT_EQ(analysePoreSpace(m2).spanning_components, 1);
}
