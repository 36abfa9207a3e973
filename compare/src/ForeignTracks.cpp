#include "mmval/compare/ForeignTracks.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <stdexcept>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"
#include "mmval/core/Strings.hpp"

namespace mmval::compare {

namespace {

namespace fs = std::filesystem;

/// One CSV record: fields split at commas outside double quotes, quotes removed
/// ("" inside quotes is one quote), surrounding blanks trimmed.
std::vector<std::string> splitRecord(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (c == '"') {
      if (quoted && i + 1 < line.size() && line[i + 1] == '"') {
        cur += '"';
        ++i;
      } else {
        quoted = !quoted;
      }
    } else if (c == ',' && !quoted) {
      out.push_back(cur);
      cur.clear();
    } else if (c != '\r') {
      cur += c;
    }
  }
  out.push_back(cur);
  for (auto& s : out) {
    const auto a = s.find_first_not_of(" \t"), b = s.find_last_not_of(" \t");
    s = a == std::string::npos ? std::string() : s.substr(a, b - a + 1);
  }
  return out;
}

std::optional<double> parseNumber(const std::string& text) {
  double v = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (ec != std::errc() || ptr != end || !std::isfinite(v)) return std::nullopt;
  return v;
}

/// A whole number, also written as "12.0" (pandas writes an integer column holding a missing value as floats).
std::optional<std::int64_t> parseWhole(const std::string& text) {
  std::int64_t v = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (ec != std::errc() || ptr == text.data()) return std::nullopt;
  if (ptr != end && (*ptr != '.' || std::any_of(ptr + 1, end, [](char c) { return c != '0'; }))) return std::nullopt;
  return v;
}

/// The header line (first line that is neither empty nor a # comment) and its line number.
std::pair<std::vector<std::string>, int> readHeader(std::ifstream& in, const fs::path& file) {
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line != "\r" && line[0] != '#') return {splitRecord(line), line_no};
  }
  throw InputError({file.string(), line_no, 0, {}}, "empty tracks file", {}, "a CSV header line and rows");
}

/// Reads the rows of a CSV after its header, calling `row(fields, line_no)`.
template <class Row>
void forEachRow(std::ifstream& in, int line_no, Row&& row) {
  std::string line;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line == "\r" || line[0] == '#') continue;
    row(splitRecord(line), line_no);
  }
}

class Columns {
 public:
  Columns(std::vector<std::string> header, fs::path file, int line_no, std::string expected)
      : m_header(std::move(header)), m_file(std::move(file)), m_line(line_no), m_expected(std::move(expected)) {
    for (std::size_t i = 0; i < m_header.size(); ++i)
      if (!m_header[i].empty()) m_index.emplace(m_header[i], static_cast<int>(i));
  }
  bool has(const std::string& name) const { return m_index.count(name) > 0; }
  int at(const std::string& name) const {
    const auto it = m_index.find(name);
    if (it != m_index.end()) return it->second;
    const std::string near = nearest(name, m_header);
    throw InputError({m_file.string(), m_line, 0, name}, "missing column" + (near.empty() ? std::string() : "; found '" + near + "'"), join(m_header, ","),
                     m_expected);
  }
  const std::string& name(int c) const { return m_header[static_cast<std::size_t>(c)]; }

 private:
  std::vector<std::string> m_header;
  std::map<std::string, int> m_index;
  fs::path m_file;
  int m_line;
  std::string m_expected;
};

const std::string& field(const std::vector<std::string>& f, int c, const fs::path& file, int line_no, const std::string& name, std::size_t width) {
  if (c >= static_cast<int>(f.size()))
    throw InputError({file.string(), line_no, 0, name}, "row has too few fields", std::to_string(f.size()), std::to_string(width) + " fields");
  return f[static_cast<std::size_t>(c)];
}

double number(const std::vector<std::string>& f, int c, const fs::path& file, int line_no, const Columns& cols, std::size_t width) {
  const std::string& s = field(f, c, file, line_no, cols.name(c), width);
  const auto v = parseNumber(s);
  if (!v) throw InputError({file.string(), line_no, c + 1, cols.name(c)}, "not a finite number", "\"" + s + "\"", "a number");
  return *v;
}

