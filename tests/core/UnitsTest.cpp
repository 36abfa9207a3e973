// Unit conversions against hand-computed values.
#include <gtest/gtest.h>

#include "mmval/core/Units.hpp"

namespace mmval {
namespace {

TEST(Units, DarcyToSquareMetres) {
  // 1 D = 9.869233e-13 m^2 (API definition); 2.5 D -> 2.4673e-12 m^2.
  EXPECT_NEAR(parseQuantity("2.5 D").si, 2.46730825e-12, 1e-20);
  EXPECT_EQ(parseQuantity("2.5 D").dim, (Dimension{{2, 0, 0, 0, 0}}));
  EXPECT_NEAR(parseQuantity("4.17 D").si, 4.17 * 9.869233e-13, 1e-22);
  EXPECT_NEAR(parseQuantity("250 mD").si, 2.46730825e-13, 1e-21);
}

TEST(Units, CentimetresPerMinuteToMetresPerSecond) {
  // 0.024 cm/min = 0.024e-2 m / 60 s = 4.0e-6 m/s.
  const Quantity q = parseQuantity("0.024 cm/min");
  EXPECT_NEAR(q.si, 4.0e-6, 1e-18);
  EXPECT_EQ(q.dim, (Dimension{{1, 0, -1, 0, 0}}));
  EXPECT_NEAR(parseQuantity("0.24 cm/min").si, 4.0e-5, 1e-17);
}

TEST(Units, MicrolitresPerMinuteToCubicMetresPerSecond) {
  // 5 uL/min = 5e-9 m^3 / 60 s = 8.3333e-11 m^3/s.
  const Quantity q = parseQuantity("5 uL/min");
  EXPECT_NEAR(q.si, 5e-9 / 60.0, 1e-22);
  EXPECT_EQ(q.dim, (Dimension{{3, 0, -1, 0, 0}}));
}

TEST(Units, DensityViscosityAndTime) {
  EXPECT_NEAR(parseQuantity("1.05 g/cm3").si, 1050.0, 1e-9);   // 1.05e-3 kg / 1e-6 m^3
  EXPECT_NEAR(parseQuantity("1e-3 Pa s").si, 1e-3, 1e-18);
  EXPECT_NEAR(parseQuantity("1 cP").si, 1e-3, 1e-18);
  EXPECT_NEAR(parseQuantity("20 min").si, 1200.0, 1e-9);
  EXPECT_NEAR(parseQuantity("5 um").si, 5e-6, 1e-18);
  EXPECT_NEAR(parseQuantity("42.3 %").si, 0.423, 1e-15);
  EXPECT_NEAR(parseQuantity("2.9e7 1/mL").si, 2.9e13, 1e3);     // per 1e-6 m^3
  EXPECT_EQ(parseQuantity("1e-3 Pa s").dim, (Dimension{{-1, 1, -1, 0, 0}}));
}

TEST(Units, ExponentSpellingsAgree) {
  EXPECT_DOUBLE_EQ(parseUnit("m2").to_si, parseUnit("m^2").to_si);
  EXPECT_EQ(parseUnit("m s^-1").dim, parseUnit("m/s").dim);
  EXPECT_NEAR(parseUnit("um2").to_si, 1e-12, 1e-24);
}

TEST(Units, BareNumberIsSi) {
  const Quantity q = parseQuantity("0.001");
  EXPECT_DOUBLE_EQ(q.si, 0.001);
  EXPECT_TRUE(q.dim.isDimensionless());
}

TEST(Units, FromSiConvertsBack) {
  EXPECT_NEAR(fromSi(2.46730825e-12, "D"), 2.5, 1e-12);
  EXPECT_NEAR(fromSi(4.0e-6, "cm/min"), 0.024, 1e-15);
  EXPECT_THROW(fromSi(1.0, "Pa s/m/s"), UnitError);
}

TEST(Units, UnknownUnitNamesTheSymbol) {
  try {
    parseQuantity("5 furlongs");
    FAIL() << "expected UnitError";
  } catch (const UnitError& e) {
    EXPECT_NE(std::string(e.what()).find("furlongs"), std::string::npos) << e.what();
  }
}

TEST(Units, MalformedNumbersAreRejected) {
  EXPECT_THROW(parseQuantity("um 5"), UnitError);
  EXPECT_THROW(parseQuantity(""), UnitError);
  EXPECT_THROW(parseQuantity("5 m//s"), UnitError);
}

// Found by fuzz_units (fuzz/findings): huge exponents overflowed the int
// dimension arithmetic (undefined behaviour) instead of being refused.
TEST(Units, HugeExponentsAreRefusedNotOverflowed) {
  EXPECT_THROW(parseUnit("D1111111111"), UnitError);
  EXPECT_THROW(parseUnit("11 P33311 P33322 P2111111122 P2111111111"), UnitError);
  EXPECT_THROW(parseUnit("m13"), UnitError);
  std::string many = "m12";
  for (int i = 0; i < 10; ++i) many += " m12";
  EXPECT_THROW(parseUnit(many), UnitError);
  EXPECT_EQ(parseUnit("m12").dim.exponent[0], 12);
  EXPECT_EQ(parseUnit("m^-3").dim.exponent[0], -3);
}

// Memory limits (run.max_memory) take byte units, decimal and binary.
TEST(Units, MemoryUnits) {
  EXPECT_DOUBLE_EQ(parseQuantity("8 GiB").si, 8.0 * 1024 * 1024 * 1024);
  EXPECT_DOUBLE_EQ(parseQuantity("500 MB").si, 5e8);
  EXPECT_EQ(dimensionName(parseUnit("GB").dim), "memory (bytes)");
  EXPECT_FALSE(parseUnit("GB").dim == parseUnit("m").dim);
}

// The micro sign (U+00B5) and the Greek small letter mu (U+03BC) look alike
// and both mean 1e-6 (what a keyboard gives varies); "micron" is the old
// name of the micrometre (retired by the CGPM in 1967, still common in labs).
TEST(Units, GreekMuAndMicronMeanMicro) {
  EXPECT_NEAR(parseQuantity("5 \u03bcm").si, 5e-6, 1e-18);
  EXPECT_NEAR(parseQuantity("5 \u00b5m").si, 5e-6, 1e-18);
  EXPECT_NEAR(parseQuantity("12 micron").si, 12e-6, 1e-18);
  EXPECT_NEAR(parseQuantity("12 microns").si, 12e-6, 1e-18);
  EXPECT_NEAR(parseUnit("microns2").to_si, 1e-12, 1e-24);
  EXPECT_EQ(parseUnit("micron").dim, parseUnit("m").dim);
  EXPECT_NEAR(parseQuantity("5 \u03bcL/min").si, 5e-9 / 60.0, 1e-22);
  EXPECT_EQ(parseUnit("\u03bcL/min").dim, parseUnit("uL/min").dim);
  EXPECT_NEAR(fromSi(5e-6, "\u03bcm"), 5.0, 1e-12);
}

TEST(Units, DimensionNames) {
  EXPECT_EQ(dimensionName(parseUnit("Pa s").dim), "dynamic viscosity");
  EXPECT_EQ(dimensionName(parseUnit("m/s").dim), "velocity");
}

}  // namespace
}  // namespace mmval
