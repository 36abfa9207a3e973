// LIGGGHTS on two MPI ranks (its own domain decomposition) against the same scene
// on one rank, run by `mpiexec -n 2`: every rank first runs the scene alone
// (MPI_COMM_SELF), then both run it together (MPI_COMM_WORLD). Particles cross the
// subdomain boundary, the fluid forces come through the per-rank fix external
// callback, and grains are an STL mesh wall split between the ranks. Only the order
// of force sums differs, so trajectories must agree to ~round-off, far inside the
// particle size: positions within 1 nm, the same particles captured (measured: bitwise equal).
#include <gtest/gtest.h>
#include <mpi.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "GridField.hpp"
#include "mmval/particles/LiggghtsEngine.hpp"

namespace mmval::particles {
namespace {

int rank() {
  int r = 0;
  MPI_Comm_rank(MPI_COMM_WORLD, &r);
  return r;
}

SceneConfig sceneConfig(const std::string& name, bool world) {
  SceneConfig c;
  c.brownian = false;
  c.gravity = 9.81 * 400;       // settles ~8 um in the window: captures on the sticky bottom
  c.attachment.grains = false;
  c.particle.youngs_modulus = 1e5;
  const std::string tag = world ? "world" : "self" + std::to_string(rank());
  c.work_dir = std::filesystem::temp_directory_path() / ("mmval-liggghts-mpi-" + name + "-" + tag);
  return c;
}

std::vector<ParticleState> runChannel(bool world) {
  auto flow = std::make_shared<HeleShawChannel>(400e-6, 100e-6, 20e-6, 7e-4);
  const SceneConfig c = sceneConfig("channel", world);
  LiggghtsEngine e(flow, c, world ? MPI_COMM_WORLD : MPI_COMM_SELF);
  e.insert(sampleInlet(*flow, c.particle.radius(), 20e-6, 60e-6, 30, 17, {}));
  e.advance(0.03);
  return e.particles();
}

std::vector<ParticleState> runGrains(bool world) {
  // A 40 x 12 node field 10 um apart, uniform flow along x, a 4 x 4 node grain in the middle
  // straddling the subdomain boundary; particles released upstream of it.
  auto flow = test_support::gridField(40, 12, 7e-4, 20e-6, [](int i, int j) { return i >= 18 && i < 22 && j >= 4 && j < 8; });
  SceneConfig c = sceneConfig("grains", world);
  c.gravity = 0;                      // stay at their heights: carried into the grain
  c.attachment.capture_distance = 0;  // nothing sticks: the mesh wall alone stops them
  c.particle.youngs_modulus = 1e4;    // softer still: a 3x longer DEM step; the drag's Hertz overlap is ~20 nm
  LiggghtsEngine e(flow, c, world ? MPI_COMM_WORLD : MPI_COMM_SELF);
  std::vector<Vec3> pos;
  for (int k = 0; k < 8; ++k) pos.emplace_back(120e-6 + 8e-6 * (k % 4), 42e-6 + 5e-6 * (k / 4) + 1.3e-6 * k, 4e-6 + 1.5e-6 * k);
  e.insert(pos);
  e.advance(0.1);  // >= 0.6 mm/s at these heights: every particle reaches the grain (<= 53 um away)
  return e.particles();
}

void expectSame(const std::vector<ParticleState>& self, const std::vector<ParticleState>& world, const char* scene) {
  ASSERT_EQ(self.size(), world.size());
  double worst = 0;
  int captured = 0;
  for (std::size_t k = 0; k < self.size(); ++k) {
    worst = std::max(worst, (self[k].x - world[k].x).norm());
    EXPECT_EQ(self[k].status, world[k].status) << scene << " particle " << k;
    if (self[k].status == ParticleStatus::deposited) ++captured;
  }
  if (rank() == 0) std::printf("%s: %zu particles, %d captured, 1 vs 2 ranks largest position difference %.3g m\n", scene, self.size(), captured, worst);
  EXPECT_LT(worst, 1e-9) << scene;
}

TEST(LiggghtsMpi, ChannelSceneOnTwoRanksIsTheOneRankScene) {
  int size = 1;
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  ASSERT_EQ(size, 2) << "run under mpiexec -n 2";
  const auto self = runChannel(false);
  const auto world = runChannel(true);
  expectSame(self, world, "channel");
}

TEST(LiggghtsMpi, GrainMeshWallOnTwoRanksIsTheOneRankScene) {
  const auto self = runGrains(false);
  const auto world = runGrains(true);
  expectSame(self, world, "grain mesh");
  // The grain's upstream face is at x = 175 um (y 35..75 um): pushed on by the flow, the
  // particles pile up against it: most rest on the face itself, their centres one radius
  // upstream (Hertz overlap ~20 nm), the others on those; none gets into the grain.
  const double a = 2.5e-6;
  int on_face = 0;
  for (const auto& p : world) {
    EXPECT_LT(p.x.x(), 175e-6 - a + 0.1e-6) << "particle at y " << p.x.y() << " is inside the grain";
    if (std::abs(p.x.x() - (175e-6 - a)) < 0.1e-6) ++on_face;
  }
  EXPECT_GE(on_face, 5);
}

}  // namespace
}  // namespace mmval::particles

int main(int argc, char** argv) {
  MPI_Init(&argc, &argv);
  ::testing::InitGoogleTest(&argc, argv);
  if (mmval::particles::rank() != 0) {
    auto& listeners = ::testing::UnitTest::GetInstance()->listeners();
    delete listeners.Release(listeners.default_result_printer());
  }
  const int rc = RUN_ALL_TESTS();
  int worst = rc;
  MPI_Allreduce(&rc, &worst, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
  MPI_Finalize();
  return worst;
}
