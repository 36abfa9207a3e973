// dispersion_frames.csv of writeComparison: the paper's Eq. 18 (Elrahmani et al. 2022,
// sigma = sqrt(sum (x_i - mu)^2 / N)) frame by frame for both sides, against a set computed by
// hand, and the binned sigma_x_time_um.csv / sigma_y_time_um.csv against those frames.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "mmval/compare/Compare.hpp"
#include "TrackPoints.hpp"

#include "../TestScratch.hpp"

namespace mmval::compare {
namespace {

using test_support::pt;

/// Frames 0-5, 0.1 s apart, all positions in um (y scaled by y_scale):
/// particle 1 at (10 + 5f, 0), particle 2 at (14 + 5f, 6), particle 3 from frame 2 at
/// (18 + 5f, 3), particle 4 at rest at (100, 100) all along (immobile: in no frame's count).
/// Frames 0-1 (particles 1, 2): mean x 12 + 5f, sigma_x = 2, mean y 3, sigma_y = 3.
/// Frames 2-5 (particles 1-3): mean x 14 + 5f, sigma_x = sqrt((16 + 0 + 16) / 3) = sqrt(32 / 3),
/// mean y 3, sigma_y = sqrt((9 + 9 + 0) / 3) = sqrt(6); all times y_scale for y.
Tracks handSet(double y_scale) {
  Tracks t;
  for (int f = 0; f <= 5; ++f) {
    const double time = 0.1 * f;
    t.points.push_back(pt(f, 1, time, (10 + 5 * f) * 1e-6, 0.0));
    t.points.push_back(pt(f, 2, time, (14 + 5 * f) * 1e-6, 6e-6 * y_scale));
    if (f >= 2) t.points.push_back(pt(f, 3, time, (18 + 5 * f) * 1e-6, 3e-6 * y_scale));
    t.points.push_back(pt(f, 4, time, 100e-6, 100e-6));
  }
  std::stable_sort(t.points.begin(), t.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  return t;
}

std::vector<std::vector<std::string>> readCsv(const std::filesystem::path& file) {
  std::ifstream in(file);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) cells.push_back(cell);
    rows.push_back(cells);
  }
  return rows;
}

TEST(DispersionFrames, EquationEighteenPerFrameForBothSides) {
  const auto dir = mmval::test::scratch("compare-dispersion-frames");
  std::filesystem::remove_all(dir);
  CompareOptions o;
  o.tracks.time_bins = 6;  // six bins of 0.5 s / 6 over the 0.5 s: frame f falls in bin f
  const auto files = writeComparison(compareTracks(handSet(1.0), handSet(2.0), o), dir);
  ASSERT_NE(std::find(files.begin(), files.end(), "dispersion_frames.csv"), files.end());
  const auto rows = readCsv(dir / "dispersion_frames.csv");
  ASSERT_EQ(rows.size(), 13u);  // header + 6 frames per side
  EXPECT_EQ(rows[0], (std::vector<std::string>{"side", "frame", "t_s", "count", "mean_x_um", "mean_y_um", "sigma_x_um", "sigma_y_um"}));
  // The frames are written to 9 significant digits (half a unit of the 9th: < 5e-9 relative), the
  // binned files to 6 (< 5e-6 relative): 1e-8 and 1e-5 relative cover the rounding and no more.
  auto near = [](const std::string& cell, double expected, double rel = 1e-8) {
    EXPECT_NEAR(std::stod(cell), expected, rel * std::max(1.0, std::abs(expected)));
  };
  std::map<std::string, std::vector<double>> sigma_x, sigma_y;
  for (std::size_t r = 1; r < rows.size(); ++r) {
    const auto& row = rows[r];
    ASSERT_EQ(row.size(), 8u);
    const std::string side = row[0];
    const double y_scale = side == "simulation" ? 2.0 : 1.0;
    const int f = std::stoi(row[1]);
    EXPECT_EQ(side, r <= 6 ? "experiment" : "simulation");
    EXPECT_EQ(f, static_cast<int>((r - 1) % 6));
    near(row[2], 0.1 * f);
    const bool three = f >= 2;
    EXPECT_EQ(std::stoi(row[3]), three ? 3 : 2) << side << " frame " << f;
    near(row[4], three ? 14 + 5 * f : 12 + 5 * f);
    near(row[5], 3 * y_scale);
    near(row[6], three ? std::sqrt(32.0 / 3.0) : 2.0);
    near(row[7], (three ? std::sqrt(6.0) : 3.0) * y_scale);
    sigma_x[side].push_back(std::stod(row[6]));
    sigma_y[side].push_back(std::stod(row[7]));
  }
  // The binned files average the frames of each bin: with one frame per bin they are the frames.
  for (const auto& [file, per_frame] : {std::pair{"sigma_x_time_um.csv", &sigma_x}, std::pair{"sigma_y_time_um.csv", &sigma_y}}) {
    const auto binned = readCsv(dir / file);
    ASSERT_EQ(binned.size(), 7u) << file;
    for (std::size_t b = 1; b < binned.size(); ++b) {
      near(binned[b][1], (*per_frame)["experiment"][b - 1], 1e-5);
      near(binned[b][2], (*per_frame)["simulation"][b - 1], 1e-5);
    }
  }
}

}  // namespace
}  // namespace mmval::compare
