// msd.csv, the ensemble mean-square displacement of a tracked video: one writer for
// both analyses (flow and Brownian), so that the file has one header whatever the mode.
//   lag_s     s     lag (mean time between the paired positions)
//   msd_um2   um^2  MSD of x + y at that lag
//   samples   1     displacements averaged at that lag
//   se_um2    um^2  standard error of msd_um2; empty where the analysis has none (flow mode)
//   fit_um2   um^2  the model fitted to the MSD, at that lag (Brownian: 4 D t + offset,
//                   Michalet 2010; flow: 4 D t^alpha); empty without a fit
#pragma once
#include <string>
#include <vector>

namespace mmval::tracking::detail {

/// One lag of msd.csv, in SI; NaN leaves a cell empty.
struct MsdRow {
  double lag_s = 0;
  double msd_m2 = 0;
  long long samples = 0;
  double se_m2 = 0;
  double fit_m2 = 0;
};

/// A CSV cell: `v` formatted by `format`, or empty for NaN / infinity (CSV readers take
/// an empty cell as missing, where "nan" would be a string to some).
std::string csvNumber(double v, const char* format = "{:.6g}");

/// The header line of msd.csv (with its newline).
std::string msdHeader();

/// msd.csv's text: the header, then one line per row in um^2 (6 significant digits).
std::string msdTable(const std::vector<MsdRow>& rows);

}  // namespace mmval::tracking::detail
