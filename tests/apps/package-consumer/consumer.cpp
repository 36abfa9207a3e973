// Uses the installed mmval::core: a quantity with units, a tracks CSV written and
// read back, a VTK grid written and one array read back. Prints what it found;
// exits non-zero on any mismatch.
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "mmval/core/Tracks.hpp"
#include "mmval/core/Units.hpp"
#include "mmval/core/VtkWriter.hpp"

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  const std::filesystem::path dir = argv[1];
  const mmval::Quantity q = mmval::parseQuantity("2.5 D");  // darcy, API definition: 9.869233e-13 m^2
  mmval::Tracks t;
  mmval::TrackPoint p;
  p.particle = 7;
  p.frame = 3;
  p.t = 0.1;
  p.x = 12.5e-6;
  p.y = 4e-6;
  t.points.push_back(p);
  mmval::writeTracksCsv(dir / "tracks.csv", t);
  const mmval::Tracks back = mmval::readTracksCsv(dir / "tracks.csv");
  mmval::vtk::RectilinearGrid g;
  g.x = {0, 1e-6, 2e-6};
  g.y = {0, 1e-6};
  g.z = {0};
  g.cell_data = {mmval::vtk::Array::float64("p", "Pa", 1, {1.5, -2.25})};
  mmval::vtk::writeVtr(dir / "g.vtr", g);
  const std::vector<double> pv = mmval::vtk::readArray(dir / "g.vtr", "p");
  std::printf("k %.6g m2, particle %lld x %.6g m, p %g %g\n", q.si, static_cast<long long>(back.points.at(0).particle), back.points.at(0).x, pv.at(0),
              pv.at(1));
  const bool ok = std::abs(q.si - 2.5 * 9.869233e-13) < 1e-24 && back.points.at(0).particle == 7 && pv == std::vector<double>{1.5, -2.25};
  return ok ? 0 : 1;
}
