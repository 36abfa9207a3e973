// VTK XML output shared by every kind (docs/outputs.md states the frame and
// lists the files): rectilinear grids (.vtr) for fields, poly data (.vtp) for
// particles and tracks, and .pvd collections for time series.
//
// Format (VTK's "VTK File Formats" document, XML section): binary appended raw
// data (<AppendedData encoding="raw">), little-endian values compressed with
// zlib as VTK's vtkZLibDataCompressor stores them (compressor attribute on
// <VTKFile>, header_type="UInt64": a header of block count, block size,
// partial last-block size and each block's compressed size, then the zlib
// streams; libdeflate compresses). Every file carries field data:
//   TimeValue  Float64, one tuple: the time of the dataset, s (the array name
//              VTK's own writers use for a dataset's time)
//   units      String, one tuple per array: "<array name> [<unit>]", plus
//              "coordinates [m]" (ParaView lists it under Field Data in the
//              Information panel and the Spreadsheet view)
// Array names stay plain ("U", "p", "solid") so that readers find them by name.
//
// Every file is written atomically (AtomicFile.hpp). Throws std::runtime_error
// on an I/O failure and std::invalid_argument when sizes disagree.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "mmval/core/Tracks.hpp"

namespace mmval::vtk {

enum class Type { Float64, Float32, UInt8, Int64 };

/// VTK's name of a type ("Float64", ...).
const char* typeName(Type t);

/// One data array: `components` values per tuple, tuples in the dataset's order.
struct Array {
  std::string name;
  std::string unit;  ///< shown in the "units" field data, e.g. "m/s", "Pa", "1"
  int components = 1;
  Type type = Type::Float64;
  std::string bytes;  ///< the values, little-endian, as written

  std::size_t tuples() const;
  static Array float64(std::string name, std::string unit, int components, const std::vector<double>& values);
  /// Values stored as Float32 (about 7 digits): for large outputs that do not need more.
  static Array float32(std::string name, std::string unit, int components, const std::vector<double>& values);
  static Array uint8(std::string name, std::string unit, const std::vector<std::uint8_t>& values);
  static Array int64(std::string name, std::string unit, const std::vector<std::int64_t>& values);
};

/// A rectilinear grid: node coordinates in metres on each axis (nx + 1 values;
/// a 2D grid has z = {0}); cell data ordered x fastest, then y, then z.
struct RectilinearGrid {
  std::vector<double> x, y, z;
  std::vector<Array> cell_data;
  std::vector<Array> point_data;
  int cells() const;
};

/// Points (m) with point data, optionally one vertex cell per point (so that
/// ParaView draws them without a glyph filter) and polylines (indices into points).
/// Cell data, when given, is ordered as VTK orders cells: all vertices, then all lines.
struct PolyData {
  std::vector<std::array<double, 3>> points;
  bool vertex_per_point = false;
  std::vector<std::vector<std::int64_t>> lines;
  std::vector<Array> point_data;
  std::vector<Array> cell_data;
};

inline constexpr double kNoTime = std::numeric_limits<double>::quiet_NaN();

/// Writes `grid` to `file` (.vtr); `time_s` NaN: no TimeValue.
void writeVtr(const std::filesystem::path& file, const RectilinearGrid& grid, double time_s = kNoTime);
/// Writes `data` to `file` (.vtp).
void writeVtp(const std::filesystem::path& file, const PolyData& data, double time_s = kNoTime);

/// One dataset of a series: its time (s) and its path relative to the .pvd.
struct PvdEntry {
  double time_s = 0;
  std::filesystem::path file;
};
/// Writes a ParaView collection (.pvd) of `entries` in the given order.
void writePvd(const std::filesystem::path& file, const std::vector<PvdEntry>& entries);

/// Particles as a time series: one `<stem>/<stem>-NNNNN.vtp` per frame of `tracks`
/// (one vertex per particle; point data particle, deposited (1 for state
/// "deposited"), z (m, when the points have one); TimeValue the frame's time)
/// and `<stem>.pvd` listing them, all under `dir`. `position` gives a point's
/// place in the frame of docs/outputs.md (m). At most `max_frames` frames are
/// written, evenly strided, the last always among them. Returns the files
/// written, relative to `dir`.
std::vector<std::string> writeParticleSeries(const std::filesystem::path& dir, const std::string& stem, const Tracks& tracks,
                                             const std::function<std::array<double, 3>(const TrackPoint&)>& position, int max_frames = 500);

/// Reads back one array of a VTK XML file mmval wrote (appended raw with UInt64
/// headers, zlib-compressed or not, or ascii), found by Name anywhere in the file (data, coordinates or
/// field data), as doubles; `components` receives NumberOfComponents. For
/// readers of mmval's own outputs (the report) and for tests; not a general
/// VTK reader. Throws std::runtime_error naming the file when the array is
/// absent or the file is not in that form.
std::vector<double> readArray(const std::filesystem::path& file, const std::string& name, int* components = nullptr);
/// The entries of a String field-data array (e.g. "units").
std::vector<std::string> readStrings(const std::filesystem::path& file, const std::string& name);

}  // namespace mmval::vtk
