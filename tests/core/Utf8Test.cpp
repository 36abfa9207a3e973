// The UTF-8 validator and the guard in front of toml++ (Utf8.hpp): every class
// of malformed sequence in Unicode 15 table 3-7, its offset, line and column,
// and the code points toml++ 3.3.0 must not see.
#include <gtest/gtest.h>

#include <string>

#include "mmval/core/Error.hpp"
#include "mmval/core/Utf8.hpp"

namespace mmval {
namespace {

std::optional<TextProblem> bad(std::string_view s) { return findInvalidUtf8(s); }

TEST(Utf8, AcceptsValidText) {
  EXPECT_FALSE(bad(""));
  EXPECT_FALSE(bad("plain ASCII\n"));
  EXPECT_FALSE(bad("\xC2\xB5m"));                  // U+00B5 micro sign, 2 bytes
  EXPECT_FALSE(bad("\xE2\x82\xAC"));               // U+20AC euro, 3 bytes
  EXPECT_FALSE(bad("\xED\x9F\xBF"));               // U+D7FF, last before the surrogates
  EXPECT_FALSE(bad("\xEE\x80\x80"));               // U+E000, first after them
  EXPECT_FALSE(bad("\xF0\x90\x80\x80"));           // U+10000, first 4-byte
  EXPECT_FALSE(bad("\xF4\x8F\xBF\xBF"));           // U+10FFFF, the last code point
  EXPECT_FALSE(bad("\xEF\xBB\xBF" "a = 1"));       // byte-order mark
  EXPECT_FALSE(bad("\xD1\xBB"));                   // U+047B: valid UTF-8 (toml++ trips on it, see below)
}

TEST(Utf8, RejectsStrayContinuationAndForbiddenBytes) {
  auto p = bad("ab\x80");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->offset, 2u);
  EXPECT_EQ(p->got, "80");
  EXPECT_NE(p->problem.find("continuation"), std::string::npos);
  for (const char* s : {"\xF5\x80\x80\x80", "\xFE", "\xFF"}) {
    p = bad(s);
    ASSERT_TRUE(p) << s;
    EXPECT_NE(p->problem.find("never occurs"), std::string::npos);
  }
}

TEST(Utf8, RejectsOverlongEncodings) {
  // '/' (U+002F) in 2, 3 and 4 bytes; U+07FF in 3; U+FFFF in 4.
  for (const char* s : {"\xC0\xAF", "\xC1\xBF", "\xE0\x80\xAF", "\xE0\x9F\xBF", "\xF0\x80\x80\xAF", "\xF0\x8F\xBF\xBF"}) {
    const auto p = bad(s);
    ASSERT_TRUE(p) << s;
    EXPECT_EQ(p->offset, 0u);
    EXPECT_NE(p->problem.find("overlong"), std::string::npos) << p->problem;
  }
}

TEST(Utf8, RejectsSurrogatesAndCodePointsAboveTheLast) {
  for (const char* s : {"\xED\xA0\x80", "\xED\xBF\xBF"}) {  // U+D800, U+DFFF
    const auto p = bad(s);
    ASSERT_TRUE(p);
    EXPECT_NE(p->problem.find("surrogate"), std::string::npos);
    EXPECT_EQ(p->got, std::string(s) == "\xED\xA0\x80" ? "ED A0" : "ED BF");
  }
  const auto p = bad("\xF4\x90\x80\x80");  // U+110000
  ASSERT_TRUE(p);
  EXPECT_NE(p->problem.find("above U+10FFFF"), std::string::npos);
}

TEST(Utf8, RejectsTruncatedSequences) {
  // At the end of the text, and interrupted by an ASCII byte.
  for (const char* s : {"\xC3", "\xE2\x82", "\xF0\x9F\x98", "\xE2\x82" "a", "\xF0\x9F" "ab"}) {
    const auto p = bad(s);
    ASSERT_TRUE(p) << s;
    EXPECT_NE(p->problem.find("truncated"), std::string::npos) << p->problem;
  }
}

TEST(Utf8, ReportsLineAndColumnOfTheFirstProblem) {
  const auto p = bad("[case]\nname = \"x\"\nkind = \"a\xC0\xAF\" \xFF\n");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->line, 3);
  EXPECT_EQ(p->column, 10);  // bytes: k i n d ' ' = ' ' " a -> the 10th
  EXPECT_EQ(p->offset, 27u);
  EXPECT_EQ(p->got, "C0 AF");
}

