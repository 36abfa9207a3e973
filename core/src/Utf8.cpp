#include "mmval/core/Utf8.hpp"

#include <cstdint>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace mmval {
namespace {

std::uint8_t byteAt(std::string_view s, std::size_t i) { return static_cast<std::uint8_t>(s[i]); }

bool isContinuation(std::uint8_t b) { return (b & 0xC0u) == 0x80u; }

std::string hexBytes(std::string_view s, std::size_t begin, std::size_t count) {
  std::string out;
  for (std::size_t i = begin; i < begin + count && i < s.size(); ++i)
    out += fmt::format("{}{:02X}", out.empty() ? "" : " ", byteAt(s, i));
  return out;
}

TextProblem problemAt(std::string_view text, std::size_t offset, std::size_t length, std::string problem) {
  TextProblem p;
  p.offset = offset;
  std::size_t line_start = 0;
  for (std::size_t i = 0; i < offset; ++i)
    if (text[i] == '\n') {
      ++p.line;
      line_start = i + 1;
    }
  p.column = static_cast<int>(offset - line_start) + 1;
  p.problem = std::move(problem);
  p.got = hexBytes(text, offset, length);
  return p;
}

/// Decodes the sequence at `i` (Unicode 15, table 3-7). Returns its length and
/// code point, or a problem. `i` must be < text.size().
struct Decoded {
  std::size_t length = 0;
  char32_t code_point = 0;
  std::optional<TextProblem> problem;
};

Decoded decodeAt(std::string_view text, std::size_t i) {
  const std::uint8_t lead = byteAt(text, i);
  if (lead < 0x80u) return {1, lead, {}};
  if (isContinuation(lead)) return {1, 0, problemAt(text, i, 1, "UTF-8 continuation byte without a lead byte")};
  if (lead == 0xC0u || lead == 0xC1u)
    return {1, 0, problemAt(text, i, 2, "overlong UTF-8 encoding (lead byte C0 or C1)")};
  if (lead > 0xF4u) return {1, 0, problemAt(text, i, 1, "byte that never occurs in UTF-8 (F5 to FF)")};

  const std::size_t length = lead < 0xE0u ? 2 : lead < 0xF0u ? 3 : 4;
  // The allowed range of the second byte narrows for E0, ED, F0 and F4 so that
  // overlongs, surrogates and code points above U+10FFFF are excluded.
  std::uint8_t second_low = 0x80u, second_high = 0xBFu;
  if (lead == 0xE0u) second_low = 0xA0u;
  if (lead == 0xEDu) second_high = 0x9Fu;
  if (lead == 0xF0u) second_low = 0x90u;
  if (lead == 0xF4u) second_high = 0x8Fu;

  char32_t cp = lead & (length == 2 ? 0x1Fu : length == 3 ? 0x0Fu : 0x07u);
  for (std::size_t k = 1; k < length; ++k) {
    if (i + k >= text.size())
      return {1, 0, problemAt(text, i, k, fmt::format("truncated UTF-8 sequence: {} of {} bytes before the end of the text", k, length))};
    const std::uint8_t b = byteAt(text, i + k);
    if (!isContinuation(b))
      return {1, 0, problemAt(text, i, k + 1, fmt::format("truncated UTF-8 sequence: {} of {} bytes, then a byte that does not continue it", k, length))};
    if (k == 1 && (b < second_low || b > second_high)) {
      std::string what = "overlong UTF-8 encoding";
      if (lead == 0xEDu) what = "UTF-16 surrogate (U+D800 to U+DFFF) encoded in UTF-8";
      if (lead == 0xF4u) what = "code point above U+10FFFF";
      return {1, 0, problemAt(text, i, 2, what)};
    }
    cp = (cp << 6) | (b & 0x3Fu);
  }
  return {length, cp, {}};
}

}  // namespace

std::optional<TextProblem> findInvalidUtf8(std::string_view text) {
  std::size_t i = 0;
  while (i < text.size()) {
    // ASCII runs are the common case in case files: skip them cheaply.
    if (byteAt(text, i) < 0x80u) {
      ++i;
      continue;
    }
    Decoded d = decodeAt(text, i);
    if (d.problem) return d.problem;
    i += d.length;
  }
  return std::nullopt;
}

