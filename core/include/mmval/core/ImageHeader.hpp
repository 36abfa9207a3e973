// Image sizes read from the file's header, without decoding the pixels.
//
// A 1 MB PNG can declare 30000 x 30000 pixels: decoding it first and looking
// at the size afterwards needs the 900 MB (grey) to 3.6 GB (RGBA) the decoder
// allocates, and everything built from the image again. The readers here look
// at the first bytes only:
//   PNG   IHDR chunk (ISO/IEC 15948, 11.2.2)
//   TIFF  first IFD, both byte orders, classic and BigTIFF (TIFF 6.0 section 2; BigTIFF design note)
//   JPEG  the first SOFn segment (ITU-T T.81, B.2.2)
//   BMP   BITMAPINFOHEADER and later, or the old OS/2 BITMAPCOREHEADER
//   PGM/PPM/PBM  Netpbm headers (P1-P6), comments allowed
// Anything else (or a file that cannot be read) gives no header: the caller's
// decoder then decides.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "mmval/core/Error.hpp"

namespace mmval {

struct ImageHeader {
  std::string format;          ///< "PNG", "TIFF", "BigTIFF", "JPEG", "BMP", "PNM"
  std::int64_t width = 0;      ///< px
  std::int64_t height = 0;     ///< px
  int channels = 1;            ///< samples per pixel (grey 1, grey+alpha 2, RGB 3, RGBA 4)
  int bit_depth = 8;           ///< bits per sample
  double pixels() const { return static_cast<double>(width) * static_cast<double>(height); }
  /// Bytes of the decoded image as stored (all channels, 8- or 16-bit samples).
  double decodedBytes() const;
};

/// The header of `file`, or nullopt when the format is none of the above or the
/// header is cut short. Reads at most a few hundred kilobytes (JPEG segments
/// before SOF, TIFF's first IFD); never decodes pixels.
std::optional<ImageHeader> readImageHeader(const std::filesystem::path& file);

/// Refuses an image whose processing would not fit in `limit_bytes`, before it
/// is decoded: the estimate is pixels x `bytes_per_pixel`, the caller's measured
/// peak per pixel of reading the image and what it builds from it (never less
/// than the decoded image itself). Throws InputError at `where` naming the
/// image's size, the estimate and the limit; `advice` says what to change.
/// Returns the header (nullopt when it could not be read: the decoder decides).
std::optional<ImageHeader> requireImageWithin(const std::filesystem::path& file, const InputLocation& where, double limit_bytes,
                                              double bytes_per_pixel, const std::string& advice);

}  // namespace mmval
