// The velocity block's preconditioner on two ranks, one velocity component per rank.
//
// On one rank the iterative plane-Stokes solve preconditions the velocity block (u and v) with
// one BoomerAMG V-cycle. On two ranks, split by bands of cell rows, that V-cycle runs on both
// ranks at once and exchanges halos on every level, and its set-up does not scale: measured on
// the square array at 1448^2 cells, the set-up took 4.6-7.0 s on either rank count and the
// V-cycles ran at 72-77 % efficiency (docs/validation/linear-solver.md). Under a constant
// viscosity the u and v blocks do not couple (each is a scalar Laplacian with its own cut-cell
// rows), so the block's V-cycle is two independent scalar V-cycles. Here rank 0 takes every u
// unknown and rank 1 every v unknown: each gathers its component's rows of the block into a
// serial matrix, sets up and applies its own serial BoomerAMG, and the two ranks exchange only
// the component's residual and correction (two scatters of half the velocity vector per
// application). Entries that couple u to v (none under a constant viscosity) are dropped, as a
// block-Jacobi preconditioner drops them; the Krylov method still sees the whole operator.
#pragma once
#include <string>
#include <vector>

#include <petscksp.h>

namespace mmval::simulate::detail {

/// The velocity block's preconditioner the solver puts in PETSc's options database as its default
/// (`-fluidm_` and `-fluidp_fieldsplit_0_pc_type`; CoupledSystem): BoomerAMG.
inline constexpr const char* kVelocityBlockPcDefault = "hypre";

/// Whether the by-component split applies: exactly two ranks on `comm` and the PETSc option
/// `-<prefix>fieldsplit_0_by_component` not set false. Unset, it is on unless `user_pc` names the
/// user's own choice of the velocity block's preconditioner (userVelocityPcType), which the split
/// would otherwise replace.
bool componentSplitWanted(MPI_Comm comm, const char* prefix, const std::string& user_pc);

/// The value of `-<prefix>fieldsplit_0_pc_type` in PETSc's options database when it is not the
/// solver's own default (kVelocityBlockPcDefault), else "".
std::string userVelocityPcType(const char* prefix);

/// The preconditioner of the velocity sub-KSP of the Schur fieldsplit of `k` (set up: KSPSetUp
/// done), or nullptr when it already preconditions by component. Throws std::runtime_error naming
/// a failed PETSc call.
PC velocityBlockToSplit(KSP k);

/// Makes `vpc` (from velocityBlockToSplit) precondition by component. `is_u`: for each of this
/// rank's rows of the velocity block, in order, whether it is a u unknown (else v). The serial KSP
/// on each rank takes the options prefix `<prefix>fieldsplit_0_comp_` (default preonly with
/// BoomerAMG). Throws std::runtime_error naming a failed PETSc call.
void installComponentSplit(PC vpc, std::vector<char> is_u);

}  // namespace mmval::simulate::detail