TEST(TomlText, AcceptsNonAsciiInStringsAndComments) {
  EXPECT_FALSE(findUnsafeTomlText("# \xD1\xBB comment\nname = \"\xD1\xBB\"\n"));
  EXPECT_FALSE(findUnsafeTomlText("a = '\xC2\xA7'\n\"\xC2\xA7 key\" = 1\n"));
  EXPECT_FALSE(findUnsafeTomlText("s = \"\"\"\n\xC2\xA7 \\\" \xC2\xA7\"\"\"\n"));
  EXPECT_FALSE(findUnsafeTomlText("s = '''\n\xC2\xA7'''\nt = 1\n"));
  EXPECT_FALSE(findUnsafeTomlText("s = \"\"\"a\"\"\"\"\nt = \"\xC2\xA7\"\n"));  // closing """ plus one quote
  EXPECT_FALSE(findUnsafeTomlText("s = \"\"\"a\\\n   b\"\"\"\n"));  // line-ending backslash, ASCII next
  EXPECT_FALSE(findUnsafeTomlText("\xEF\xBB\xBF" "a = 1\n"));
}

// Strings in every place TOML allows them still take non-ASCII text.
TEST(TomlText, AcceptsStringsWhereverTomlPutsThem) {
  EXPECT_FALSE(findUnsafeTomlText("a = [\"\xC2\xB5m\", '\xC2\xB5m',\n  \"\xC2\xA7\"]\n"));
  EXPECT_FALSE(findUnsafeTomlText("t = { k = \"\xC2\xB5\", \"cl\xC3\xA9\" = 2 }\n"));
  EXPECT_FALSE(findUnsafeTomlText("[\"cl\xC3\xA9\"]\na.\"b\xC3\xA9\" = \"\xC2\xB5\"\n"));
  EXPECT_FALSE(findUnsafeTomlText("# note\n\"\xC2\xB5 key\" = 1\n"));
}

// Found by fuzz_case_reader: a quote inside a bare value (12"...") does not
// open a string, and toml++ scans ahead through what follows, reaching its
// unreachable branch on non-ASCII; such text is now refused first.
TEST(TomlText, RejectsNonAsciiAfterAQuoteInsideABareValue) {
  EXPECT_TRUE(findUnsafeTomlText("x = 12\"\xC2\xA7\"\n"));
  static const char kFuzzInput[] = "\nrun.duratation=000\"\0\0\0ooo\0case.desc:\0\0eomet\xEF\xBA\xBFry";
  const std::string fuzz_input(kFuzzInput, sizeof kFuzzInput - 1);
  EXPECT_TRUE(findUnsafeTomlText(fuzz_input));
}

TEST(TomlText, RejectsTheCodePointsTomlppMishandles) {
  // The fuzzer's smallest trigger: U+047B where a key or whitespace is expected.
  auto p = findUnsafeTomlText("\xD1\xBB");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->offset, 0u);
  EXPECT_NE(p->problem.find("outside a string"), std::string::npos);
  p = findUnsafeTomlText("a = 1\xC2\xA7\n");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->column, 6);
  // marzer/tomlplusplus#190: first on the line after a line-ending backslash.
  p = findUnsafeTomlText("s = \"\"\"\\\n  \xC2\xA7\"\"\"\n");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->line, 2);
  EXPECT_EQ(p->column, 3);
  EXPECT_TRUE(findUnsafeTomlText("s = \"\"\"\\\xC2\xA7\"\"\"\n"));
  EXPECT_TRUE(findUnsafeTomlText("s = \"\"\"\\ \xC2\xA7\"\"\"\n"));
  // Malformed UTF-8 anywhere, strings included.
  EXPECT_TRUE(findUnsafeTomlText("a = \"\xC0\xAF\"\n"));
}

TEST(TomlText, CheckThrowsInputErrorWithFileLineAndColumn) {
  try {
    checkTomlText("[case]\nkind = \"x\"\n\xD1\xBB = 1\n", "cases/bad.toml");
    FAIL() << "no InputError";
  } catch (const InputError& e) {
    EXPECT_EQ(e.where().file, "cases/bad.toml");
    EXPECT_EQ(e.where().line, 3);
    EXPECT_EQ(e.where().column, 1);
    EXPECT_EQ(e.got(), "D1 BB");
  }
  EXPECT_NO_THROW(checkTomlText("[case]\nkind = \"x\"\n", "ok.toml"));
}

}  // namespace
}  // namespace mmval
