#include "mmval/reports/Plot.hpp"

#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

namespace mmval::reports {

namespace {

std::string quote(const std::string& s) {
  std::string out = "\"";
  for (char c : s) out += (c == '"' || c == '\\') ? std::string("\\") + c : std::string(1, c);
  return out + "\"";
}

}  // namespace

bool gnuplotAvailable() { return std::system("command -v gnuplot >/dev/null 2>&1") == 0; }

std::string renderSvg(const Plot& plot) {
  namespace fs = std::filesystem;
  char tmpl[] = "/tmp/mmval-plot-XXXXXX";
  if (mkdtemp(tmpl) == nullptr) throw std::runtime_error("cannot create a temporary folder for gnuplot");
  const fs::path dir = tmpl;
  // The key is one entry a line under the plot: the page grows by a line per series.
  std::string script = fmt::format(
      "set terminal svg size {},{} dynamic enhanced font 'sans,11' background rgb 'white'\n"
      "set output {}\nset title {} noenhanced\nset xlabel {}\nset ylabel {}\nset grid\nset key outside bottom center vertical noenhanced\n",
      plot.width, plot.height + 18 * static_cast<int>(plot.series.size()), quote((dir / "plot.svg").string()), quote(plot.title), quote(plot.xlabel), quote(plot.ylabel));
  if (!plot.yrange.empty()) script += "set yrange " + plot.yrange + "\n";
  if (plot.logx) script += "set logscale x\nset format x '10^{%L}'\n";
  if (plot.logy) script += "set logscale y\nset format y '10^{%L}'\n";
  int label_id = 1;
  for (const auto& l : plot.labels)
    if (std::isfinite(l.x) && std::isfinite(l.y))
      script += fmt::format("set label {} {} at {:.10g},{:.10g} right point pt 13 ps 1.6 lc rgb 'black' offset -1,0.8 front noenhanced\n", label_id++,
                            quote(l.text), l.x, l.y);
  std::vector<std::string> parts;
  int k = 0;
  for (const auto& s : plot.series) {
    const fs::path data = dir / fmt::format("s{}.dat", k++);
    std::ofstream out(data);
    int rows = 0;
    const bool bars = !s.yerr.empty() && s.yerr.size() == s.y.size();
    for (std::size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!std::isfinite(s.x[i]) || !std::isfinite(s.y[i])) {
        out << "\n";  // gap
        continue;
      }
      if ((plot.logx && s.x[i] <= 0) || (plot.logy && s.y[i] <= 0)) continue;
      if (bars)
        out << fmt::format("{:.10g} {:.10g} {:.10g}\n", s.x[i], s.y[i], std::isfinite(s.yerr[i]) ? s.yerr[i] : 0.0);
      else
        out << fmt::format("{:.10g} {:.10g}\n", s.x[i], s.y[i]);
      ++rows;
    }
    if (rows == 0) continue;
    parts.push_back(fmt::format("{} using {} with {} lw 2 title {}", quote(data.string()), bars ? "1:2:3" : "1:2", s.style, quote(s.name)));
  }
  if (parts.empty()) {
    fs::remove_all(dir);
    throw std::runtime_error("plot '" + plot.title + "' has no finite data");
  }
  script += "plot ";
  for (std::size_t i = 0; i < parts.size(); ++i) script += (i ? ", \\\n     " : "") + parts[i];
  script += "\n";
  std::ofstream(dir / "plot.gp") << script;
  const std::string cmd = fmt::format("gnuplot {} > {} 2>&1", quote((dir / "plot.gp").string()), quote((dir / "gnuplot.log").string()));
  const int status = std::system(cmd.c_str());
  std::stringstream svg, log;
  svg << std::ifstream(dir / "plot.svg").rdbuf();
  log << std::ifstream(dir / "gnuplot.log").rdbuf();
  fs::remove_all(dir);
  if (status != 0 || svg.str().find("<svg") == std::string::npos)
    throw std::runtime_error("gnuplot failed for plot '" + plot.title + "': " + log.str());
  // Drop the XML prolog so the SVG can be inlined in HTML.
  std::string text = svg.str();
  const auto start = text.find("<svg");
  return text.substr(start);
}

}  // namespace mmval::reports
