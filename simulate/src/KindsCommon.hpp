// Internal helpers shared by the fluid case kinds.
#pragma once
#include <chrono>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Run.hpp"
#include "mmval/simulate/CylinderScene.hpp"
#include "mmval/simulate/FlowSolver.hpp"

#include "SolverUtil.hpp"

namespace mmval::simulate::detail {

inline constexpr const char* kSolverName = "mmval simulate (MAC, immersed boundary, PETSc)";

/// numerics.levels if present, else the single resolution key; each in [lo, hi].
std::vector<int> levelsOf(const Case& c, const char* single_key, int lo, int hi);
/// numerics.immersed, numerics.cut_cells, numerics.linear_solver (+ the peer's max_iterations / residual if absent).
void declareSolverKeys(Schema& s, bool peer_keys);
/// quiet: no terminal line when numerics.linear_solver = "auto" picks the iterative solver or falls back.
SolverOptions solverOptions(const Case& c, bool quiet = false);
/// The case's immersed-boundary treatment (numerics.immersed, numerics.cut_cells) into p.
void setImmersed(const Case& c, FlowProblem& p);
/// result.json's details.immersed: "penalized", or "sharp" with the cut-cell treatment.
std::string immersedLabel(const Case& c);
/// A level's clock: wall and process CPU seconds since it was made.
struct LevelClock {
  std::chrono::steady_clock::time_point t0 = std::chrono::steady_clock::now();
  double cpu0 = processCpuSeconds();
  double wallSeconds() const { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); }
  double cpuSeconds() const { return processCpuSeconds() - cpu0; }
};
/// One ladder row: cells, unknowns, timings (wall and CPU since `clock` was made), iterations,
/// memory, value and error against `primary`.
nlohmann::json ladderRow(std::size_t index, int resolution, const SteadyFlowSolver& s, const LevelClock& clock, double value,
                         const Acceptance* primary);
/// Writes fields.vtr and speed.png of `s` into ctx.out_dir (rank 0 only) and lists them in out.files.
void writeFields(const SteadyFlowSolver& s, const RunContext& ctx, const std::string& stem, RunOutput& out);

/// Unsteady cylinder keys (Courant limit, perturbation, statistics window, refined box).
void declareUnsteadyCylinderKeys(Schema& s);
/// Runs the unsteady cylinder-channel case of `scene`: make_problem(cells_around) builds each
/// level's problem; forces become coefficients by scene.forceCoefficient().
RunOutput runUnsteadyCylinder(const Case& c, const RunContext& ctx, const CylinderScene& scene,
                              const std::function<FlowProblem(int level)>& make_problem);


}  // namespace mmval::simulate::detail
