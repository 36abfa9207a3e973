// The iterative plane-Stokes solve (numerics.linear_solver = "iterative"): GMRES with the pressure
// mass matrix for the Schur complement, switching to selfp (BoomerAMG on B diag(A)^-1 B^T) when
// the residual has not fallen far enough in its first iterations (CoupledSystem). On a dense
// mask of narrow throats the mass matrix alone stalls and the switch bounds the count; on an open
// mask the mass matrix converges and no switch happens. Both answers are the direct LU's
// (an independent solve of the same system) to 1e-7. 1 MPI rank, grids up to 120^2 cells.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>

#include <gtest/gtest.h>
#include <petscksp.h>
#include <petscsys.h>

#include "mmval/simulate/FlowSolver.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "MaskProblems.hpp"

using namespace mmval::simulate;

namespace {

using mask_problems::denseThroats;
using mask_problems::Mask;
using mask_problems::maskProblem;

/// Open: one 16 x 16 px grain in the middle of 40 x 40 px.
Mask openMask() {
  Mask m = Mask::Constant(40, 40, false);
  m.block(12, 12, 16, 16).setConstant(true);
  return m;
}

struct Solved {
  double q = 0;
  FlowStats stats;
};

Solved solve(const Mask& solid, const std::string& linear) {
  SolverOptions o;
  o.linear = linear;
  SteadyFlowSolver s(maskProblem(solid), o);
  s.solve();
  return {s.flowRate(Side::east), s.stats()};
}

bool switched(const FlowStats& st) { return st.linear_reason.find("then selfp") != std::string::npos; }

/// The second stage's KSP as PETSc describes it (its own part of KSPView: the text before its
/// sub-solvers'), written at the end of its KSPSolve through the option -fluidp_ksp_view.
struct SecondStageView {
  std::filesystem::path file = std::filesystem::temp_directory_path() / "mmval-schur-second-stage-view.txt";
  SecondStageView() {
    std::filesystem::remove(file);
    PetscOptionsSetValue(nullptr, "-fluidp_ksp_view", ("ascii:" + file.string()).c_str());
  }
  ~SecondStageView() {
    PetscOptionsClearValue(nullptr, "-fluidp_ksp_view");
    std::filesystem::remove(file);
  }
  std::string text() const {
    std::ifstream in(file);
    std::stringstream ss;
    ss << in.rdbuf();
    const std::string all = ss.str();
    const auto sub = all.find("KSP Object:", 1);
    return all.substr(0, sub);
  }
};

/// Krylov solvers alive in this process: created minus destroyed over every logging stage, from
/// PETSc's class log (counted once its default logging has begun; before, neither is counted).
int liveKsps() {
  PetscStageLog log = nullptr;
  if (PetscLogGetStageLog(&log) != 0 || log == nullptr) return -1;
  int live = 0;
  for (int c = 0; c < log->classLog->numClasses; ++c) {
    if (log->classLog->classInfo[c].classid != KSP_CLASSID) continue;
    for (int s = 0; s < log->numStages; ++s) {
      const PetscClassPerfLog perf = log->stageInfo[s].classLog;
      if (c < perf->numClasses) live += perf->classInfo[c].creations - perf->classInfo[c].destructions;
    }
  }
  return live;
}

}  // namespace

// Dense narrow throats: 40 iterations with the mass matrix, then selfp (28 more when written);
// at most 150 in all.
TEST(IterativeStokesSchur, DenseNarrowThroatsSwitchToSelfpAndConverge) {
  const Mask m = denseThroats(120);
  const Solved it = solve(m, "iterative"), lu = solve(m, "direct");
  ASSERT_GT(lu.q, 0);
  EXPECT_TRUE(switched(it.stats)) << it.stats.linear_reason;
  EXPECT_LE(it.stats.linear_iterations, 150);
  EXPECT_NEAR(it.q / lu.q, 1.0, 1e-7);
}

