#include "mmval/simulate/FieldOutput.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/VtkWriter.hpp"

namespace mmval::simulate {

namespace {

void writePng(const cv::Mat& img, const std::filesystem::path& file) {
  std::vector<unsigned char> buf;
  if (!cv::imencode(".png", img, buf)) throw std::runtime_error("PNG encoding failed for " + file.string());
  writeFileAtomic(file, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()));
}

}  // namespace

namespace {

struct Snapshot {
  const FlowProblem& pr;
  int nx, ny;
  Eigen::ArrayXXd p, ux, uy, chi;
};

Snapshot snapshot(const SteadyFlowSolver& s) { return {s.problem(), s.nx(), s.ny(), s.p(), s.cellVelocity(0), s.cellVelocity(1), s.cellSolidFraction()}; }

Snapshot snapshot(const UnsteadyFlowSolver& s) {
  Eigen::ArrayXXd u, v, p;
  s.fields(u, v, p);
  return {s.problem(), s.nx(), s.ny(), p, s.cellVelocity(0), s.cellVelocity(1), s.cellSolidFraction()};
}

Snapshot snapshot(const ResolvedStokes& s) {
  Eigen::ArrayXXd u, v, p;
  s.fields(u, v, p);
  return {s.problem(), static_cast<int>(p.cols()), static_cast<int>(p.rows()), p, s.cellVelocity(0), s.cellVelocity(1), s.cellSolidFraction()};
}

/// Cells ordered x fastest, then y (then z): VTK's order for cell data.
std::vector<double> cellOrder(const Eigen::ArrayXXd& a) {
  std::vector<double> v;
  v.reserve(static_cast<std::size_t>(a.size()));
  for (Eigen::Index j = 0; j < a.rows(); ++j)
    for (Eigen::Index i = 0; i < a.cols(); ++i) v.push_back(a(j, i));
  return v;
}

void writeVtrOf(const Snapshot& s, const std::filesystem::path& file, double time_s) {
  vtk::RectilinearGrid g;
  g.x = s.pr.x.faces();
  g.y = s.pr.y.faces();
  g.z = {0.0};
  std::vector<double> u;
  u.reserve(3 * static_cast<std::size_t>(s.nx) * s.ny);
  for (int j = 0; j < s.ny; ++j)
    for (int i = 0; i < s.nx; ++i) u.insert(u.end(), {s.ux(j, i), s.uy(j, i), 0.0});
  g.cell_data = {vtk::Array::float64("p", "Pa", 1, cellOrder(s.p)), vtk::Array::float64("U", "m/s", 3, u),
                 vtk::Array::float32("solid", "1", 1, cellOrder(s.chi))};
  vtk::writeVtr(file, g, time_s);
}

void writeSpeedPngOf(const Snapshot& s, const std::filesystem::path& file, int max_pixels, const std::vector<std::vector<Eigen::Vector2d>>& paths = {}) {
  const FlowProblem& pr = s.pr;
  const Eigen::ArrayXXd &ux = s.ux, &uy = s.uy, &chi = s.chi;
  const Eigen::ArrayXXd speed = (ux.square() + uy.square()).sqrt();
  const double vmax = std::max(speed.maxCoeff(), 1e-300);
  const double lx = pr.x.length(), ly = pr.y.length();
  const int w = lx >= ly ? max_pixels : std::max(1, static_cast<int>(max_pixels * lx / ly));
  const int h = lx >= ly ? std::max(1, static_cast<int>(max_pixels * ly / lx)) : max_pixels;
  cv::Mat gray(h, w, CV_8UC1), solid(h, w, CV_8UC1);
  for (int r = 0; r < h; ++r)
    for (int c = 0; c < w; ++c) {
      const int i = pr.x.cellOf(pr.x.lo() + (c + 0.5) * lx / w);
      const int j = pr.y.cellOf(pr.y.hi() - (r + 0.5) * ly / h);  // image rows go down
      gray.at<unsigned char>(r, c) = static_cast<unsigned char>(std::clamp(255.0 * speed(j, i) / vmax, 0.0, 255.0));
      solid.at<unsigned char>(r, c) = chi(j, i) >= 0.5 ? 255 : 0;
    }
  cv::Mat color;
  cv::applyColorMap(gray, color, cv::COLORMAP_VIRIDIS);
  color.setTo(cv::Scalar(128, 128, 128), solid);
  // Particle paths in white, start marked by a ring, end by a dot.
  const auto pixelOf = [&](const Eigen::Vector2d& X) {
    return cv::Point(static_cast<int>(std::lround((X.x() - pr.x.lo()) / lx * w)), static_cast<int>(std::lround((pr.y.hi() - X.y()) / ly * h)));
  };
  const int thick = std::max(1, std::max(w, h) / 400);
  for (const auto& path : paths) {
    if (path.empty()) continue;
    for (std::size_t k = 1; k < path.size(); ++k) cv::line(color, pixelOf(path[k - 1]), pixelOf(path[k]), cv::Scalar(255, 255, 255), thick, cv::LINE_AA);
    cv::circle(color, pixelOf(path.front()), 3 * thick, cv::Scalar(255, 255, 255), thick, cv::LINE_AA);
    cv::circle(color, pixelOf(path.back()), 2 * thick, cv::Scalar(255, 255, 255), cv::FILLED, cv::LINE_AA);
  }
  std::vector<unsigned char> buf;
  if (!cv::imencode(".png", color, buf)) throw std::runtime_error("PNG encoding failed for " + file.string());
  writeFileAtomic(file, std::string_view(reinterpret_cast<const char*>(buf.data()), buf.size()));
}

/// Cell-centred velocity of a 3D solution: the mean of the two faces on each axis.
Eigen::Vector3d cellVelocity3d(const Stokes3DSolver& s, int i, int j, int k) {
  return {0.5 * (s.u(i, j, k) + s.u(i + 1, j, k)), 0.5 * (s.v(i, j, k) + s.v(i, j + 1, k)), 0.5 * (s.w(i, j, k) + s.w(i, j, k + 1))};
}

bool solidCell3d(const Stokes3DSolver& s, int i, int j) {
  const auto& solid = s.problem().solid;
  return solid.size() > 0 && solid(j, i);
}

}  // namespace

