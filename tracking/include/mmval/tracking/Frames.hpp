// Frame sources: a video (any format OpenCV/FFmpeg reads), a folder or glob
// of images (PNG, TIFF, JPEG; 8 or 16 bit), or a multi-page TIFF. Frames are
// streamed one at a time as single-channel 32-bit float in [0, 1], so memory
// stays bounded on long videos. Optional region of interest and frame range.
// 8-bit frames map 0..255 to 0..1; 16-bit frames are stretched by the first
// frame's range (the same for all frames), since cameras rarely fill 16 bits.
#pragma once
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/videoio.hpp>

namespace mmval::tracking {

struct FrameRange {
  int first = 0;
  int last = -1;  ///< inclusive; -1: to the end
  int step = 1;
};

class FrameSource {
 public:
  /// Opens `input`; throws InputError naming it when it cannot be read.
  FrameSource(const std::string& input, std::optional<cv::Rect> roi = std::nullopt, FrameRange range = {});
  /// Next frame (float, [0, 1]); false at the end.
  bool next(cv::Mat& frame, int& index);
  /// Frames in the selected range, when known (0 otherwise).
  int count() const { return m_count; }
  /// Starts again from the first selected frame.
  void rewind();
  const std::string& input() const { return m_input; }
  /// Image files (folder or glob) can be read out of order and from several threads at
  /// once with readAt(); videos and TIFF stacks only in order with next().
  bool randomAccess() const { return m_kind == Kind::images; }
  /// Frame number `pos` of the selected range (0 <= pos < count()) and its index in the
  /// input; thread-safe once next() has returned the first frame (which fixes the frame
  /// size and the 16-bit range every frame is checked against). Throws like next().
  void readAt(int pos, cv::Mat& frame, int& index) const;

 private:
  bool readRaw(int index, cv::Mat& out);
  /// Raw image -> float grey [0, 1], size check, region of interest (const: safe in threads
  /// once m_size and m_range16 are set by the first frame).
  void finish(const cv::Mat& raw, int index, cv::Mat& frame) const;
  std::string m_input;
  std::optional<cv::Rect> m_roi;
  FrameRange m_range;
  enum class Kind { video, images, tiff } m_kind = Kind::images;
  std::vector<std::string> m_files;  // images
  cv::VideoCapture m_video;
  int m_total = 0, m_count = 0, m_pos = 0;
  double m_range16[2] = {0, 0};
  cv::Size m_size;  // of the first frame: every frame must match  // 16-bit inputs: [min, max] of the first frame
};

/// Converts any grey or colour image, 8 or 16 bit, to float grey in [0, 1].
cv::Mat toFloatGrey(const cv::Mat& image);

}  // namespace mmval::tracking
