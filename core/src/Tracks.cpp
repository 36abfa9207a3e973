#include "mmval/core/Tracks.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <fstream>
#include <map>
#include <optional>
#include <sstream>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/Strings.hpp"

namespace mmval {

namespace {

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == ',') {
      out.push_back(cur);
      cur.clear();
    } else if (c != '\r' && c != '"') {
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

/// A whole number read exactly: particle ids and frame indices are 64-bit
/// integers, and read through a double, ids at or above 2^53 would merge.
/// "12.0" is accepted, as pandas writes an integer column holding a missing value.
std::optional<std::int64_t> parseInteger(const std::string& text) {
  std::int64_t v = 0;
  const char* end = text.data() + text.size();
  const auto [ptr, ec] = std::from_chars(text.data(), end, v);
  if (ec != std::errc() || ptr == text.data()) return std::nullopt;
  if (ptr != end && (*ptr != '.' || std::any_of(ptr + 1, end, [](char c) { return c != '0'; }))) return std::nullopt;
  return v;
}

/// The quality columns in file order, with the member each fills.
struct QualityColumn {
  const char* name;
  double SpotQuality::*member;
};
constexpr QualityColumn kQualityColumns[] = {{"sigma_px", &SpotQuality::sigma_px}, {"eccentricity", &SpotQuality::eccentricity},
                                             {"signal", &SpotQuality::signal},     {"mass", &SpotQuality::mass},
                                             {"background", &SpotQuality::background}, {"ep_px", &SpotQuality::ep_px}};

}  // namespace

Tracks readTracksCsv(const std::filesystem::path& file, double pixel_size) {
  std::ifstream in(file);
  if (!in) throw InputError({file.string(), 0, 0, {}}, "cannot open tracks file", {}, "a readable CSV file");
  Tracks tracks;
  tracks.source = file.string();
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (!line.empty() && line[0] != '#') break;
  }
  const auto header = splitCsv(line);
  std::map<std::string, int> col;
  for (std::size_t i = 0; i < header.size(); ++i) col[header[i]] = static_cast<int>(i);
  auto need = [&](const std::string& name) {
    if (col.count(name) == 0) {
      const std::string near = nearest(name, header);
      throw InputError({file.string(), line_no, 0, name}, "missing column" + (near.empty() ? std::string() : "; found '" + near + "'"),
                       join(header, ","), "columns frame, particle, t_s, x_um, y_um (or x_px, y_px with a pixel size)");
    }
    return col[name];
  };
  const int c_frame = need("frame"), c_particle = need("particle"), c_t = need("t_s");
  // trackpy's x, y (pixels) are synonyms of x_px, y_px.
  if (!col.count("x_px") && col.count("x")) col["x_px"] = col["x"];
  if (!col.count("y_px") && col.count("y")) col["y_px"] = col["y"];
  const bool have_um = col.count("x_um") && col.count("y_um");
  const bool have_px = col.count("x_px") && col.count("y_px");
  if (!have_um && !(have_px && pixel_size > 0)) {
    if (have_px) throw InputError({file.string(), line_no, 0, "x_um"}, "positions only in pixels and no pixel size given", {}, "x_um, y_um columns or a pixel size");
    need("x_um");
    need("y_um");
  }
  const int c_x = have_um ? col["x_um"] : col["x_px"], c_y = have_um ? col["y_um"] : col["y_px"];
  const int c_state = col.count("state") ? col["state"] : -1;
  const double scale = have_um ? 1e-6 : pixel_size;
  const int c_z = col.count("z_um") ? col["z_um"] : -1;
  const int c_xp = have_px ? col["x_px"] : -1, c_yp = have_px ? col["y_px"] : -1;
  std::vector<std::pair<int, double SpotQuality::*>> c_quality;
  for (const auto& q : kQualityColumns)
    if (col.count(q.name)) c_quality.emplace_back(col[q.name], q.member);
  auto number = [&](const std::vector<std::string>& f, int c, const std::string& name) {
    if (c >= static_cast<int>(f.size())) throw InputError({file.string(), line_no, 0, name}, "row has too few fields", std::to_string(f.size()), std::to_string(header.size()) + " fields");
    try {
      std::size_t used = 0;
      const double v = std::stod(f[c], &used);
      if (used != f[c].size() || !std::isfinite(v)) throw std::invalid_argument("x");
      return v;
    } catch (const std::exception&) {
      throw InputError({file.string(), line_no, c + 1, name}, "not a finite number", "\"" + f[c] + "\"", "a number");
    }
  };
  auto integer = [&](const std::vector<std::string>& f, int c, const std::string& name) {
    if (c >= static_cast<int>(f.size())) throw InputError({file.string(), line_no, 0, name}, "row has too few fields", std::to_string(f.size()), std::to_string(header.size()) + " fields");
    const auto v = parseInteger(f[c]);
    if (!v) throw InputError({file.string(), line_no, c + 1, name}, "not a whole number", "\"" + f[c] + "\"", "a 64-bit integer");
    return *v;
  };
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    const auto f = splitCsv(line);
    TrackPoint p;
    p.frame = integer(f, c_frame, "frame");
    if (p.frame < 0) throw InputError({file.string(), line_no, c_frame + 1, "frame"}, "negative frame index", std::to_string(p.frame), "a frame index of 0 or more");
    p.particle = integer(f, c_particle, "particle");
    p.t = number(f, c_t, "t_s");
    p.x = number(f, c_x, header[c_x]) * scale;
    p.y = number(f, c_y, header[c_y]) * scale;
    if (c_z >= 0) p.z = number(f, c_z, "z_um") * 1e-6;
    if (c_xp >= 0) {
      p.x_px = number(f, c_xp, "x_px");
      p.y_px = number(f, c_yp, "y_px");
    }
    if (c_state >= 0 && c_state < static_cast<int>(f.size())) p.state = f[c_state];
    // A quality field may be empty (a point without a measured spot), as the writer
    // leaves it and pandas writes NaN.
    for (const auto& [c, member] : c_quality)
      if (c < static_cast<int>(f.size()) && !f[c].empty() && f[c] != "nan" && f[c] != "NaN") p.quality.*member = number(f, c, header[c]);
    tracks.points.push_back(p);
  }
  std::stable_sort(tracks.points.begin(), tracks.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  return tracks;
}

