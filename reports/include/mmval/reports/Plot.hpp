// Plots through gnuplot's SVG terminal (a maintained tool; no hand-written
// plotting). A Plot is data plus labels; renderSvg() writes the data to a
// temporary folder, runs gnuplot and returns the SVG text for inlining.
#pragma once
#include <optional>
#include <string>
#include <vector>

namespace mmval::reports {

struct Series {
  std::string name;
  std::vector<double> x, y;
  std::string style = "linespoints";  ///< gnuplot "with" style: lines, points, linespoints, boxes, steps, yerrorbars
  /// Error bar half-widths, one per point; when given the series is drawn "using 1:2:3"
  /// (the style should then be an error-bar style such as "yerrorbars").
  std::vector<double> yerr = {};
};

/// A labelled point drawn on the plot (e.g. a paper's value).
struct Label {
  double x = 0, y = 0;
  std::string text;
};

struct Plot {
  std::string title, xlabel, ylabel;
  bool logx = false, logy = false;
  std::vector<Series> series;
  int width = 640, height = 400;
  std::vector<Label> labels = {};
  std::string yrange = {};  ///< gnuplot range, e.g. "[0:1]"; empty: automatic
};

/// True when gnuplot can be run.
bool gnuplotAvailable();

/// The SVG of the plot; throws std::runtime_error with gnuplot's message on failure.
std::string renderSvg(const Plot& plot);

}  // namespace mmval::reports