std::int64_t whole(const std::vector<std::string>& f, int c, const fs::path& file, int line_no, const Columns& cols, std::size_t width) {
  const std::string& s = field(f, c, file, line_no, cols.name(c), width);
  const auto v = parseWhole(s);
  if (!v) throw InputError({file.string(), line_no, c + 1, cols.name(c)}, "not a whole number", "\"" + s + "\"", "a 64-bit integer");
  if (cols.name(c) == "frame" || cols.name(c) == "FRAME") {
    if (*v < 0) throw InputError({file.string(), line_no, c + 1, cols.name(c)}, "negative frame index", std::to_string(*v), "a frame index of 0 or more");
  }
  return *v;
}

void sortTracks(Tracks& t) {
  std::stable_sort(t.points.begin(), t.points.end(),
                   [](const TrackPoint& a, const TrackPoint& b) { return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame; });
}

ImportedTracks readTrackpy(const fs::path& file, const TrackImport& o) {
  std::ifstream in(file);
  if (!in) throw InputError({file.string(), 0, 0, {}}, "cannot open tracks file", {}, "a readable CSV file");
  // Named, not a structured binding: clang 14 (the fuzz build) cannot capture bindings in a lambda.
  const auto head = readHeader(in, file);
  const std::vector<std::string>& header = head.first;
  const int header_line = head.second;
  const Columns cols(header, file, header_line, "trackpy's linked columns x, y (pixels), frame, particle");
  const int c_x = cols.at("x"), c_y = cols.at("y"), c_frame = cols.at("frame");
  if (!cols.has("particle"))
    throw InputError({file.string(), header_line, 0, "particle"}, "trackpy features without a 'particle' column are not linked into tracks",
                     join(header, ","), "the output of trackpy.link (or link_df), which adds 'particle'");
  const int c_particle = cols.at("particle");
  if (!(o.fps > 0))
    throw InputError({file.string(), header_line, 0, "frame"}, "trackpy stores frame numbers, not times", {}, "the video's frame rate (--fps, or inputs.fps in a case)");
  if (!(o.pixel_size > 0))
    throw InputError({file.string(), header_line, 0, "x"}, "trackpy positions are in pixels and no pixel size was given", {},
                     "the camera's pixel size (--pixel-size-um, or inputs.pixel_size in a case)");
  ImportedTracks r;
  r.format = TrackFormat::trackpy;
  r.tracks.source = file.string();
  forEachRow(in, header_line, [&](const std::vector<std::string>& f, int line_no) {
    TrackPoint p;
    p.frame = whole(f, c_frame, file, line_no, cols, header.size());
    p.particle = whole(f, c_particle, file, line_no, cols, header.size());
    p.x_px = number(f, c_x, file, line_no, cols, header.size());
    p.y_px = number(f, c_y, file, line_no, cols, header.size());
    p.x = p.x_px * o.pixel_size;
    p.y = p.y_px * o.pixel_size;
    p.t = static_cast<double>(p.frame) / o.fps;
    r.tracks.points.push_back(std::move(p));
  });
  sortTracks(r.tracks);
  r.note = fmt::format("trackpy tracks: positions in pixels x {:g} um, time = frame / {:g} Hz", o.pixel_size * 1e6, o.fps);
  return r;
}

