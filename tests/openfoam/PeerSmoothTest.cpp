// The OpenFOAM peer on mmval's smooth grain boundary (geometry.boundary = "smooth"): one case file,
// a disc packing the test renders (60 x 60 px, 10 um per pixel, gaps of 3-7 px), run through
// mmval's own image-permeability kind and through the peer (its direct mesher: Cartesian cells
// with the wall vertices moved onto the smooth boundary; simpleFoam), each on a ladder of cells per
// pixel. Checks that the peer's mesh holds the boundary's pore fraction, that checkMesh finds it
// sound, and that the two extrapolated plane-2D permeabilities agree.
// 1 MPI rank for mmval, 1 process for OpenFOAM; skipped without OpenFOAM.
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/openfoam/Kinds.hpp"
#include "mmval/openfoam/Peer.hpp"
#include "mmval/simulate/Kinds.hpp"

#include "../TestScratch.hpp"

namespace mmval::openfoam {
namespace {

namespace fs = std::filesystem;

constexpr double kDarcy = 9.869233e-13;  // m2

struct Disc {
  double x, y, r;  ///< pixels: centre from the left and top edges, radius
};

/// Nine discs on a jittered 20 px lattice, radii 6.5-8.2 px: gaps of 3.1-6.7 px between lattice
/// neighbours, at least 1.6 px to the image edges (so no grain touches the inlet or outlet).
const std::vector<Disc> kDiscs = {{10.2, 10.8, 7.6}, {30.9, 9.7, 6.9}, {50.1, 11.2, 7.2}, {9.6, 30.4, 7.0},  {29.8, 31.1, 8.2},
                                  {50.7, 29.6, 6.5}, {11.1, 50.3, 7.4}, {31.2, 49.4, 7.1}, {49.5, 50.6, 7.8}};

fs::path writeMask() {
  cv::Mat img(60, 60, CV_8U, cv::Scalar(255));
  for (int r = 0; r < img.rows; ++r)
    for (int c = 0; c < img.cols; ++c)
      for (const Disc& d : kDiscs)
        if (std::hypot(c + 0.5 - d.x, r + 0.5 - d.y) < d.r) img.at<unsigned char>(r, c) = 0;
  const fs::path p = mmval::test::scratch("discs.png");
  cv::imwrite(p.string(), img);
  return p;
}

const CaseKindRegistry& registry() {
  static const CaseKindRegistry r = [] {
    CaseKindRegistry reg;
    simulate::registerFluidKinds(reg);
    return reg;
  }();
  return r;
}

Case smoothCase(const fs::path& mask, const std::string& levels) {
  const std::string text = "[case]\nname = \"peer-smooth\"\nkind = \"image-permeability\"\n[geometry]\nmask = \"" + mask.string() +
                           "\"\npixel_size = \"10 um\"\nboundary = \"smooth\"\n[numerics]\ndepth_model = \"2d\"\ncells_per_pixel_levels = " +
                           levels + "\n";
  return Case::parse(text, mmval::test::scratch("peer-smooth.toml"), registry());
}

double seconds(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

TEST(PeerSmooth, MeshHoldsTheSmoothBoundaryAndAgreesWithMmval) {
  if (!detect().available) GTEST_SKIP() << detect().reason;
  const fs::path mask = writeMask();
  // Both on 1, 2 and 3 cells per pixel (the peer's at the grains; its background is half as fine):
  // three levels give each an observed order and a Richardson value.
  const Case c = smoothCase(mask, "[1.0, 2.0, 3.0]");
  const fs::path out = mmval::test::scratch("peer-smooth");
  fs::create_directories(out);

  auto t0 = std::chrono::steady_clock::now();
  const RunOutput own = registry().find("image-permeability")->run(c, RunContext{out / "mmval", true, false, 0});
  const double own_s = seconds(t0);
  t0 = std::chrono::steady_clock::now();
  const RunOutput peer = runPeer(c, RunContext{out, true, false, 0}, PeerRunOptions{});
  const double peer_s = seconds(t0);

  const auto& ladder = peer.details.at("ladder");
  for (const auto& row : ladder) {
    const double mesh = row.at("porosity_mesh"), boundary = row.at("porosity_boundary"), mask_phi = row.at("porosity_mask");
    const double ortho = row.at("max_non_orthogonality_deg").is_number() ? row.at("max_non_orthogonality_deg").get<double>() : std::nan("");
    const double skew = row.at("max_skewness").is_number() ? row.at("max_skewness").get<double>() : std::nan("");
    std::printf("peer %.2f cells/px (%s): %lld cells, pore fraction mesh %.5f, smooth boundary %.5f (%+.3f %%), mask %.5f (%+.3f %%), "
                "non-orthogonality %.1f deg, skewness %.2f, mesh %.2f s, solve %.1f s (%d iterations), k %.4g D\n",
                row.at("cells_per_pixel").get<double>(), row.at("mesher").get<std::string>().c_str(), row.at("cells").get<long long>(), mesh, boundary,
                100 * (mesh / boundary - 1), mask_phi, 100 * (mesh / mask_phi - 1), ortho, skew, row.at("mesh_seconds").get<double>(),
                row.at("solve_seconds").get<double>(), row.at("iterations").get<int>(), row.value("value", std::nan("")) / kDarcy);
    // checkMesh's own limits (70 degrees, skewness 4) with margin: the mesher keeps every cell
    // star-shaped about its centre and evens out the wall vertices' spacing.
    EXPECT_LT(ortho, 45.0) << "level " << row.at("level");
    EXPECT_LT(skew, 3.0) << "level " << row.at("level");
    // The brief's bound: the peer meshes the same geometry to 0.5 % of its pore fraction.
    EXPECT_NEAR(mesh / boundary, 1.0, 5e-3) << "level " << row.at("level");
  }
  for (const auto& row : own.details.at("runs"))
    std::printf("mmval %.2f cells/px: k %.4g D, %.1f s\n", row.at("cells_per_pixel").get<double>(), row.at("permeability_D").get<double>(),
                row.value("wall_seconds", std::nan("")));
  ASSERT_TRUE(peer.metrics.count("permeability_2d_extrapolated")) << peer.details.dump(1);
  ASSERT_TRUE(own.metrics.count("permeability_2d_extrapolated")) << own.details.dump(1);
  const double k_peer = peer.metrics.at("permeability_2d_extrapolated"), k_own = own.metrics.at("permeability_2d_extrapolated");
  std::printf("extrapolated: mmval %.5g D, OpenFOAM %.5g D, difference %+.3f %%; wall mmval %.1f s, OpenFOAM %.1f s\n", k_own / kDarcy,
              k_peer / kDarcy, 100 * (k_peer / k_own - 1), own_s, peer_s);
  const double gci_peer = peer.metrics.at("permeability_2d_gci"), gci_own = own.metrics.at("permeability_2d_gci");
  std::printf("observed order: mmval %.2f, OpenFOAM %.2f; GCI: mmval %.2f %%, OpenFOAM %.2f %%\n",
              own.metrics.count("permeability_2d_observed_order") ? own.metrics.at("permeability_2d_observed_order") : std::nan(""),
              peer.metrics.count("permeability_2d_observed_order") ? peer.metrics.at("permeability_2d_observed_order") : std::nan(""), 100 * gci_own,
              100 * gci_peer);
  // 2 %: the target for the two solvers' extrapolated values (measured -0.6 % on this 1/2/3 ladder,
  // 37 s; -0.3 % on 1/2/4, which costs minutes of simpleFoam at 4 cells/px; with snappyHexMesh
  // -1.2 %). Both ladders converge at about second order (docs/validation/peer-smooth.md); the two
  // values must also lie within their combined GCI, which is what the 2 % rests on.
  EXPECT_NEAR(k_peer / k_own, 1.0, 0.02);
  EXPECT_LE(std::abs(k_peer / k_own - 1), std::hypot(gci_peer, gci_own));
}

}  // namespace
}  // namespace mmval::openfoam