std::optional<TextProblem> findUnsafeTomlText(std::string_view text) {
  static const std::string kBadEscape = "non-ASCII character after a backslash in a \"\"\" string (not a TOML escape)";
  if (auto p = findInvalidUtf8(text)) return p;

  // A small TOML 1.0 lexer that only tracks whether a byte is in a comment or
  // in which kind of string; it never rejects what toml++ would report itself.
  enum class State { normal, comment, basic, literal, ml_basic, ml_literal, ml_after_line_end };
  State state = State::normal;
  const auto startsWith = [&](std::size_t i, std::string_view s) { return text.substr(i, s.size()) == s; };
  const auto nonAscii = [&](std::size_t i) { return byteAt(text, i) >= 0x80u; };
  const auto unsafe = [&](std::size_t i, const std::string& problem) {
    return problemAt(text, i, decodeAt(text, i).length, problem);
  };

  // A closing """ or ''' may be followed by one or two more quotes that belong
  // to the string (TOML 1.0 "String"); skip up to five in all.
  const auto skipClosing = [&](std::size_t i, char quote) {
    std::size_t n = 0;
    while (i + n < text.size() && text[i + n] == quote && n < 5) ++n;
    return i + n;
  };

  // toml++ skips a leading byte-order mark (U+FEFF, which it classifies safely).
  std::size_t i = text.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0;
  // A quote opens a string only where TOML allows one: first on a line, or
  // after '=', '[', '{', ',' or '.' (blanks between). Elsewhere (as in 12"...")
  // it is part of a bare value, which toml++ scans ahead through, classifying
  // every code point it meets; so what follows stays "outside a string" here.
  // Found by fuzz_case_reader (fuzz/findings/tomlpp-quote-in-bare-value.toml).
  char before = '\n';  // last byte outside strings and comments that is not a blank
  const auto opensString = [&] { return before == '\n' || before == '=' || before == '[' || before == '{' || before == ',' || before == '.'; };
  while (i < text.size()) {
    const char c = text[i];
    if (state == State::normal && c != ' ' && c != '\t' && c != '\r') {
      const bool quote = c == '"' || c == '\'';
      if (quote && !opensString()) {
        before = c;
        ++i;
        continue;
      }
      before = quote ? '"' : c;  // after a string closes, `before` reads as a value character
    }
    if (state == State::comment && c == '\n') before = '\n';
    switch (state) {
      case State::normal:
        if (c == '#') {
          state = State::comment;
        } else if (startsWith(i, "\"\"\"")) {
          state = State::ml_basic;
          i += 3;
          continue;
        } else if (startsWith(i, "'''")) {
          state = State::ml_literal;
          i += 3;
          continue;
        } else if (c == '"') {
          state = State::basic;
        } else if (c == '\'') {
          state = State::literal;
        } else if (nonAscii(i)) {
          // Bare keys, values and whitespace are ASCII in TOML 1.0: never valid here.
          return unsafe(i, "non-ASCII character outside a string or comment (TOML keys and whitespace are ASCII)");
        }
        break;
      case State::comment:
        if (c == '\n') state = State::normal;
        break;
      case State::basic:
        if (c == '\\' && i + 1 < text.size() && text[i + 1] != '\n') {
          ++i;  // the escaped byte cannot end the string
        } else if (c == '"' || c == '\n') {
          state = State::normal;
        }
        break;
      case State::literal:
        if (c == '\'' || c == '\n') state = State::normal;
        break;
      case State::ml_basic:
        if (startsWith(i, "\"\"\"")) {
          i = skipClosing(i, '"');
          state = State::normal;
          continue;
        }
        if (c == '\\') {
          // toml++ asks whether the escaped character is whitespace (a
          // line-ending backslash), which is the undefined case for non-ASCII.
          if (i + 1 < text.size() && nonAscii(i + 1)) return unsafe(i + 1, kBadEscape);
          std::size_t j = i + 1;
          while (j < text.size() && (text[j] == ' ' || text[j] == '\t' || text[j] == '\r')) ++j;
          if (j < text.size() && text[j] == '\n') {
            state = State::ml_after_line_end;
            i = j + 1;
            continue;
          }
          if (j < text.size() && j > i + 1 && nonAscii(j))
            return unsafe(j, kBadEscape);
          i += 2;  // an ordinary escape such as \" or \\ .
          continue;
        }
        break;
      case State::ml_after_line_end:
        // toml++ skips whitespace after a line-ending backslash by asking, for
        // each character, whether it is whitespace.
        if (c == ' ' || c == '\t' || c == '\r' || c == '\n') break;
        if (nonAscii(i))
          return unsafe(i, "non-ASCII character first after a line-ending backslash in a \"\"\" string: valid TOML, "
                           "but toml++ 3.3.0 mishandles it (marzer/tomlplusplus#190); write it as \\uXXXX");
        state = State::ml_basic;
        continue;  // re-read it as string content (it may be a quote or a backslash)
      case State::ml_literal:
        if (startsWith(i, "'''")) {
          i = skipClosing(i, '\'');
          state = State::normal;
          continue;
        }
        break;
    }
    ++i;
  }
  return std::nullopt;
}

void checkTomlText(std::string_view text, const std::string& file) {
  if (const auto p = findUnsafeTomlText(text))
    throw InputError({file, p->line, p->column, {}}, p->problem, p->got,
                     "valid UTF-8, with non-ASCII characters only inside strings and comments");
}

}  // namespace mmval
