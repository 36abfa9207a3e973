// Counting a run's detections by frame, for tests that compare a tracker's output with a count
// made by hand or with a synthetic scene's truth.
#pragma once
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>

namespace mmval::test {

/// Detections per frame whose centre lies in [x0, x1) x [y0, y1), from detections.csv
/// (frame,t_s,x_px,y_px,...); a frame with detections only outside the region counts 0.
inline std::map<int, int> countInRegion(const std::filesystem::path& csv, double x0, double y0, double x1, double y1) {
  std::ifstream in(csv);
  std::string line;
  std::getline(in, line);
  std::map<int, int> n;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::string frame, t, x, y;
    std::getline(ss, frame, ',');
    std::getline(ss, t, ',');
    std::getline(ss, x, ',');
    std::getline(ss, y, ',');
    int& count = n[std::stoi(frame)];
    const double xv = std::stod(x), yv = std::stod(y);
    if (xv >= x0 && xv < x1 && yv >= y0 && yv < y1) ++count;
  }
  return n;
}

}  // namespace mmval::test
