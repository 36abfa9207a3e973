#include "mmval/particles/KindMetrics.hpp"

namespace mmval::particles {

namespace {

// Particle counts are plain numbers: declared dimensionless.
void channelMetrics(Schema& s) {
  s.metric("retained_fraction", "1", "Deposited over injected particles");
  s.metric("left_fraction", "1", "Particles that left through the outlet over injected");
  s.metric("injected", "1", "Particles injected");
  s.metric("deposited", "1", "Particles deposited");
  s.metric("left", "1", "Particles that left through the outlet");
  s.metric("inside", "1", "Particles still moving in the channel at the end");
  s.metric("count_balance_error", "1", "injected - inside - deposited - left (0: counts balance)");
  s.metric("mean_speed", "um/s", "Mean x-speed of the mobile particles between output frames");
  s.metric("mean_speed_ratio", "1", "mean_speed over the depth-averaged flow speed seen by particles spread evenly across the accessible depth (Faxen-corrected)");
  s.metric("particle_steps_per_second", "Hz", "Engine throughput: particle steps per wall-clock second of the run");
  s.metric("engine_wall_time", "s", "Wall-clock time spent in the particle engine");
}

void micromodelMetrics(Schema& s) {
  s.metric("retained_fraction", "1",
           "Retained (deposited) over injected particles, the paper's retention; particles never injected (never_injected) are in neither");
  s.metric("left_fraction", "1", "Particles that left through the outlet over injected");
  s.metric("count_balance_error", "1", "injected - inside - retained - left (0: counts balance)");
  s.metric("injected", "1", "Simulated particles injected (placed in the chip)");
  s.metric("scheduled", "1", "Simulated particles the injection schedule called for by the run's planned end");
  s.metric("never_injected", "1",
           "scheduled - injected: particles that never entered the chip (the pump stalled, or the inlet strip stayed full); counted apart");
  s.metric("window_injected", "1", "Particles injected within analysis.retention_window (from, to] (to cut at the run's end)");
  s.metric("window_retained", "1", "Of those, particles retained by the window's end");
  s.metric("window_retained_fraction", "1", "window_retained over window_injected (absent when nothing was injected in the window)");
  s.metric("pressure_drop_initial", "Pa", "Pressure drop the set flow rate needs across the clean simulated geometry (Darcy's law, mu u L / k0)");
  s.metric("pressure_drop_final", "Pa", "Pressure drop the set flow rate needed at the last fluid solve that found a flow path");
  s.metric("pump_stall_time", "s", "Time the pump stalled (pressure above flow.max_pressure, or no flow path left): injection stopped and the run ended (absent when it never stalled)");
  s.metric("pump_stall_pressure", "Pa", "Pressure drop the set rate needed when the pump stalled at its limit (absent otherwise, and when no flow path was left)");
  s.metric("retained", "1", "Simulated particles retained: attached + strained");
  s.metric("attached", "1", "Retained particles held by a surface (plates, grains, deposits, closed cells)");
  s.metric("strained", "1",
           "Retained particles held by the flow in a passage narrower than themselves (deposition.straining; 0 when it is off)");
  s.metric("strained_fraction", "1", "Strained over injected particles (part of retained_fraction)");
  s.metric("left", "1", "Simulated particles that left through the outlet");
  s.metric("inside", "1", "Simulated particles still moving at the end");
  s.metric("represented_particles", "1", "Physical particles the injected ones stand for (injected / particles.sample_fraction)");
  s.metric("not_placed", "1",
           "Particles due by the end of injection (the run's end, or a pump stall) but never placed because the inlet strip stayed full "
           "(inlet clogging): retried every frame, never dropped; part of never_injected, and details.not_placed (or the pump stall) says why");
  s.metric("mean_speed", "um/s", "Mean speed of the mobile particles");
  s.metric("k_over_k0", "1", "Final over clean permeability");
  s.metric("permeability_reduction", "%", "1 - k / k0");
  s.metric("k0", "D", "Permeability of the clean micromodel");
  s.metric("resolves", "1", "Fluid re-solves after deposition changed the pore space");
  s.metric("resolves_pattern_kept", "1",
           "Of those, re-solves that fitted the clean chip's matrix pattern (numerics.resolve_pattern = \"fixed\"): a numeric LU only, no new ordering");
  s.metric("time_to_10pct_reduction", "s", "Time of the first 10 % permeability loss (absent when it never happened)");
  s.metric("time_to_clogging", "s", "Time of the first re-solve that found no open path inlet to outlet (absent when none)");
  s.metric("closed_pixels", "1", "Pore pixels closed by deposits");
  s.metric("aperture_loss", "1", "Mean loss of aperture over the pore pixels (a closed pixel counts as a whole column)");
  s.metric("wall_time", "s", "Wall-clock time of the run, over all resumed parts");
  s.metric("fluid_solve_time", "s", "Wall-clock time spent in fluid solves");
  s.metric("particle_steps_per_second", "Hz", "Particle steps per wall-clock second of the run");
  s.metric("engine_particle_steps_per_second", "Hz", "Particle steps per wall-clock second spent in the engine");
  s.metric("porosity", "1", "Porosity of the micromodel image");
  // engines.compare: LIGGGHTS against the overdamped engine on a window of the scene (first step setting).
  s.metric("engines_rms_position_difference", "um", "Engine comparison: RMS position difference over all particles and output times");
  s.metric("engines_captured_liggghts", "1", "Engine comparison: particles the LIGGGHTS engine captured");
  s.metric("engines_captured_overdamped", "1", "Engine comparison: particles the overdamped engine captured");
  s.metric("engines_capture_difference", "1", "Engine comparison: |captured by LIGGGHTS - captured by overdamped|");
  s.metric("engines_speedup", "1", "Engine comparison: LIGGGHTS wall time over the overdamped engine's");
}

void resolvedMetrics(Schema& s) {
  s.metric("final_velocity_x", "um/s", "x-velocity of particle 1 at the end, when it is still mobile (terminal velocity of a settling scene)");
  s.metric("final_velocity_y", "um/s", "y-velocity of particle 1 at the end, when it is still mobile");
  s.metric("faxen_velocity_ratio", "1", "Settling scene in plane 2D: particle 1's velocity over Faxen's cylinder midway between plates");
  s.metric("deposited", "1", "Particles deposited");
  s.metric("left", "1", "Particles that left the domain");
  s.metric("inside", "1", "Particles still mobile inside the domain");
  s.metric("retained_fraction", "1", "Deposited over all particles");
  s.metric("k_over_k0", "1", "Clean over final pressure drop, i.e. final over clean permeability (with flow)");
  s.metric("wall_time", "s", "Wall-clock time of the run");
}

}  // namespace

void declareParticleMetrics(CaseKindRegistry& registry) {
  registry.declareMetrics("particles-channel", channelMetrics);
  registry.declareMetrics("particles-micromodel", micromodelMetrics);
  registry.declareMetrics("particles-resolved", resolvedMetrics);
}

}  // namespace mmval::particles
