// The strict UTF-8 validator (core/Utf8.hpp) against glibc's iconv, which
// also rejects overlongs, surrogates and code points above U+10FFFF: both must
// agree on whether a text is valid and, if not, on the offset of the first bad
// sequence. findUnsafeTomlText must never accept what findInvalidUtf8 rejects.
#include <iconv.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "FuzzSupport.hpp"
#include "mmval/core/Utf8.hpp"

namespace {

/// Offset of the first invalid sequence by iconv, or -1 when the text converts.
long iconvFirstInvalid(std::string_view text) {
  static iconv_t cd = iconv_open("UTF-32LE", "UTF-8");
  iconv(cd, nullptr, nullptr, nullptr, nullptr);
  std::vector<char> buffer(4 * text.size() + 4);
  char* in = const_cast<char*>(text.data());
  std::size_t in_left = text.size();
  char* out = buffer.data();
  std::size_t out_left = buffer.size();
  if (iconv(cd, &in, &in_left, &out, &out_left) != static_cast<std::size_t>(-1)) return -1;
  if (errno != EILSEQ && errno != EINVAL) std::abort();
  return static_cast<long>(in - text.data());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text = mmval::fuzz::asText(data, size);
  const auto ours = mmval::findInvalidUtf8(text);
  const long theirs = iconvFirstInvalid(text);
  const long our_offset = ours ? static_cast<long>(ours->offset) : -1;
  if (our_offset != theirs) {
    std::fprintf(stderr, "findInvalidUtf8 says %ld (%s), iconv says %ld\n", our_offset, ours ? ours->problem.c_str() : "valid", theirs);
    std::abort();
  }
  if (ours && !mmval::findUnsafeTomlText(text)) std::abort();
  return 0;
}
