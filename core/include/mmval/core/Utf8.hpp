// Checks on text before it reaches a parser that trusts its input.
//
// TOML files must be valid UTF-8 (TOML 1.0.0, "Spec"). toml++ 3.3.0, the
// Debian 12 package mmval links, decodes UTF-8 without rejecting every bad
// sequence, and its whitespace classifier reaches __builtin_unreachable()
// (undefined behaviour) for many *valid* non-ASCII code points (U+00A1 to
// U+0499 and others) when they stand where the parser looks for whitespace:
// outside strings and comments, or first on the line after a line-ending
// backslash in a multi-line basic string. Upstream: marzer/tomlplusplus
// issues #190 and #295, fixed by pull request #305 ("return false for
// non-whitespace code points"), which is in no Debian 12 release. Until mmval
// links a fixed toml++, checkTomlText() is called on every TOML text before
// toml::parse: it rejects malformed UTF-8 and the code points toml++
// mishandles, with the file, line and column, and accepts every valid TOML
// 1.0 document except the one with a non-ASCII character right after a
// line-ending backslash (which it rejects with advice to escape it).
#pragma once
#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace mmval {

/// The first problem found in a text. Line and column are 1-based; the
/// column counts bytes, so an editor's column may differ after non-ASCII text.
struct TextProblem {
  std::size_t offset = 0;  ///< byte offset of the offending sequence
  int line = 1;
  int column = 1;
  std::string problem;     ///< e.g. "overlong UTF-8 encoding of U+002F"
  std::string got;         ///< the offending bytes in hex ("C0 AF")
};

/// Strict UTF-8 (RFC 3629, Unicode 15 table 3-7): rejects stray continuation
/// bytes, truncated sequences, overlong encodings, surrogates (U+D800 to
/// U+DFFF), code points above U+10FFFF and the bytes C0, C1, F5 to FF.
/// Returns the first problem, or nothing when `text` is valid UTF-8.
std::optional<TextProblem> findInvalidUtf8(std::string_view text);

/// findInvalidUtf8(), then the non-ASCII code points toml++ 3.3.0 must not see
/// (see the comment at the top of this file): any outside strings and
/// comments (never valid TOML 1.0: bare keys and whitespace are ASCII), and
/// one first on the line after a line-ending backslash in a """ string.
std::optional<TextProblem> findUnsafeTomlText(std::string_view text);

/// Throws InputError naming `file`, line and column when findUnsafeTomlText()
/// finds a problem; call it on every TOML text before toml::parse.
void checkTomlText(std::string_view text, const std::string& file);

}  // namespace mmval
