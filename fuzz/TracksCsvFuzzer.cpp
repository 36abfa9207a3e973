// The tracks CSV reader (Tracks.hpp), with and without a pixel size. Expected
// outcome of bad input: InputError. A file that reads must survive a round
// trip through writeTracksCsv with the same number of points.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>

#include "FuzzSupport.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Tracks.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& dir = mmval::fuzz::scratchDir();
  const auto in = dir / "tracks.csv";
  const auto out = dir / "roundtrip.csv";
  mmval::fuzz::writeFile(in, mmval::fuzz::asText(data, size));
  for (const double pixel_size_m : {0.0, 0.5e-6}) {
    try {
      const mmval::Tracks t = mmval::readTracksCsv(in, pixel_size_m);
      mmval::writeTracksCsv(out, t, pixel_size_m);
      const mmval::Tracks again = mmval::readTracksCsv(out, pixel_size_m);
      if (again.points.size() != t.points.size()) {
        std::fprintf(stderr, "round trip changed the number of points: %zu -> %zu\n", t.points.size(), again.points.size());
        std::abort();
      }
    } catch (const mmval::InputError&) {
    }
  }
  return 0;
}