void writeTracksCsv(const std::filesystem::path& file, const Tracks& tracks, double pixel_size) {
  bool px = pixel_size > 0, z = false, state = false, quality = false;
  for (const auto& p : tracks.points) {
    px = px || std::isfinite(p.x_px);
    z = z || std::isfinite(p.z);
    state = state || !p.state.empty();
    quality = quality || p.quality.measured();
  }
  std::string out = std::string("frame,particle") + (px ? ",x,y" : "") + ",x_um,y_um,t_s" + (z ? ",z_um" : "");
  if (quality)
    for (const auto& q : kQualityColumns) out += std::string(",") + q.name;
  out += std::string(state ? ",state" : "") + "\n";
  for (const auto& p : tracks.points) {
    out += fmt::format("{},{}", p.frame, p.particle);
    if (px) {
      const double xp = std::isfinite(p.x_px) ? p.x_px : p.x / pixel_size;
      const double yp = std::isfinite(p.y_px) ? p.y_px : p.y / pixel_size;
      out += fmt::format(",{:.4f},{:.4f}", xp, yp);
    }
    out += fmt::format(",{:.5f},{:.5f},{:.9g}", p.x * 1e6, p.y * 1e6, p.t);
    if (z) out += fmt::format(",{:.5f}", std::isfinite(p.z) ? p.z * 1e6 : 0.0);
    if (quality)
      for (const auto& q : kQualityColumns) {
        const double v = p.quality.*q.member;
        out += std::isfinite(v) ? fmt::format(",{:.5g}", v) : std::string(",");
      }
    if (state) out += "," + (p.state.empty() ? std::string("mobile") : p.state);
    out += "\n";
  }
  writeFileAtomic(file, out);
}

}  // namespace mmval
