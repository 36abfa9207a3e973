// The VTK XML writer (core/VtkWriter.hpp): files written, then read back both
// by the library's own reader and by a decoding written here from the format's
// definition (at the array's offset after the '_' of <AppendedData>: the UInt64
// zlib header of vtkZLibDataCompressor, then the blocks, inflated here with
// libdeflate into little-endian values), so that a mistake shared by
// writer and reader does not pass. Values are compared bit for bit: a binary
// round trip loses nothing (Float32 arrays: to the float the double rounds to).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <libdeflate.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <tuple>

#include "mmval/core/VtkWriter.hpp"

namespace fs = std::filesystem;
using namespace mmval;
using ::testing::HasSubstr;

namespace {

fs::path folder(const std::string& name) {
  const fs::path d = fs::path(MMVAL_BINARY_DIR) / "test-output" / "vtk-writer" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& f) {
  std::ifstream in(f, std::ios::binary);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

/// The opening tag of the element named `name` (a DataArray or a field-data Array).
/// `from`: where in the file to start looking.
std::string tagOf(const std::string& text, const std::string& name, std::size_t from = 0) {
  std::smatch m;
  const std::string xml = text.substr(from, text.find("<AppendedData") - from);
  EXPECT_TRUE(std::regex_search(xml, m, std::regex("<(Data)?Array [^>]*Name=\"" + name + "\"[^>]*>"))) << name;
  return m.size() ? m[0].str() : std::string();
}

/// Decodes the appended block of array `name` as doubles stored as T.
template <class T>
std::vector<T> appended(const std::string& text, const std::string& name, std::size_t from = 0) {
  const std::string tag = tagOf(text, name, from);
  std::smatch m;
  EXPECT_TRUE(std::regex_search(tag, m, std::regex("offset=\"([0-9]+)\"")));
  const std::size_t offset = std::stoull(m[1]);
  const std::size_t start = text.find('_', text.find("<AppendedData encoding=\"raw\">")) + 1 + offset;
  auto word = [&](std::size_t k) {
    std::uint64_t w = 0;
    std::memcpy(&w, text.data() + start + 8 * k, 8);
    return w;
  };
  const std::uint64_t blocks = word(0), block = word(1), partial = word(2);
  std::string bytes;
  std::size_t at = start + 8 * (3 + blocks);
  libdeflate_decompressor* inflater = libdeflate_alloc_decompressor();
  for (std::uint64_t b = 0; b < blocks; ++b) {
    const std::size_t want = b + 1 == blocks && partial != 0 ? partial : block;
    std::string out(want, '\0');
    std::size_t got = 0;
    EXPECT_EQ(libdeflate_zlib_decompress(inflater, text.data() + at, word(3 + b), out.data(), want, &got), LIBDEFLATE_SUCCESS) << name;
    EXPECT_EQ(got, want) << name;
    bytes += out;
    at += word(3 + b);
  }
  libdeflate_free_decompressor(inflater);
  std::vector<T> v(bytes.size() / sizeof(T));
  std::memcpy(v.data(), bytes.data(), bytes.size());
  return v;
}

}  // namespace

TEST(VtkWriter, RectilinearGridRoundTripsItsValuesCoordinatesUnitsAndTime) {
  const fs::path f = folder("grid") / "fields.vtr";
  vtk::RectilinearGrid g;
  g.x = {0.0, 1e-6, 2.5e-6, 4e-6};  // stretched: kept exactly
  g.y = {0.0, 2e-6, 4e-6};
  g.z = {0.0};
  std::vector<double> p, u;
  std::vector<std::uint8_t> solid;
  for (int j = 0; j < 2; ++j)
    for (int i = 0; i < 3; ++i) {
      p.push_back(1.0 / 3.0 + i - 7.25 * j);  // not exact in decimal: an ASCII writer would round it
      u.insert(u.end(), {1e-3 * i, -2e-3 * j, 0.0});
      solid.push_back(static_cast<std::uint8_t>(i == 1 && j == 1));
    }
  g.cell_data = {vtk::Array::float64("p", "Pa", 1, p), vtk::Array::float64("U", "m/s", 3, u), vtk::Array::uint8("solid", "1", solid),
                 vtk::Array::float32("p32", "Pa", 1, p)};
  vtk::writeVtr(f, g, 0.125);

  const std::string text = slurp(f);
  EXPECT_THAT(text, HasSubstr("<VTKFile type=\"RectilinearGrid\" version=\"1.0\" byte_order=\"LittleEndian\" header_type=\"UInt64\" compressor=\"vtkZLibDataCompressor\">"));
  EXPECT_THAT(text, HasSubstr("WholeExtent=\"0 3 0 2 0 0\""));
  EXPECT_THAT(tagOf(text, "U"), HasSubstr("type=\"Float64\""));
  EXPECT_THAT(tagOf(text, "U"), HasSubstr("NumberOfComponents=\"3\""));
  EXPECT_THAT(tagOf(text, "solid"), HasSubstr("type=\"UInt8\""));
  EXPECT_THAT(tagOf(text, "p32"), HasSubstr("type=\"Float32\""));
  EXPECT_EQ(text.find("format=\"ascii\""), std::string::npos);

  // Independent decoding of the appended blocks.
  EXPECT_EQ(appended<double>(text, "p"), p);
  EXPECT_EQ(appended<double>(text, "U"), u);
  EXPECT_EQ(appended<std::uint8_t>(text, "solid"), solid);
  EXPECT_EQ(appended<double>(text, "x"), g.x);
  EXPECT_EQ(appended<double>(text, "TimeValue"), std::vector<double>{0.125});
  const std::vector<float> p32 = appended<float>(text, "p32");
  ASSERT_EQ(p32.size(), p.size());
  for (std::size_t k = 0; k < p.size(); ++k) EXPECT_EQ(p32[k], static_cast<float>(p[k]));

  // The library's reader agrees.
  int comps = 0;
  EXPECT_EQ(vtk::readArray(f, "U", &comps), u);
  EXPECT_EQ(comps, 3);
  EXPECT_EQ(vtk::readArray(f, "y"), g.y);
  EXPECT_EQ(vtk::readArray(f, "solid"), std::vector<double>({0, 0, 0, 0, 1, 0}));
  EXPECT_THAT(vtk::readStrings(f, "units"), ::testing::ElementsAre("coordinates [m]", "p [Pa]", "U [m/s]", "solid [1]", "p32 [Pa]"));
  EXPECT_THROW(vtk::readArray(f, "missing"), std::runtime_error);
}

TEST(VtkWriter, PolyDataHoldsPointsVerticesPolylinesAndTheirData) {
  const fs::path f = folder("poly") / "tracks.vtp";
  vtk::PolyData d;
  d.points = {{{0, 0, 0}}, {{1e-6, 2e-6, 0}}, {{3e-6, 1e-6, 0}}, {{5e-6, 5e-6, 0}}, {{6e-6, 4e-6, 0}}};
  d.lines = {{0, 1, 2}, {3, 4}};
  d.point_data = {vtk::Array::int64("particle", "1", {7, 7, 7, 9, 9}), vtk::Array::float64("t", "s", 1, {0, 0.1, 0.2, 0.1, 0.2})};
  d.cell_data = {vtk::Array::int64("track", "1", {7, 9})};
  vtk::writeVtp(f, d);
  const std::string text = slurp(f);
  EXPECT_THAT(text, HasSubstr("NumberOfPoints=\"5\" NumberOfVerts=\"0\" NumberOfLines=\"2\""));
  EXPECT_EQ(text.find("TimeValue"), std::string::npos);  // no time given, none written
  const std::vector<double> pts = appended<double>(text, "Points");
  ASSERT_EQ(pts.size(), 15u);
  EXPECT_EQ(pts[3 * 3 + 0], 5e-6);
  EXPECT_EQ(pts[3 * 1 + 1], 2e-6);
  // Lines: connectivity 0 1 2 3 4, offsets 3 5 (one past each line's last index).
  const std::size_t lines = text.find("<Lines>");
  ASSERT_NE(lines, std::string::npos);
  EXPECT_EQ(appended<std::int64_t>(text, "connectivity"), std::vector<std::int64_t>{});  // the (empty) Verts block comes first
  EXPECT_EQ(appended<std::int64_t>(text, "connectivity", lines), std::vector<std::int64_t>({0, 1, 2, 3, 4}));
  EXPECT_EQ(appended<std::int64_t>(text, "offsets", lines), std::vector<std::int64_t>({3, 5}));
  EXPECT_EQ(vtk::readArray(f, "particle"), std::vector<double>({7, 7, 7, 9, 9}));
  EXPECT_EQ(vtk::readArray(f, "track"), std::vector<double>({7, 9}));

  // Vertices: one per point, listed before the lines.
  d.vertex_per_point = true;
  d.cell_data = {vtk::Array::int64("track", "1", {-1, -1, -1, -1, -1, 7, 9})};
  vtk::writeVtp(f, d, 2.0);
  const std::string text2 = slurp(f);
  EXPECT_THAT(text2, HasSubstr("NumberOfVerts=\"5\" NumberOfLines=\"2\""));
  EXPECT_EQ(appended<std::int64_t>(text2, "connectivity"), std::vector<std::int64_t>({0, 1, 2, 3, 4}));
  EXPECT_EQ(appended<std::int64_t>(text2, "offsets"), std::vector<std::int64_t>({1, 2, 3, 4, 5}));
  EXPECT_EQ(vtk::readArray(f, "TimeValue"), std::vector<double>{2.0});

  // A point and a cell array of one name and unit are listed once in the units.
  d.cell_data = {vtk::Array::int64("particle", "1", {7, 7, 7, 9, 9, 7, 9})};
  vtk::writeVtp(f, d);
  EXPECT_THAT(vtk::readStrings(f, "units"), ::testing::ElementsAre("coordinates [m]", "particle [1]", "t [s]"));
}

TEST(VtkWriter, SizesThatDisagreeAreRefused) {
  const fs::path f = folder("bad") / "bad.vtr";
  vtk::RectilinearGrid g;
  g.x = {0, 1, 2};
  g.y = {0, 1};
  g.z = {0};
  g.cell_data = {vtk::Array::float64("p", "Pa", 1, {1, 2, 3})};  // 2 cells
  EXPECT_THROW(vtk::writeVtr(f, g), std::invalid_argument);
  EXPECT_FALSE(fs::exists(f));
  vtk::PolyData d;
  d.points = {{{0, 0, 0}}};
  d.lines = {{0, 1}};
  EXPECT_THROW(vtk::writeVtp(folder("bad") / "bad.vtp", d), std::invalid_argument);
}

TEST(VtkWriter, CollectionListsEachStepWithItsTime) {
  const fs::path f = folder("pvd") / "fields.pvd";
  vtk::writePvd(f, {{0.0, "fields/fields-0000.vtr"}, {0.5, "fields/fields-0001.vtr"}});
  const std::string text = slurp(f);
  EXPECT_THAT(text, HasSubstr("<VTKFile type=\"Collection\""));
  EXPECT_THAT(text, HasSubstr("<DataSet timestep=\"0\" group=\"\" part=\"0\" file=\"fields/fields-0000.vtr\"/>"));
  EXPECT_THAT(text, HasSubstr("<DataSet timestep=\"0.5\" group=\"\" part=\"0\" file=\"fields/fields-0001.vtr\"/>"));
}

TEST(VtkWriter, ParticleSeriesWritesOneSnapshotPerFrameWithItsTime) {
  const fs::path dir = folder("series");
  Tracks tr;
  // Particle 1 in frames 0-2, particle 2 in frames 1-2 (deposited in frame 2).
  for (const auto& [frame, id, x, state] : std::vector<std::tuple<int, int, double, std::string>>{
           {0, 1, 1e-6, "mobile"}, {1, 1, 2e-6, "mobile"}, {2, 1, 3e-6, "mobile"}, {1, 2, 5e-6, "mobile"}, {2, 2, 5e-6, "deposited"}}) {
    TrackPoint q;
    q.frame = frame;
    q.particle = id;
    q.t = 0.25 * frame;
    q.x = x;
    q.y = 1e-6 * id;
    q.state = state;
    tr.points.push_back(q);
  }
  const auto files = vtk::writeParticleSeries(dir, "particles", tr, [](const TrackPoint& q) { return std::array<double, 3>{q.x, q.y, 0.0}; });
  EXPECT_THAT(files, ::testing::ElementsAre("particles/particles-00000.vtp", "particles/particles-00001.vtp", "particles/particles-00002.vtp",
                                            "particles.pvd"));
  const fs::path last = dir / "particles" / "particles-00002.vtp";
  EXPECT_EQ(vtk::readArray(last, "TimeValue"), std::vector<double>{0.5});
  EXPECT_EQ(vtk::readArray(last, "particle"), std::vector<double>({1, 2}));
  EXPECT_EQ(vtk::readArray(last, "deposited"), std::vector<double>({0, 1}));
  EXPECT_EQ(vtk::readArray(last, "Points"), std::vector<double>({3e-6, 1e-6, 0, 5e-6, 2e-6, 0}));
  EXPECT_THROW(vtk::readArray(last, "z"), std::runtime_error);  // no z in the points: none written
  const std::string pvd = slurp(dir / "particles.pvd");
  EXPECT_THAT(pvd, HasSubstr("timestep=\"0.25\" group=\"\" part=\"0\" file=\"particles/particles-00001.vtp\""));

  // A cap of 2 frames keeps the first and the last.
  const auto capped = vtk::writeParticleSeries(folder("series-capped"), "particles", tr,
                                               [](const TrackPoint& q) { return std::array<double, 3>{q.x, q.y, 0.0}; }, 2);
  EXPECT_THAT(capped, ::testing::ElementsAre("particles/particles-00000.vtp", "particles/particles-00002.vtp", "particles.pvd"));
}

// An array larger than one zlib block (32768 bytes) and not a whole number of
// blocks: 5 full blocks and a partial one, read back bit for bit by both
// decoders; a grain mask (long runs of one value, as every solid array is)
// shrinks at least tenfold (zlib stores a run in a few bytes per 258 repeats).
TEST(VtkWriter, LargeArraysSpanSeveralZlibBlocksAndMasksCompress) {
  const fs::path f = folder("blocks") / "big.vtr";
  const int nx = 300, ny = 70;  // 21000 cells: 168000 bytes of Float64 = 5 blocks + 4160 bytes
  vtk::RectilinearGrid g;
  for (int i = 0; i <= nx; ++i) g.x.push_back(1e-6 * i);
  for (int j = 0; j <= ny; ++j) g.y.push_back(1e-6 * j);
  g.z = {0.0};
  std::vector<double> p;
  std::vector<std::uint8_t> solid;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      p.push_back(std::sin(0.01 * i) * std::exp(-0.003 * j * i) + 1e-9 * (i * 7919 % 104729));  // no structure zlib can exploit in the low bits
      solid.push_back(static_cast<std::uint8_t>((i / 25 + j / 20) % 2));
    }
  g.cell_data = {vtk::Array::float64("p", "Pa", 1, p), vtk::Array::uint8("solid", "1", solid)};
  vtk::writeVtr(f, g);
  const std::string text = slurp(f);
  EXPECT_EQ(appended<double>(text, "p"), p);
  EXPECT_EQ(vtk::readArray(f, "p"), p);
  EXPECT_EQ(appended<std::uint8_t>(text, "solid"), solid);

  vtk::RectilinearGrid mask = g;  // 300 x 700 cells: the mask's bytes outweigh the coordinates' 8 KB
  mask.y.clear();
  std::vector<std::uint8_t> grains;
  for (int j = 0; j <= 10 * ny; ++j) mask.y.push_back(1e-6 * j);
  for (int j = 0; j < 10 * ny; ++j)
    for (int i = 0; i < nx; ++i) grains.push_back(static_cast<std::uint8_t>((i / 25 + j / 20) % 2));
  mask.cell_data = {vtk::Array::uint8("solid", "1", grains)};
  vtk::writeVtr(f, mask);
  EXPECT_LT(fs::file_size(f), grains.size() / 10) << "a 210000-cell mask in " << fs::file_size(f) << " bytes";
  EXPECT_EQ(vtk::readArray(f, "solid").size(), grains.size());
}