// The same mask with the switch turned off (-fluidm_schur_switch_iterations 0): the mass matrix
// alone does not converge within the bound above (it needed 449 iterations when let run), so the
// bound holds only through the switch.
TEST(IterativeStokesSchur, DenseNarrowThroatsStallWithTheMassMatrixAlone) {
  PetscOptionsSetValue(nullptr, "-fluidm_schur_switch_iterations", "0");
  SolverOptions o;
  o.linear = "iterative";
  o.linear_max_iterations = 150;
  SteadyFlowSolver s(maskProblem(denseThroats(120)), o);
  EXPECT_THROW(s.solve(), FlowFailure);
  PetscOptionsClearValue(nullptr, "-fluidm_schur_switch_iterations");
}

// Open mask: the mass matrix converges before the probe; no switch, few iterations.
TEST(IterativeStokesSchur, OpenMaskKeepsTheMassMatrix) {
  const Solved it = solve(openMask(), "iterative"), lu = solve(openMask(), "direct");
  ASSERT_GT(lu.q, 0);
  EXPECT_FALSE(switched(it.stats)) << it.stats.linear_reason;
  EXPECT_LE(it.stats.linear_iterations, 60);
  EXPECT_NEAR(it.q / lu.q, 1.0, 1e-7);
}

// Memory at the switch: a switched solve holds neither stage's Krylov solver afterwards (the
// first stage's, with its Krylov basis and BoomerAMG hierarchy, is destroyed before the second is
// set up, the second after its solve; before, both stayed held: 8 KSPs with their sub-solvers),
// and a second solve of the same solver, whose first stage is created anew, repeats the first
// one's iterations and flow rate (to 1e-12: the same system from the same zero guess).
TEST(IterativeStokesSchur, SwitchedSolveReleasesBothStagesAndRepeatsExactly) {
  ASSERT_EQ(PetscLogDefaultBegin(), 0);
  const int before = liveKsps();
  ASSERT_GE(before, 0);
  SolverOptions o;
  o.linear = "iterative";
  SteadyFlowSolver s(maskProblem(denseThroats(120)), o);
  s.solve();
  ASSERT_TRUE(switched(s.stats())) << s.stats().linear_reason;
  EXPECT_EQ(liveKsps(), before);
  const int its = s.stats().linear_iterations;
  const double q = s.flowRate(Side::east);
  s.solve();
  EXPECT_TRUE(switched(s.stats())) << s.stats().linear_reason;
  EXPECT_EQ(s.stats().linear_iterations, its);
  EXPECT_NEAR(s.flowRate(Side::east) / q, 1.0, 1e-12);
  EXPECT_EQ(liveKsps(), before);
}

// Memory of the second stage: LGMRES restarted after 30 iterations (its Krylov basis ~32 vectors
// instead of GMRES(200)'s one per iteration, on chip2 at 2 cells/px 0.72 GB peak against 1.52 GB),
// as PETSc reports the KSP it ran. Switched at the first iteration (-fluidm_schur_switch_iterations
// 1), selfp alone needs more than 30 iterations on the dense mask, so the solve goes through
// restarts; it converges within the bound above to the LU's flow rate within 1e-7.
TEST(IterativeStokesSchur, SecondStageIsShortRestartLgmresAndConvergesThroughRestarts) {
  const Mask m = denseThroats(120);
  const Solved lu = solve(m, "direct");
  ASSERT_GT(lu.q, 0);
  Solved it;
  std::string view;
  {
    const SecondStageView v;
    PetscOptionsSetValue(nullptr, "-fluidm_schur_switch_iterations", "1");
    it = solve(m, "iterative");
    PetscOptionsClearValue(nullptr, "-fluidm_schur_switch_iterations");
    view = v.text();
  }
  ASSERT_TRUE(switched(it.stats)) << it.stats.linear_reason;
  EXPECT_NE(view.find("(fluidp_)"), std::string::npos) << view;
  EXPECT_NE(view.find("type: lgmres"), std::string::npos) << view;
  EXPECT_NE(view.find("restart=30,"), std::string::npos) << view;
  EXPECT_GT(it.stats.linear_iterations - 1, 30);  // at least one restart
  EXPECT_LE(it.stats.linear_iterations, 150);
  EXPECT_NEAR(it.q / lu.q, 1.0, 1e-7);
}
