#include "mmval/tracking/Frames.hpp"

#include <algorithm>
#include <ctime>
#include <exception>
#include <regex>
#include <thread>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <fmt/format.h>

#include "mmval/core/DataPaths.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"
#include "PngReader.hpp"

namespace fs = std::filesystem;

namespace mmval::tracking {

cv::Mat toFloatGrey(const cv::Mat& image) {
  cv::Mat grey = image;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  if (image.channels() == 4) cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  cv::Mat out;
  const double scale = grey.depth() == CV_16U ? 1.0 / 65535.0 : grey.depth() == CV_8U ? 1.0 / 255.0 : 1.0;
  grey.convertTo(out, CV_32F, scale);
  return out;
}

namespace {

bool isImage(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
  return ext == ".png" || ext == ".tif" || ext == ".tiff" || ext == ".jpg" || ext == ".jpeg" || ext == ".bmp";
}

std::regex globToRegex(const std::string& glob) {
  std::string re;
  for (char c : glob) {
    if (c == '*') re += "[^/]*";
    else if (c == '?') re += "[^/]";
    else if (std::string(".()[]{}+^$|\\").find(c) != std::string::npos) re += std::string("\\") + c;
    else re += c;
  }
  return std::regex(re);
}

/// Adds the calling thread's CPU time from construction to destruction to `total` (ns):
/// CPU time, not wall time, so that a loaded machine's preemptions do not count.
class DecodeTimer {
 public:
  explicit DecodeTimer(std::atomic<long long>& total) : m_total(total), m_start(threadNanoseconds()) {}
  ~DecodeTimer() { m_total += threadNanoseconds() - m_start; }
  DecodeTimer(const DecodeTimer&) = delete;
  DecodeTimer& operator=(const DecodeTimer&) = delete;

 private:
  static long long threadNanoseconds() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return static_cast<long long>(t.tv_sec) * 1000000000LL + t.tv_nsec;
  }
  std::atomic<long long>& m_total;
  long long m_start;
};

/// An image file as cv::imread(IMREAD_UNCHANGED) reads it, or, for the common 8-bit PNG,
/// its grey image (the same grey values, read ~2x faster: PngReader.hpp). Throws
/// InputError naming the file when it cannot be read.
cv::Mat readImage(const std::string& file) {
  cv::Mat image;
  if (file.size() > 4 && (file.compare(file.size() - 4, 4, ".png") == 0 || file.compare(file.size() - 4, 4, ".PNG") == 0) &&
      detail::readPngGrey8(file, image))
    return image;
  image = cv::imread(file, cv::IMREAD_UNCHANGED);
  if (image.empty()) throw InputError({file, 0, 0, {}}, "cannot read the image", {}, "PNG, TIFF or JPEG, 8 or 16 bit");
  return image;
}

}  // namespace