void writeVtr(const Stokes3DSolver& s, const std::filesystem::path& file) {
  const auto& pr = s.problem();
  const int nx = pr.nx, ny = pr.ny, nz = pr.nz;
  // The solver's y cell j is image row j (top down); the file is y up (docs/outputs.md):
  // file row jj holds solver row ny - 1 - jj, and the y velocity changes sign.
  std::vector<double> p, u, solid;
  const std::size_t n = static_cast<std::size_t>(nx) * ny * nz;
  p.reserve(n);
  u.reserve(3 * n);
  solid.reserve(n);
  for (int k = 0; k < nz; ++k)
    for (int jj = 0; jj < ny; ++jj)
      for (int i = 0; i < nx; ++i) {
        const int j = ny - 1 - jj;
        const bool in_solid = solidCell3d(s, i, j);
        const Eigen::Vector3d v = cellVelocity3d(s, i, j, k);
        p.push_back(in_solid ? 0.0 : s.p(i, j, k));
        u.insert(u.end(), {v.x(), -v.y(), v.z()});
        solid.push_back(in_solid ? 1.0 : 0.0);
      }
  vtk::RectilinearGrid g;
  const auto axis = [](int cells, double len) {
    std::vector<double> a;
    for (int q = 0; q <= cells; ++q) a.push_back(len * q / cells);
    return a;
  };
  g.x = axis(nx, pr.length);
  g.y = axis(ny, pr.width);
  g.z = axis(nz, pr.depth);
  g.cell_data = {vtk::Array::float64("p", "Pa", 1, p), vtk::Array::float64("U", "m/s", 3, u), vtk::Array::float32("solid", "1", 1, solid)};
  vtk::writeVtr(file, g);
}

void writeMidDepthSpeedPng(const Stokes3DSolver& s, const std::filesystem::path& file) {
  const auto& pr = s.problem();
  const int k = pr.nz / 2;
  Eigen::ArrayXXd speed(pr.ny, pr.nx);
  for (int j = 0; j < pr.ny; ++j)
    for (int i = 0; i < pr.nx; ++i) speed(j, i) = solidCell3d(s, i, j) ? 0.0 : cellVelocity3d(s, i, j, k).norm();
  const double vmax = std::max(speed.maxCoeff(), 1e-300);
  cv::Mat gray(pr.ny, pr.nx, CV_8UC1), solid(pr.ny, pr.nx, CV_8UC1);
  for (int j = 0; j < pr.ny; ++j)
    for (int i = 0; i < pr.nx; ++i) {
      const int r = j;  // the 3D grid's y cell j is row j of the (coarsened) image: drawn as the image
      gray.at<unsigned char>(r, i) = static_cast<unsigned char>(std::clamp(255.0 * speed(j, i) / vmax, 0.0, 255.0));
      solid.at<unsigned char>(r, i) = solidCell3d(s, i, j) ? 255 : 0;
    }
  cv::Mat color;
  cv::applyColorMap(gray, color, cv::COLORMAP_VIRIDIS);
  color.setTo(cv::Scalar(128, 128, 128), solid);
  // Coarse 3D grids are small: enlarge by whole pixels to ~600 px on the long side.
  const int zoom = std::max(1, 600 / std::max(pr.nx, pr.ny));
  if (zoom > 1) cv::resize(color, color, cv::Size(), zoom, zoom, cv::INTER_NEAREST);
  writePng(color, file);
}

void writeVtr(const SteadyFlowSolver& s, const std::filesystem::path& file) { writeVtrOf(snapshot(s), file, vtk::kNoTime); }
void writeVtr(const UnsteadyFlowSolver& s, const std::filesystem::path& file) { writeVtrOf(snapshot(s), file, s.time()); }
void writeSpeedPng(const SteadyFlowSolver& s, const std::filesystem::path& file, int max_pixels) { writeSpeedPngOf(snapshot(s), file, max_pixels); }
void writeSpeedPng(const UnsteadyFlowSolver& s, const std::filesystem::path& file, int max_pixels) { writeSpeedPngOf(snapshot(s), file, max_pixels); }
void writeVtr(const ResolvedStokes& s, const std::filesystem::path& file) { writeVtrOf(snapshot(s), file, vtk::kNoTime); }
void writeSpeedPng(const ResolvedStokes& s, const std::filesystem::path& file, int max_pixels, const std::vector<std::vector<Eigen::Vector2d>>& paths) {
  writeSpeedPngOf(snapshot(s), file, max_pixels, paths);
}

}  // namespace mmval::simulate
