#include "mmval/core/VtkWriter.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <regex>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>
#include <libdeflate.h>

#include "mmval/core/AtomicFile.hpp"

namespace mmval::vtk {

static_assert(std::endian::native == std::endian::little, "the VTK writer stores values as they are in memory: little-endian");

namespace {

std::size_t typeSize(Type t) {
  switch (t) {
    case Type::Float64:
    case Type::Int64:
      return 8;
    case Type::Float32:
      return 4;
    case Type::UInt8:
      return 1;
  }
  return 1;
}

template <class T>
std::string rawBytes(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

/// Uncompressed bytes per zlib block: VTK's own writers' default block size.
constexpr std::size_t kBlockBytes = 32768;
/// libdeflate level 4: within ~5 % of level 6's size on mmval's fields at about
/// half its time (levels run 1..12).
constexpr int kCompressionLevel = 4;

/// `bytes` as VTK's vtkZLibDataCompressor stores an appended block with
/// header_type UInt64: the header [number of blocks, block size, size of a
/// partial last block (0 when the last block is full), compressed size of each
/// block], then the zlib streams one after another.
std::string zlibBlocks(const std::string& bytes) {
  struct Free {
    void operator()(libdeflate_compressor* c) const { libdeflate_free_compressor(c); }
  };
  static thread_local std::unique_ptr<libdeflate_compressor, Free> compressor(libdeflate_alloc_compressor(kCompressionLevel));
  if (!compressor) throw std::runtime_error("VTK writer: cannot allocate a zlib compressor");
  const std::size_t blocks = (bytes.size() + kBlockBytes - 1) / kBlockBytes;
  std::vector<std::uint64_t> header{blocks, kBlockBytes, bytes.size() % kBlockBytes};
  std::string streams, buffer(libdeflate_zlib_compress_bound(compressor.get(), kBlockBytes), '\0');
  for (std::size_t b = 0; b < blocks; ++b) {
    const std::size_t begin = b * kBlockBytes, n = std::min(kBlockBytes, bytes.size() - begin);
    const std::size_t m = libdeflate_zlib_compress(compressor.get(), bytes.data() + begin, n, buffer.data(), buffer.size());
    if (m == 0) throw std::runtime_error("VTK writer: zlib compression failed");
    header.push_back(m);
    streams.append(buffer.data(), m);
  }
  return std::string(reinterpret_cast<const char*>(header.data()), header.size() * sizeof(std::uint64_t)) + streams;
}

std::string xmlEscape(const std::string& s) {
  std::string out;
  for (char c : s) {
    if (c == '&') out += "&amp;";
    else if (c == '<') out += "&lt;";
    else if (c == '>') out += "&gt;";
    else if (c == '"') out += "&quot;";
    else out += c;
  }
  return out;
}

/// The XML text and the appended blocks of one file, built together so that
/// every offset is the position of its block after the '_' marker.
class Document {
 public:
  explicit Document(const std::string& type) : m_type(type) {}
  std::string& xml() { return m_xml; }

  /// A <DataArray> whose values go to the appended block.
  void array(const std::string& name, Type type, int components, const std::string& bytes, const std::string& extra = "") {
    m_xml += fmt::format("<DataArray type=\"{}\"{}{} format=\"appended\" offset=\"{}\"{}/>\n", typeName(type),
                         name.empty() ? std::string() : " Name=\"" + xmlEscape(name) + "\"",
                         components != 1 ? fmt::format(" NumberOfComponents=\"{}\"", components) : std::string(), m_appended.size(), extra);
    block(bytes);
  }
  void array(const Array& a) {
    if (a.bytes.size() % (typeSize(a.type) * static_cast<std::size_t>(a.components)) != 0)
      throw std::invalid_argument("VTK array " + a.name + ": byte count is not a whole number of tuples");
    array(a.name, a.type, a.components, a.bytes);
  }
  /// Field data: TimeValue (when finite) and the units of every array.
  void fieldData(double time_s, const std::vector<const Array*>& arrays) {
    m_xml += "<FieldData>\n";
    if (std::isfinite(time_s)) array("TimeValue", Type::Float64, 1, rawBytes(std::vector<double>{time_s}), " NumberOfTuples=\"1\"");
    std::vector<std::string> units{"coordinates [m]"};
    for (const Array* a : arrays) {
      const std::string entry = a->name + " [" + a->unit + "]";
      if (std::find(units.begin(), units.end(), entry) == units.end()) units.push_back(entry);  // point and cell arrays may share a name
    }
    // A String array: the strings one after another, each ended by a NUL byte.
    std::string bytes;
    for (const auto& u : units) bytes += u + '\0';
    m_xml += fmt::format("<Array type=\"String\" Name=\"units\" NumberOfTuples=\"{}\" format=\"appended\" offset=\"{}\"/>\n", units.size(),
                         m_appended.size());
    block(bytes);
    m_xml += "</FieldData>\n";
  }
  void write(const std::filesystem::path& file) {
    std::string out = "<?xml version=\"1.0\"?>\n<VTKFile type=\"" + m_type +
                      "\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">\n";
    out += m_xml;
    out += "<AppendedData encoding=\"raw\">\n_";
    out += m_appended;
    out += "\n</AppendedData>\n</VTKFile>\n";
    writeFileAtomic(file, out);
  }

 private:
  void block(const std::string& bytes) { m_appended += zlibBlocks(bytes); }
  std::string m_type, m_xml, m_appended;
};

void checkTuples(const std::vector<Array>& arrays, std::size_t n, const char* what) {
  for (const auto& a : arrays)
    if (a.tuples() != n) throw std::invalid_argument(fmt::format("VTK {} array {} has {} tuples, the dataset {}", what, a.name, a.tuples(), n));
}

std::vector<const Array*> all(const std::vector<Array>& a, const std::vector<Array>& b) {
  std::vector<const Array*> out;
  for (const auto& x : a) out.push_back(&x);
  for (const auto& x : b) out.push_back(&x);
  return out;
}

/// Connectivity and offsets of cells given as index lists.
void cells(Document& d, const char* tag, const std::vector<std::vector<std::int64_t>>& lists) {
  std::vector<std::int64_t> conn, offsets;
  for (const auto& l : lists) {
    conn.insert(conn.end(), l.begin(), l.end());
    offsets.push_back(static_cast<std::int64_t>(conn.size()));
  }
  d.xml() += fmt::format("<{}>\n", tag);
  d.array("connectivity", Type::Int64, 1, rawBytes(conn));
  d.array("offsets", Type::Int64, 1, rawBytes(offsets));
  d.xml() += fmt::format("</{}>\n", tag);
}

}  // namespace

const char* typeName(Type t) {
  switch (t) {
    case Type::Float64:
      return "Float64";
    case Type::Float32:
      return "Float32";
    case Type::UInt8:
      return "UInt8";
    case Type::Int64:
      return "Int64";
  }
  return "";
}

std::size_t Array::tuples() const { return bytes.size() / (typeSize(type) * static_cast<std::size_t>(std::max(components, 1))); }

Array Array::float64(std::string name, std::string unit, int components, const std::vector<double>& values) {
  return {std::move(name), std::move(unit), components, Type::Float64, rawBytes(values)};
}

Array Array::float32(std::string name, std::string unit, int components, const std::vector<double>& values) {
  std::vector<float> f(values.begin(), values.end());
  return {std::move(name), std::move(unit), components, Type::Float32, rawBytes(f)};
}

Array Array::uint8(std::string name, std::string unit, const std::vector<std::uint8_t>& values) {
  return {std::move(name), std::move(unit), 1, Type::UInt8, rawBytes(values)};
}

Array Array::int64(std::string name, std::string unit, const std::vector<std::int64_t>& values) {
  return {std::move(name), std::move(unit), 1, Type::Int64, rawBytes(values)};
}

int RectilinearGrid::cells() const {
  auto n = [](const std::vector<double>& a) { return std::max<int>(1, static_cast<int>(a.size()) - 1); };
  return n(x) * n(y) * n(z);
}

void writeVtr(const std::filesystem::path& file, const RectilinearGrid& g, double time_s) {
  if (g.x.empty() || g.y.empty() || g.z.empty()) throw std::invalid_argument("VTK grid: every axis needs at least one coordinate");
  checkTuples(g.cell_data, static_cast<std::size_t>(g.cells()), "cell");
  checkTuples(g.point_data, g.x.size() * g.y.size() * g.z.size(), "point");
  const std::string extent = fmt::format("0 {} 0 {} 0 {}", g.x.size() - 1, g.y.size() - 1, g.z.size() - 1);
  Document d("RectilinearGrid");
  d.xml() += "<RectilinearGrid WholeExtent=\"" + extent + "\">\n";
  d.fieldData(time_s, all(g.cell_data, g.point_data));
  d.xml() += "<Piece Extent=\"" + extent + "\">\n<PointData>\n";
  for (const auto& a : g.point_data) d.array(a);
  d.xml() += "</PointData>\n<CellData>\n";
  for (const auto& a : g.cell_data) d.array(a);
  d.xml() += "</CellData>\n<Coordinates>\n";
  d.array("x", Type::Float64, 1, rawBytes(g.x));
  d.array("y", Type::Float64, 1, rawBytes(g.y));
  d.array("z", Type::Float64, 1, rawBytes(g.z));
  d.xml() += "</Coordinates>\n</Piece>\n</RectilinearGrid>\n";
  d.write(file);
}

void writeVtp(const std::filesystem::path& file, const PolyData& p, double time_s) {
  const std::size_t n = p.points.size();
  const std::size_t verts = p.vertex_per_point ? n : 0;
  checkTuples(p.point_data, n, "point");
  checkTuples(p.cell_data, verts + p.lines.size(), "cell");
  for (const auto& l : p.lines)
    for (std::int64_t k : l)
      if (k < 0 || static_cast<std::size_t>(k) >= n) throw std::invalid_argument(fmt::format("VTK polyline index {} outside 0..{}", k, n));
  Document d("PolyData");
  d.xml() += "<PolyData>\n";
  d.fieldData(time_s, all(p.point_data, p.cell_data));
  d.xml() += fmt::format("<Piece NumberOfPoints=\"{}\" NumberOfVerts=\"{}\" NumberOfLines=\"{}\" NumberOfStrips=\"0\" NumberOfPolys=\"0\">\n<PointData>\n",
                         n, verts, p.lines.size());
  for (const auto& a : p.point_data) d.array(a);
  d.xml() += "</PointData>\n<CellData>\n";
  for (const auto& a : p.cell_data) d.array(a);
  d.xml() += "</CellData>\n<Points>\n";
  std::vector<double> xyz;
  xyz.reserve(3 * n);
  for (const auto& q : p.points) xyz.insert(xyz.end(), q.begin(), q.end());
  d.array("Points", Type::Float64, 3, rawBytes(xyz));
  d.xml() += "</Points>\n";
  std::vector<std::vector<std::int64_t>> vlist;
  for (std::size_t k = 0; k < verts; ++k) vlist.push_back({static_cast<std::int64_t>(k)});
  cells(d, "Verts", vlist);
  cells(d, "Lines", p.lines);
  d.xml() += "</Piece>\n</PolyData>\n";
  d.write(file);
}

void writePvd(const std::filesystem::path& file, const std::vector<PvdEntry>& entries) {
  std::string out = "<?xml version=\"1.0\"?>\n<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n<Collection>\n";
  for (const auto& e : entries)
    out += fmt::format("<DataSet timestep=\"{:.17g}\" group=\"\" part=\"0\" file=\"{}\"/>\n", e.time_s, xmlEscape(e.file.generic_string()));
  out += "</Collection>\n</VTKFile>\n";
  writeFileAtomic(file, out);
}

std::vector<std::string> writeParticleSeries(const std::filesystem::path& dir, const std::string& stem, const Tracks& tracks,
                                             const std::function<std::array<double, 3>(const TrackPoint&)>& position, int max_frames) {
  std::map<std::int64_t, std::vector<const TrackPoint*>> frames;
  for (const auto& q : tracks.points) frames[q.frame].push_back(&q);
  std::vector<std::string> files;
  if (frames.empty()) return files;
  const std::size_t stride = (frames.size() + static_cast<std::size_t>(std::max(max_frames, 1)) - 1) / static_cast<std::size_t>(std::max(max_frames, 1));
  std::vector<PvdEntry> entries;
  std::size_t k = 0;
  for (const auto& [frame, pts] : frames) {
    const bool last = k + 1 == frames.size();
    if (k++ % stride != 0 && !last) continue;
    PolyData d;
    d.vertex_per_point = true;
    std::vector<std::int64_t> id;
    std::vector<std::uint8_t> deposited;
    std::vector<double> z;
    bool has_z = true;
    for (const TrackPoint* q : pts) {
      d.points.push_back(position(*q));
      id.push_back(q->particle);
      deposited.push_back(q->state == "deposited" ? 1 : 0);
      z.push_back(q->z);
      has_z = has_z && std::isfinite(q->z);
    }
    d.point_data = {Array::int64("particle", "1", id), Array::uint8("deposited", "1", deposited)};
    if (has_z) d.point_data.push_back(Array::float64("z", "m", 1, z));
    const std::string name = fmt::format("{}/{}-{:05d}.vtp", stem, stem, frame);
    writeVtp(dir / name, d, pts.front()->t);
    entries.push_back({pts.front()->t, name});
    files.push_back(name);
  }
  writePvd(dir / (stem + ".pvd"), entries);
  files.push_back(stem + ".pvd");
  return files;
}

namespace {

struct Located {
  std::string text;
  std::string tag;          ///< the opening tag of the array
  std::size_t body = 0;     ///< first character after the tag
  std::string format;
  std::size_t offset = 0;
  std::size_t appended = 0;  ///< first byte after the '_' marker
  bool zlib = false;         ///< blocks compressed by vtkZLibDataCompressor
};

std::string attribute(const std::string& tag, const std::string& key) {
  std::smatch m;
  if (std::regex_search(tag, m, std::regex("\\s" + key + "=\"([^\"]*)\""))) return m[1];
  return {};
}

std::string readBinary(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + file.string());
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

Located locate(const std::filesystem::path& file, const std::string& name) {
  Located l;
  l.text = readBinary(file);
  const std::size_t end_of_xml = std::min(l.text.find("<AppendedData"), l.text.size());
  const std::string needle = "Name=\"" + name + "\"";
  std::size_t at = 0;
  for (;;) {
    at = l.text.find(needle, at);
    if (at == std::string::npos || at > end_of_xml) throw std::runtime_error(file.string() + ": no array named " + name);
    const std::size_t open = l.text.rfind('<', at);
    const std::string element = l.text.substr(open, l.text.find_first_of(" >", open) - open);
    if (element == "<DataArray" || element == "<Array") break;
    at += needle.size();
  }
  const std::size_t open = l.text.rfind('<', at);
  l.body = l.text.find('>', at) + 1;
  l.tag = l.text.substr(open, l.body - open);
  l.format = attribute(l.tag, "format");
  if (l.format == "appended") {
    const std::string off = attribute(l.tag, "offset");
    l.offset = static_cast<std::size_t>(std::stoull(off.empty() ? "0" : off));
    const std::size_t data = l.text.find("<AppendedData");
    const std::size_t marker = data == std::string::npos ? std::string::npos : l.text.find('_', data);
    if (marker == std::string::npos) throw std::runtime_error(file.string() + ": appended array " + name + " without <AppendedData>");
    if (attribute(l.text.substr(data, marker - data), "encoding") != "raw") throw std::runtime_error(file.string() + ": appended data is not raw");
    l.appended = marker + 1;
    const std::size_t file_tag = l.text.find("<VTKFile");
    if (file_tag != std::string::npos) {
      const std::string compressor = attribute(l.text.substr(file_tag, l.text.find('>', file_tag) - file_tag), "compressor");
      if (!compressor.empty() && compressor != "vtkZLibDataCompressor")
        throw std::runtime_error(file.string() + ": compressor " + compressor + " (expected none or vtkZLibDataCompressor)");
      l.zlib = !compressor.empty();
    }
  } else if (l.format != "ascii") {
    throw std::runtime_error(file.string() + ": array " + name + " is in format \"" + l.format + "\" (expected appended raw or ascii)");
  }
  return l;
}

/// The UInt64 at `at` of the file's text.
std::uint64_t word(const Located& l, std::size_t at, const std::filesystem::path& file) {
  std::uint64_t n = 0;
  if (at + sizeof n > l.text.size()) throw std::runtime_error(file.string() + ": appended block beyond the end of the file");
  std::memcpy(&n, l.text.data() + at, sizeof n);
  return n;
}

/// The values of an appended block: after its UInt64 byte count (raw), or
/// inflated from its zlib blocks (header as zlibBlocks writes it).
std::string appendedBlock(const Located& l, const std::filesystem::path& file) {
  const std::size_t start = l.appended + l.offset;
  if (!l.zlib) {
    const std::uint64_t n = word(l, start, file);
    if (start + sizeof n + n > l.text.size()) throw std::runtime_error(file.string() + ": appended block longer than the file");
    return l.text.substr(start + sizeof n, n);
  }
  const std::uint64_t blocks = word(l, start, file), block = word(l, start + 8, file), last = word(l, start + 16, file);
  if (blocks > l.text.size() / 8) throw std::runtime_error(file.string() + ": zlib header claims more blocks than the file holds");
  struct Free {
    void operator()(libdeflate_decompressor* d) const { libdeflate_free_decompressor(d); }
  };
  std::unique_ptr<libdeflate_decompressor, Free> inflater(libdeflate_alloc_decompressor());
  std::string out;
  std::size_t at = start + 24 + 8 * blocks;
  for (std::uint64_t b = 0; b < blocks; ++b) {
    const std::uint64_t size = word(l, start + 24 + 8 * b, file);
    const std::uint64_t expect = b + 1 == blocks && last != 0 ? last : block;
    if (at + size > l.text.size() || expect > (std::uint64_t{1} << 31)) throw std::runtime_error(file.string() + ": zlib block beyond the end of the file");
    const std::size_t before = out.size();
    out.resize(before + expect);
    std::size_t got = 0;
    if (libdeflate_zlib_decompress(inflater.get(), l.text.data() + at, size, out.data() + before, expect, &got) != LIBDEFLATE_SUCCESS || got != expect)
      throw std::runtime_error(file.string() + ": a zlib block does not inflate to its stated size");
    at += size;
  }
  return out;
}

template <class T>
void decode(const std::string& bytes, std::vector<double>& out) {
  const std::size_t n = bytes.size() / sizeof(T);
  for (std::size_t k = 0; k < n; ++k) {
    T v;
    std::memcpy(&v, bytes.data() + k * sizeof(T), sizeof(T));
    out.push_back(static_cast<double>(v));
  }
}

}  // namespace

std::vector<double> readArray(const std::filesystem::path& file, const std::string& name, int* components) {
  const Located l = locate(file, name);
  const std::string type = attribute(l.tag, "type");
  const std::string comps = attribute(l.tag, "NumberOfComponents");
  if (components != nullptr) *components = comps.empty() ? 1 : std::stoi(comps);
  std::vector<double> out;
  if (l.format == "ascii") {
    std::istringstream in(l.text.substr(l.body, l.text.find("</", l.body) - l.body));
    double x = 0;
    while (in >> x) out.push_back(x);
    return out;
  }
  const std::string bytes = appendedBlock(l, file);
  if (type == "Float64") decode<double>(bytes, out);
  else if (type == "Float32") decode<float>(bytes, out);
  else if (type == "UInt8") decode<std::uint8_t>(bytes, out);
  else if (type == "Int64") decode<std::int64_t>(bytes, out);
  else throw std::runtime_error(file.string() + ": array " + name + " has type " + type + " (expected Float64, Float32, UInt8 or Int64)");
  return out;
}

std::vector<std::string> readStrings(const std::filesystem::path& file, const std::string& name) {
  const Located l = locate(file, name);
  if (attribute(l.tag, "type") != "String" || l.format != "appended")
    throw std::runtime_error(file.string() + ": " + name + " is not an appended String array");
  const std::string bytes = appendedBlock(l, file);
  std::vector<std::string> out;
  std::size_t start = 0;
  for (std::size_t k = 0; k < bytes.size(); ++k)
    if (bytes[k] == '\0') {
      out.push_back(bytes.substr(start, k - start));
      start = k + 1;
    }
  return out;
}

}  // namespace mmval::vtk
