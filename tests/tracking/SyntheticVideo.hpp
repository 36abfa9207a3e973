// A synthetic micromodel video with ground truth written under the build tree,
// for the tests of the tracker's stages (FramesTest.cpp, PipelineTest.cpp).
#pragma once
#include <filesystem>

#include "mmval/tracking/Synth.hpp"

namespace mmval::tracking {

/// Writes the video of `o` to <build>/test-output/<name> (emptied first) and its truth to `r`.
inline std::filesystem::path synthetic(const char* name, const SynthOptions& o, SynthResult& r) {
  const std::filesystem::path dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output" / name;
  std::filesystem::remove_all(dir);
  r = writeSyntheticVideo(o, dir);
  return dir;
}

}  // namespace mmval::tracking