/// Metres per unit of a TrackMate length unit ("(micron)", "um", ...); 0 for pixels; NaN when unknown.
double trackmateLength(std::string unit, double pixel_size) {
  unit.erase(std::remove_if(unit.begin(), unit.end(), [](char c) { return c == '(' || c == ')' || c == ' '; }), unit.end());
  std::transform(unit.begin(), unit.end(), unit.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (unit == "micron" || unit == "microns" || unit == "um" || unit == "\xC2\xB5m" || unit == "\xCE\xBCm") return 1e-6;
  if (unit == "nm") return 1e-9;
  if (unit == "mm") return 1e-3;
  if (unit == "m") return 1.0;
  if (unit == "pixel" || unit == "pixels" || unit == "px" || unit.empty()) return pixel_size > 0 ? pixel_size : 0.0;
  return std::nan("");
}

/// Seconds per unit of a TrackMate time unit; 0 for frames or no unit; NaN when unknown.
double trackmateTime(std::string unit) {
  unit.erase(std::remove_if(unit.begin(), unit.end(), [](char c) { return c == '(' || c == ')' || c == ' '; }), unit.end());
  std::transform(unit.begin(), unit.end(), unit.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (unit == "sec" || unit == "s" || unit == "second" || unit == "seconds") return 1.0;
  if (unit == "ms" || unit == "msec") return 1e-3;
  if (unit == "min") return 60.0;
  if (unit == "h" || unit == "hour") return 3600.0;
  if (unit.empty() || unit == "frame" || unit == "frames") return 0.0;
  return std::nan("");
}

ImportedTracks readTrackmate(const fs::path& file, const TrackImport& o) {
  std::ifstream in(file);
  if (!in) throw InputError({file.string(), 0, 0, {}}, "cannot open tracks file", {}, "a readable CSV file");
  auto [header, header_line] = readHeader(in, file);
  const Columns cols(header, file, header_line, "TrackMate's spot features TRACK_ID, FRAME, POSITION_X, POSITION_Y (its 'Spots' table exported as CSV)");
  const int c_track = cols.at("TRACK_ID"), c_frame = cols.at("FRAME"), c_x = cols.at("POSITION_X"), c_y = cols.at("POSITION_Y");
  const int c_t = cols.has("POSITION_T") ? cols.at("POSITION_T") : -1;
  // TrackMate 7 writes three descriptor rows (names, short names, units) under the keys:
  // rows whose FRAME is not a number, before the first data row. The units row has "(...)".
  std::string x_unit, t_unit;
  bool units_row = false;
  std::vector<std::pair<std::vector<std::string>, int>> rows;
  bool in_data = false;
  forEachRow(in, header_line, [&](std::vector<std::string> f, int line_no) {
    if (!in_data) {
      const bool descriptor = c_frame < static_cast<int>(f.size()) && !parseWhole(f[static_cast<std::size_t>(c_frame)]);
      if (descriptor) {
        const std::string& xu = c_x < static_cast<int>(f.size()) ? f[static_cast<std::size_t>(c_x)] : std::string();
        if (!xu.empty() && xu.front() == '(') {
          units_row = true;
          x_unit = xu;
          if (c_t >= 0 && c_t < static_cast<int>(f.size())) t_unit = f[static_cast<std::size_t>(c_t)];
        }
        return;
      }
      in_data = true;
    }
    rows.emplace_back(std::move(f), line_no);
  });
  double length = trackmateLength(x_unit, o.pixel_size);
  if (std::isnan(length))
    throw InputError({file.string(), header_line, c_x + 1, "POSITION_X"}, "unknown length unit in TrackMate's units row", "\"" + x_unit + "\"",
                     "micron, um, nm, mm, m or pixel");
  if (!(length > 0))
    throw InputError({file.string(), header_line, c_x + 1, "POSITION_X"},
                     units_row ? "TrackMate positions are in pixels and no pixel size was given" : "TrackMate file without a units row: positions taken as pixels, and no pixel size was given",
                     x_unit.empty() ? std::string() : "\"" + x_unit + "\"", "the pixel size (--pixel-size-um, or inputs.pixel_size in a case)");
  double seconds = c_t >= 0 ? trackmateTime(t_unit) : 0.0;
  if (std::isnan(seconds))
    throw InputError({file.string(), header_line, c_t + 1, "POSITION_T"}, "unknown time unit in TrackMate's units row", "\"" + t_unit + "\"", "sec, ms, min, h or frame");
  const bool time_from_frames = o.fps > 0 || !(seconds > 0);
  if (time_from_frames && !(o.fps > 0))
    throw InputError({file.string(), header_line, 0, "POSITION_T"}, "TrackMate times are not in a time unit (no units row, or frames)", t_unit.empty() ? std::string() : "\"" + t_unit + "\"",
                     "the video's frame rate (--fps, or inputs.fps in a case)");

  ImportedTracks r;
  r.format = TrackFormat::trackmate;
  r.tracks.source = file.string();
  for (const auto& [f, line_no] : rows) {
    const std::string& track = field(f, c_track, file, line_no, "TRACK_ID", header.size());
    if (track.empty() || track == "None" || track == "NaN" || track == "nan") {
      ++r.skipped_spots;  // a spot outside any track
      continue;
    }
    TrackPoint p;
    p.particle = whole(f, c_track, file, line_no, cols, header.size());
    p.frame = whole(f, c_frame, file, line_no, cols, header.size());
    p.x = number(f, c_x, file, line_no, cols, header.size()) * length;
    p.y = number(f, c_y, file, line_no, cols, header.size()) * length;
    if (o.pixel_size > 0) {
      p.x_px = p.x / o.pixel_size;
      p.y_px = p.y / o.pixel_size;
    }
    p.t = time_from_frames ? static_cast<double>(p.frame) / o.fps : number(f, c_t, file, line_no, cols, header.size()) * seconds;
    r.tracks.points.push_back(std::move(p));
  }
  sortTracks(r.tracks);
  // A track that splits or merges has two spots in one frame: not a single particle's path.
  std::set<std::int64_t> branched;
  for (std::size_t i = 1; i < r.tracks.points.size(); ++i) {
    const auto &a = r.tracks.points[i - 1], &b = r.tracks.points[i];
    if (a.particle == b.particle && a.frame == b.frame) branched.insert(a.particle);
  }
  if (!branched.empty()) {
    const auto before = static_cast<std::int64_t>(r.tracks.points.size());
    std::erase_if(r.tracks.points, [&](const TrackPoint& p) { return branched.count(p.particle) > 0; });
    r.skipped_spots += before - static_cast<std::int64_t>(r.tracks.points.size());
    r.skipped_tracks = static_cast<std::int64_t>(branched.size());
  }
  r.note = fmt::format("TrackMate spots: positions in {} ({:g} um each), time {}; {} spot(s) outside tracks or in {} track(s) that split or merge left out",
                       x_unit.empty() ? "pixels" : x_unit, length * 1e6,
                       time_from_frames ? fmt::format("= FRAME / {:g} Hz", o.fps) : fmt::format("from POSITION_T in {}", t_unit), r.skipped_spots, r.skipped_tracks);
  return r;
}

}  // namespace

TrackFormat parseTrackFormat(std::string_view name) {
  if (name == "auto") return TrackFormat::automatic;
  if (name == "mmval") return TrackFormat::mmval;
  if (name == "trackpy") return TrackFormat::trackpy;
  if (name == "trackmate") return TrackFormat::trackmate;
  throw std::invalid_argument("unknown tracks format '" + std::string(name) + "' (auto, mmval, trackpy, trackmate)");
}

const char* trackFormatName(TrackFormat f) {
  switch (f) {
    case TrackFormat::automatic: return "auto";
    case TrackFormat::mmval: return "mmval";
    case TrackFormat::trackpy: return "trackpy";
    case TrackFormat::trackmate: return "trackmate";
  }
  return "?";
}

TrackFormat sniffTrackFormat(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw InputError({file.string(), 0, 0, {}}, "cannot open tracks file", {}, "a readable CSV file");
  const auto head = readHeader(in, file);
  const std::vector<std::string>& header = head.first;
  const int line_no = head.second;
  const auto has = [&](const char* name) { return std::find(header.begin(), header.end(), name) != header.end(); };
  if (has("POSITION_X")) return TrackFormat::trackmate;
  if (has("t_s") || has("x_um")) return TrackFormat::mmval;
  if (has("x") && has("y") && has("frame")) return TrackFormat::trackpy;
  throw InputError({file.string(), line_no, 0, {}}, "cannot tell which tracker wrote this file", join(header, ","),
                   "mmval's tracks (t_s, x_um, y_um), trackpy's linked DataFrame (x, y, frame, particle) or TrackMate's spots (TRACK_ID, FRAME, POSITION_X, ...)");
}

ImportedTracks readTracksAnyFormat(const fs::path& file, const TrackImport& options) {
  const TrackFormat format = options.format == TrackFormat::automatic ? sniffTrackFormat(file) : options.format;
  switch (format) {
    case TrackFormat::trackpy: return readTrackpy(file, options);
    case TrackFormat::trackmate: return readTrackmate(file, options);
    default: break;
  }
  ImportedTracks r;
  r.format = TrackFormat::mmval;
  r.tracks = readTracksCsv(file, options.pixel_size);
  r.note = "mmval tracks schema";
  return r;
}

}  // namespace mmval::compare