FrameSource::FrameSource(const std::string& input, std::optional<cv::Rect> roi, FrameRange range)
    : m_input(input), m_roi(roi), m_range(range) {
  const fs::path p(input);
  if (m_range.step < 1) throw InputError({input, 0, 0, "frame step"}, "frame step must be at least 1", std::to_string(m_range.step), ">= 1");
  if (fs::is_directory(p)) {
    for (const auto& e : fs::directory_iterator(p))
      if (e.is_regular_file() && isImage(e.path())) m_files.push_back(e.path().string());
    std::sort(m_files.begin(), m_files.end());
    if (m_files.empty()) throw InputError({input, 0, 0, {}}, "folder holds no images", {}, "PNG, TIFF or JPEG files");
    m_kind = Kind::images;
    m_total = static_cast<int>(m_files.size());
  } else if (input.find_first_of("*?") != std::string::npos) {
    const fs::path dir = p.parent_path().empty() ? fs::path(".") : p.parent_path();
    const std::regex re = globToRegex(p.filename().string());
    if (isDirectory(dir))
      for (const auto& e : fs::directory_iterator(dir))
        if (std::regex_match(e.path().filename().string(), re) && isImage(e.path())) m_files.push_back(e.path().string());
    std::sort(m_files.begin(), m_files.end());
    if (m_files.empty()) throw InputError({input, 0, 0, {}}, "no image matches the pattern", {}, "a glob such as frames/*.png");
    m_kind = Kind::images;
    m_total = static_cast<int>(m_files.size());
  } else {
    if (!pathExists(p)) throw InputError({input, 0, 0, {}}, "input not found", {}, "a video, an image folder, a glob or a multi-page TIFF");
    std::string ext = p.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), ::tolower);
    if (ext == ".tif" || ext == ".tiff") {
      m_kind = Kind::tiff;
      m_total = static_cast<int>(cv::imcount(input, cv::IMREAD_UNCHANGED));
      if (m_total <= 0) throw InputError({input, 0, 0, {}}, "cannot read the TIFF", {}, "a readable single- or multi-page TIFF");
    } else if (isImage(p)) {
      m_kind = Kind::images;
      m_files = {input};
      m_total = 1;
    } else {
      m_kind = Kind::video;
      m_video = std::make_unique<cv::VideoCapture>();
      if (!m_video->open(input)) throw InputError({input, 0, 0, {}}, "cannot open the video", {}, "a video OpenCV/FFmpeg reads (avi, mp4, mov, mkv)");
      m_total = static_cast<int>(m_video->get(cv::CAP_PROP_FRAME_COUNT));
    }
  }
  const int last = m_range.last < 0 ? m_total - 1 : std::min(m_range.last, m_total - 1);
  m_count = m_total > 0 && last >= m_range.first ? (last - m_range.first) / m_range.step + 1 : 0;
  if (m_count == 0) {
    // Say so here: otherwise an empty range ends as "no particles found ... check the polarity".
    const bool last_before_first = m_range.last >= 0 && m_range.last < m_range.first;
    throw InputError({input, 0, 0, last_before_first ? "inputs.last_frame" : "inputs.first_frame"}, "the frame range selects no frame",
                     fmt::format("frames {} to {} of an input with {} frame{}", m_range.first, m_range.last < 0 ? std::string("the end") : std::to_string(m_range.last),
                                 m_total, m_total == 1 ? "" : "s"),
                     m_total > 0 ? fmt::format("a first frame (--first, inputs.first_frame) from 0 to {} and a last frame (--last, inputs.last_frame) "
                                               "at or after it, or -1 for the end", m_total - 1)
                                 : std::string("an input with at least one readable frame"));
  }
  // The tracker holds ~64 frames as 32-bit float at once (60 sampled for the median background,
  // which the frame cache shares; the cache itself stays within a quarter of the limit;
  // the detection batch): refuse frames too large for that before the first is decoded.
  constexpr double kTrackerBytesPerPixel = 64 * 4;
  const double limit = defaultMaxMemoryBytes();
  const std::string advice = "smaller frames: a region of interest (--roi) does not help, the whole frame is decoded; downscale the video";
  if (m_kind == Kind::video) {
    const double w = m_video->get(cv::CAP_PROP_FRAME_WIDTH), h = m_video->get(cv::CAP_PROP_FRAME_HEIGHT);
    requireMemory(w * h * kTrackerBytesPerPixel, limit, fmt::format("tracking the video's {:.0f} x {:.0f} px frames", w, h), {input, 0, 0, "inputs.video"},
                  advice);
  } else {
    const std::string first = m_kind == Kind::tiff ? input : m_files[static_cast<std::size_t>(std::min<int>(m_range.first, static_cast<int>(m_files.size()) - 1))];
    requireImageWithin(first, {first, 0, 0, "inputs.video"}, limit, kTrackerBytesPerPixel, advice);
  }
  if (m_kind == Kind::video && m_range.first > 0) m_video->set(cv::CAP_PROP_POS_FRAMES, m_range.first);
  m_video_at = m_kind == Kind::video ? m_range.first : 0;
}

void FrameSource::rewind() { m_pos = 0; }

bool FrameSource::readVideo(int index, cv::Mat& out) {
  if (index < m_video_at) {
    // Back to the first selected frame (the position the constructor relies on too),
    // then forward: seeking to an arbitrary frame lands on a key frame in some codecs.
    m_video->set(cv::CAP_PROP_POS_FRAMES, m_range.first);
    m_video_at = m_range.first;
  }
  for (; m_video_at < index; ++m_video_at) {
    if (!m_video->grab()) return false;
    ++m_stats->grabbed;
  }
  ++m_video_at;
  if (!m_video->read(out) || out.empty()) return false;
  ++m_stats->decoded;
  return true;
}

