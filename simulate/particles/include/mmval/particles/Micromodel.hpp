// The coupled validation scene, case kind "particles-micromodel":
// the micromodel experiment of the paper (Elrahmani et al. 2022; its numbers in
// reference-data/micromodel-experiment.toml) on a pore mask. The geometry comes from a binary image (pixel
// size and chip depth from the case), the depth-averaged Stokes flow from
// mmval's fluid solver (MicromodelFlow) at the experiment's Darcy velocity,
// fines of the experiment's size and density enter at the inlet at the
// experiment's concentration (optionally a random sample of it, each simulated
// particle then a parcel for the deposit volume), move with the overdamped
// colloid engine (Stokes number ~1e-5) and stick to grains, the bottom plate
// and earlier deposits. Four-way: deposits at grains fill pixel columns, deposits
// on the plates thin the local aperture (the fluid solver's per-cell depth) and
// close a pixel only below a minimum aperture (DepositGrid), and the flow is
// solved again when enough aperture was lost since the last solve.
//
// Outputs (all written under temporary names and renamed):
//   trajectories.csv  the tracker's tracks schema: frame, particle, x, y (pixels
//                     of the geometry image, column / row from the top-left
//                     pixel's centre), x_um, y_um (= pixels x pixel size, image
//                     axes), t_s, z_um (height above the bottom plate), state
//                     (mobile; a deposited particle appears once, in the first
//                     frame after it deposited, with state "deposited")
//   retention.csv     frame, t_s, injected, inside, retained, left, retained_fraction
//   permeability.csv  frame, t_s, k_m2, k_D, k_over_k0, pressure_drop_pa, deposited, resolves
//                     (both one row per output frame, written by mmval/core/OutputTables.hpp;
//                     columns, units and invariants in docs/outputs.md, "Tables")
// The pump (MicromodelBookkeeping.hpp). Each fluid solve gives the
// pressure drop the set flow rate needs across the simulated geometry. When a
// re-solve finds no flow path left, or that pressure above flow.max_pressure
// (the syringe pump's limit, optional), the pump stalls: that frame injects
// nothing, is written, and the run ends there (details.pump_stall: time,
// reason, pressure; one line on stderr). Ending rather than going on without
// flow: a stalled chip moves nothing but by sedimentation, which would turn the
// particles still in the pores into "retained" ones that no flow placed there.
// They are reported as inside. A clean chip that already needs more than
// flow.max_pressure is an InputError.
// Counts: scheduled (what the injection schedule called for by the planned end)
// = injected + never_injected; retained_fraction = retained / injected (the
// paper's definition); analysis.retention_window adds the same ratio for the
// particles injected within a window.
// Long runs write checkpoint.bin every run.checkpoint_every engine steps (at
// the next output frame); `mmval run --resume` continues from it bit for bit.
#pragma once
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Checkpoint.hpp"  // mmval::RunStopped: thrown after run.stop_after_frames frames

namespace mmval::particles {

CaseKind micromodelKind();

}  // namespace mmval::particles
