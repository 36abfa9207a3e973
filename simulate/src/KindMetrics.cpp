#include "mmval/simulate/KindMetrics.hpp"

namespace mmval::simulate {

namespace {

void channelMetrics(Schema& s) {
  s.metric("flow_rate_per_depth", "m2/s", "Plane 2D drives: flow rate per unit depth through the outlet (exact: G W^3 / (12 mu))");
  s.metric("flow_rate", "uL/min", "Depth-averaged duct: volumetric flow rate through the outlet");
  s.metric("flow_rate_factor", "1", "Depth-averaged duct: flow rate over the plates' G h^3 W / (12 mu)");
  s.metric("model_flow_rate_factor", "1", "Depth-averaged duct: the continuous model's exact flow-rate factor (what flow_rate_factor converges to)");
  s.metric("pressure_gradient", "Pa/m", "Velocity drive: developed pressure gradient between 1/4 and 3/4 of the length");
  s.metric("pressure_gradient_exact", "Pa/m", "Velocity drive, plane 2D: plane Poiseuille's 12 mu U / W^2");
}

void periodicArrayMetrics(Schema& s) {
  s.metric("F_star", "1", "Dimensionless drag F / (mu U_darcy) per unit length (Sangani & Acrivos 1982)");
  s.metric("k_over_L2", "1", "Permeability over the squared cell size, 1 / F*");
  s.metric("permeability", "m2", "Permeability L^2 / F*");
  s.metric("drag_balance", "1", "mmval: the cylinder's drag over the driving force G L^2 (1: forces balance)");
}

void cylinderChannelMetrics(Schema& s) {
  // Steady (both solvers; torque_coefficient mmval only).
  s.metric("c_D", "1", "Drag coefficient 2 F_x / (rho U_ref^2 L_ref)");
  s.metric("c_L", "1", "Lift coefficient 2 F_y / (rho U_ref^2 L_ref)");
  s.metric("torque_coefficient", "1", "mmval: torque coefficient 2 T / (rho U_ref^2 L_ref^2)");
  s.metric("dp", "Pa", "Pressure difference between probes.pressure_a and probes.pressure_b (when both are given)");
  // Unsteady (numerics.mode = "unsteady"), over the statistics window.
  s.metric("c_D_max", "1", "Unsteady: largest drag coefficient");
  s.metric("c_D_min", "1", "Unsteady, mmval: smallest drag coefficient");
  s.metric("c_D_mean", "1", "Unsteady: mean drag coefficient");
  s.metric("c_L_max", "1", "Unsteady: largest lift coefficient");
  s.metric("c_L_min", "1", "Unsteady, mmval: smallest lift coefficient");
  s.metric("c_L_amplitude", "1", "Unsteady, mmval: half the peak-to-peak lift coefficient over the statistics window");
  s.metric("c_L_amplitude_drift", "1", "Unsteady, mmval: relative growth of the lift amplitude over the last period (0: periodic state reached)");
  s.metric("St", "1", "Unsteady: Strouhal number f L_ref / U_ref of the lift");
  s.metric("frequency", "Hz", "Unsteady, mmval: shedding frequency of the lift");
}

void imagePermeabilityMetrics(Schema& s) {
  s.metric("permeability", "D", "Permeability of the chip: depth-averaged model if run, else 3D, else 2D (OpenFOAM: its mesh's)");
  s.metric("permeability_2d", "D", "Permeability of the plane 2D model (per unit depth)");
  s.metric("permeability_depth_averaged", "D", "Permeability of the depth-averaged (Hele-Shaw friction) model");
  s.metric("depth_model_ratio", "1", "Depth-averaged over 2D permeability");
  // A cells_per_pixel_levels ladder (Celik et al. 2008, J. Fluids Eng. 130 078001).
  s.metric("permeability_2d_extrapolated", "D", "Ladder: plane 2D permeability Richardson-extrapolated with the observed order (monotone convergence)");
  s.metric("permeability_2d_observed_order", "1", "Ladder: observed order of the plane 2D permeability from the three finest levels");
  s.metric("permeability_2d_gci", "1", "Ladder: grid convergence index of the finest plane 2D permeability, relative (Roache; Fs 1.25, 3 without an observed order)");
  s.metric("permeability_depth_averaged_extrapolated", "D", "Ladder: depth-averaged permeability Richardson-extrapolated with the observed order");
  s.metric("permeability_depth_averaged_observed_order", "1", "Ladder: observed order of the depth-averaged permeability from the three finest levels");
  s.metric("permeability_depth_averaged_gci", "1", "Ladder: grid convergence index of the finest depth-averaged permeability, relative");
  s.metric("permeability_3d", "D", "Permeability of the coarse 3D Stokes model, finest level");
  s.metric("permeability_3d_extrapolated", "D", "3D permeability Richardson-extrapolated over the last two depth levels");
  s.metric("porosity_3d_grid", "1", "Connected porosity of the block-averaged 3D grid");
  s.metric("k_3d_over_depth_averaged", "1", "3D over depth-averaged permeability");
  s.metric("porosity_total", "1", "Pore pixels over all pixels of the mask");
  s.metric("porosity_connected", "1", "Pore pixels connected inlet to outlet over all pixels");
  s.metric("porosity_mesh", "1", "OpenFOAM: fluid volume of the mesh over the domain's");
}

}  // namespace

void declareFluidMetrics(CaseKindRegistry& registry) {
  registry.declareMetrics("channel", channelMetrics);
  registry.declareMetrics("periodic-array", periodicArrayMetrics);
  registry.declareMetrics("cylinder-channel", cylinderChannelMetrics);
  registry.declareMetrics("image-permeability", imagePermeabilityMetrics);
}

}  // namespace mmval::simulate