bool FrameSource::readRaw(int index, cv::Mat& out) {
  switch (m_kind) {
    case Kind::images:
      if (index >= static_cast<int>(m_files.size())) return false;
      out = readImage(m_files[index]);
      ++m_stats->decoded;
      return true;
    case Kind::tiff: {
      if (index >= m_total) return false;
      std::vector<cv::Mat> pages;
      if (!cv::imreadmulti(m_input, pages, index, 1, cv::IMREAD_UNCHANGED) || pages.empty())
        throw InputError({m_input, 0, 0, {}}, "cannot read TIFF page " + std::to_string(index));
      out = pages.front();
      ++m_stats->decoded;
      return true;
    }
    case Kind::video:
      if (!readVideo(index, out))
        // The container announced more frames than can be decoded: a truncated or
        // damaged file. Say so rather than stop quietly with part of the video.
        throw InputError({m_input, 0, 0, {}}, "the video ends early (truncated or damaged): frame " + std::to_string(index) + " cannot be decoded",
                         std::to_string(index) + " of " + std::to_string(m_total) + " frames",
                         "a complete file, or inputs.last_frame below " + std::to_string(index) + " to use the readable part");
      return true;
  }
  return false;
}

void FrameSource::fixFirst(const cv::Mat& raw) {
  if (m_first_fixed) return;
  if (raw.depth() == CV_16U) {
    // Scientific cameras put 10-14 bit data (often a narrow band of it) in 16-bit
    // containers: stretch by the first frame's range, the same for every frame.
    cv::Mat grey = raw;
    if (raw.channels() != 1) cv::cvtColor(raw, grey, cv::COLOR_BGR2GRAY);
    cv::minMaxLoc(grey, &m_range16[0], &m_range16[1]);
    if (m_range16[1] <= m_range16[0]) m_range16[1] = m_range16[0] + 1;
  }
  m_size = raw.size();
  m_first_fixed = true;
}

bool FrameSource::takeCached(int pos, cv::Mat& frame) const {
  const std::lock_guard<std::mutex> lock(m_stats->mutex);
  const auto it = m_stats->cache.find(pos);
  if (it == m_stats->cache.end()) return false;
  frame = it->second;
  m_stats->cache.erase(it);
  return true;
}

void FrameSource::putCached(int pos, const cv::Mat& frame) {
  const double frame_bytes = static_cast<double>(frame.total() * frame.elemSize());
  const int by_bytes = frame_bytes > 0 ? static_cast<int>(std::min<double>(kMaxCachedFrames, 0.25 * defaultMaxMemoryBytes() / frame_bytes)) : 0;
  const std::lock_guard<std::mutex> lock(m_stats->mutex);
  if (static_cast<int>(m_stats->cache.size()) < std::min(m_cache_limit, by_bytes)) m_stats->cache.emplace(pos, frame);
}

bool FrameSource::primeFirst(cv::Mat& frame) {
  if (m_first_fixed) return false;
  const DecodeTimer timer(m_stats->decode_ns);
  cv::Mat raw;
  const int index = m_range.first;
  if (!readRaw(index, raw)) throw InputError({m_input, 0, 0, {}}, "cannot read the first selected frame " + std::to_string(index));
  fixFirst(raw);
  finish(raw, index, frame);
  putCached(0, frame);
  return true;
}

void FrameSource::sample(int pos, cv::Mat& frame, int& index) {
  if (pos < 0 || pos >= m_count) throw std::out_of_range("FrameSource::sample");
  index = m_range.first + pos * m_range.step;
  cv::Mat first;
  if (primeFirst(first) && pos == 0) {
    frame = first;
    return;
  }
  {
    const std::lock_guard<std::mutex> lock(m_stats->mutex);
    const auto it = m_stats->cache.find(pos);
    if (it != m_stats->cache.end()) {
      frame = it->second;
      return;
    }
  }
  {
    const DecodeTimer timer(m_stats->decode_ns);
    cv::Mat raw;
    if (!readRaw(index, raw)) throw InputError({m_input, 0, 0, {}}, "cannot read frame " + std::to_string(index));
    finish(raw, index, frame);
  }
  putCached(pos, frame);
}

