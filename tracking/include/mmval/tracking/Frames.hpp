// Frame sources: a video (any format OpenCV/FFmpeg reads), a folder or glob
// of images (PNG, TIFF, JPEG; 8 or 16 bit), or a multi-page TIFF. Frames are
// streamed one at a time as single-channel 32-bit float in [0, 1], so memory
// stays bounded on long videos. Optional region of interest and frame range.
// 8-bit frames map 0..255 to 0..1; 16-bit frames are stretched by the first
// frame's range (the same for all frames), since cameras rarely fill 16 bits.
//
// Each frame is decoded at most once per run: samplers (background, polarity) read
// only the frames they keep with sample(), and keep them in a bounded cache that the
// main pass (next(), readAt()) takes them from. The cache holds at most
// kMaxCachedFrames frames and at most a quarter of run.max_memory's default
// (defaultMaxMemoryBytes()); a sampled frame that does not fit is decoded again
// by the main pass. Videos are decoded in order: a sampler skips the frames
// between its samples with grab() (the codec still runs, the pixel conversion
// does not), and the main pass grab()s past frames the cache already holds.
#pragma once
#include <atomic>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
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
  /// Input index of position `pos` of the selected range.
  int indexOf(int pos) const { return m_range.first + pos * m_range.step; }
  /// Frames in the selected range, when known (0 otherwise).
  int count() const { return m_count; }
  /// Starts again from the first selected frame.
  void rewind();
  const std::string& input() const { return m_input; }
  /// Image files (folder or glob) and multi-page TIFF can be read out of order and from
  /// several threads at once with readAt(); videos only in order with next().
  bool randomAccess() const { return m_kind != Kind::video; }
  /// Frame number `pos` of the selected range (0 <= pos < count()) and its index in the
  /// input; thread-safe once next() has returned the first frame (which fixes the frame
  /// size and the 16-bit range every frame is checked against). Throws like next().
  /// A cached frame is handed out (and leaves the cache) instead of decoded again.
  void readAt(int pos, cv::Mat& frame, int& index) const;
  /// Frame `pos` of the selected range for a sampler: decoded (the first selected frame
  /// before it, once, as it fixes size and 16-bit range) and kept in the cache when
  /// there is room, so that the main pass does not decode it again; from the cache if
  /// it is there already (it stays). Does not move next()'s position. Videos: cheapest
  /// in increasing `pos` (prefetch()); a smaller pos than the capture's seeks back to
  /// the first selected frame and grabs forward. Throws like next().
  void sample(int pos, cv::Mat& frame, int& index);
  /// Decodes the given positions (any order, duplicates allowed) into the cache, as far
  /// as it has room: one forward pass over a video; image files and TIFF pages with
  /// `threads` threads. Throws like next().
  void prefetch(std::vector<int> positions, int threads = 1);
  /// Frames fully decoded so far (imread, TIFF page, video read/retrieve), and video
  /// frames skipped with grab() (codec only): for tests and benchmarks.
  long decoded() const { return m_stats->decoded.load(); }
  long grabbed() const { return m_stats->grabbed.load(); }
  /// CPU time spent decoding and converting frames so far, summed over threads (s): the
  /// decoding share of a run's CPU time.
  double decodeSeconds() const { return 1e-9 * static_cast<double>(m_stats->decode_ns.load()); }
  /// Largest number of frames the cache may hold (the byte bound may lower it); 0
  /// turns the cache off (every sampled frame is decoded again by the main pass).
  void setCacheLimit(int frames) { m_cache_limit = frames; }
  static constexpr int kMaxCachedFrames = 128;

 private:
  bool readRaw(int index, cv::Mat& out);
  /// Video: the raw frame `index` of the input, grabbing past the frames before it.
  bool readVideo(int index, cv::Mat& out);
  /// Fixes frame size and 16-bit range from the first selected frame (raw).
  void fixFirst(const cv::Mat& raw);
  /// Decodes the first selected frame into `frame` (and the cache) unless done; true if it did.
  bool primeFirst(cv::Mat& frame);
  bool takeCached(int pos, cv::Mat& frame) const;
  /// Image file or TIFF page at `pos`, decoded (thread-safe once the first frame is fixed).
  void decodeAt(int pos, cv::Mat& frame, int& index) const;
  void putCached(int pos, const cv::Mat& frame);
  struct Shared {
    std::mutex mutex;
    std::map<int, cv::Mat> cache;  // position in the range -> float frame
    std::atomic<long> decoded{0}, grabbed{0};
    std::atomic<long long> decode_ns{0};
  };
  /// Raw image -> float grey [0, 1], size check, region of interest (const: safe in threads
  /// once m_size and m_range16 are set by the first frame).
  void finish(const cv::Mat& raw, int index, cv::Mat& frame) const;
  std::string m_input;
  std::optional<cv::Rect> m_roi;
  FrameRange m_range;
  enum class Kind { video, images, tiff } m_kind = Kind::images;
  std::vector<std::string> m_files;  // images
  std::unique_ptr<cv::VideoCapture> m_video;  // videos only: image inputs never load OpenCV's video module
  int m_total = 0, m_count = 0, m_pos = 0;
  int m_video_at = 0;  // input index of the frame the capture returns next
  int m_cache_limit = kMaxCachedFrames;
  bool m_first_fixed = false;
  std::unique_ptr<Shared> m_stats = std::make_unique<Shared>();
  double m_range16[2] = {0, 0};
  cv::Size m_size;  // of the first frame: every frame must match  // 16-bit inputs: [min, max] of the first frame
};

/// Converts any grey or colour image, 8 or 16 bit, to float grey in [0, 1].
cv::Mat toFloatGrey(const cv::Mat& image);

}  // namespace mmval::tracking