void FrameSource::prefetch(std::vector<int> positions, int threads) {
  if (m_cache_limit <= 0 || m_count == 0) return;
  cv::Mat f;
  int index = 0;
  primeFirst(f);
  std::sort(positions.begin(), positions.end());
  positions.erase(std::unique(positions.begin(), positions.end()), positions.end());
  std::erase_if(positions, [&](int pos) { return pos < 0 || pos >= m_count || m_stats->cache.count(pos) != 0; });
  // As many as the cache has room for (the samplers decode the rest themselves).
  const double frame_bytes = 4.0 * m_size.area();
  const int room = static_cast<int>(std::min<double>(std::min(m_cache_limit, kMaxCachedFrames), 0.25 * defaultMaxMemoryBytes() / std::max(1.0, frame_bytes))) -
                   static_cast<int>(m_stats->cache.size());
  if (room <= 0) return;
  if (static_cast<int>(positions.size()) > room) positions.resize(static_cast<std::size_t>(room));
  if (threads <= 1 || !randomAccess()) {
    for (int pos : positions) sample(pos, f, index);
    return;
  }
  // Files: decoded by `threads` workers taking positions from a shared counter.
  std::atomic<std::size_t> next{0};
  std::vector<std::exception_ptr> failed(static_cast<std::size_t>(threads));
  auto work = [&](int t) {
    try {
      cv::Mat frame;
      int at = 0;
      for (std::size_t k; (k = next++) < positions.size();) {
        decodeAt(positions[k], frame, at);
        putCached(positions[k], frame);
      }
    } catch (...) {
      failed[static_cast<std::size_t>(t)] = std::current_exception();
      next = positions.size();
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < threads; ++t) pool.emplace_back(work, t);
  work(0);
  for (auto& t : pool) t.join();
  for (const auto& e : failed)
    if (e) std::rethrow_exception(e);
}

bool FrameSource::next(cv::Mat& frame, int& index) {
  if (m_pos >= m_count) return false;
  index = m_range.first + m_pos * m_range.step;
  if (takeCached(m_pos, frame)) {
    ++m_pos;
    return true;
  }
  const DecodeTimer timer(m_stats->decode_ns);
  cv::Mat raw;
  if (!readRaw(index, raw)) return false;
  ++m_pos;
  fixFirst(raw);
  finish(raw, index, frame);
  return true;
}

void FrameSource::readAt(int pos, cv::Mat& frame, int& index) const {
  if (m_kind == Kind::video) throw std::logic_error("FrameSource::readAt: a video can only be read in order");
  index = m_range.first + pos * m_range.step;
  if (pos < 0 || pos >= m_count || index >= m_total) throw std::out_of_range("FrameSource::readAt");
  if (takeCached(pos, frame)) return;
  decodeAt(pos, frame, index);
}

void FrameSource::decodeAt(int pos, cv::Mat& frame, int& index) const {
  const DecodeTimer timer(m_stats->decode_ns);
  index = m_range.first + pos * m_range.step;
  cv::Mat raw;
  if (m_kind == Kind::images) {
    raw = readImage(m_files[index]);
  } else {
    std::vector<cv::Mat> pages;
    if (!cv::imreadmulti(m_input, pages, index, 1, cv::IMREAD_UNCHANGED) || pages.empty())
      throw InputError({m_input, 0, 0, {}}, "cannot read TIFF page " + std::to_string(index));
    raw = pages.front();
  }
  ++m_stats->decoded;
  finish(raw, index, frame);
}

void FrameSource::finish(const cv::Mat& raw, int index, cv::Mat& frame) const {
  // Always a new buffer: `frame` may share its pixels with the cache or a sampler's list.
  frame.release();
  const std::string name = m_kind == Kind::images ? m_files[index] : m_input;
  if (raw.size() != m_size)
    throw InputError({name, 0, 0, {}}, "frame size differs from the first frame", std::to_string(raw.cols) + " x " + std::to_string(raw.rows),
                     std::to_string(m_size.width) + " x " + std::to_string(m_size.height));
  if (raw.depth() == CV_16U) {
    cv::Mat grey = raw;
    if (raw.channels() != 1) cv::cvtColor(raw, grey, cv::COLOR_BGR2GRAY);
    const double lo = m_range16[0], hi = m_range16[1] > m_range16[0] ? m_range16[1] : m_range16[0] + 1;
    grey.convertTo(frame, CV_32F, 1.0 / (hi - lo), -lo / (hi - lo));
  } else {
    frame = toFloatGrey(raw);
  }
  if (m_roi) {
    const cv::Rect r = *m_roi & cv::Rect(0, 0, frame.cols, frame.rows);
    if (r.area() == 0) throw InputError({m_input, 0, 0, "roi"}, "region of interest lies outside the frame");
    frame = frame(r).clone();
  }
}

}  // namespace mmval::tracking
