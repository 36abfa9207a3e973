// "particles-resolved": particles that span many fluid cells, moved through
// creeping flow by the resolved immersed boundary (the coupling mode SceneSelection
// picks for d/dx >= ~8). Each particle is a rigid disk in the 2D flow (a cylinder
// through the plane, or with channel.depth > 0 a pillar spanning a Hele-Shaw
// chip); its motion is the Stokes mobility problem of ResolvedStokes: no
// drag law, no wall correction, no lubrication model: the flow between the
// particle, the walls, the obstacles and the other particles is solved on the
// grid. Particle inertia is left out (the overdamped limit: St << 1 is what
// makes a scene Stokes flow in the first place).
//
// Time stepping: explicit midpoint (two mobility solves per step) with the
// step set by the fastest particle moving at most numerics.max_step_fraction
// of a cell. Contacts: surfaces closer than numerics.contact_gap (in cells;
// the immersed boundary needs a fluid node between two surfaces) are held
// apart by moving the particle back along the normal, and a particle within
// deposition.capture_distance of a wall, an obstacle or a deposited particle
// sticks there and becomes a fixed body: the flow and the pressure drop then
// feel it (four-way coupling; permeability.csv).
// Outputs retention.csv and permeability.csv follow the one schema of
// mmval/core/OutputTables.hpp: every particle is injected at t = 0, and k is
// the channel's Darcy permeability mu U L / dp (U the mean inflow speed, L the
// distance between the first and last cell centres along x, where pressureDrop
// measures dp), so k/k0 = dp0/dp.
#include <chrono>

#include "CaseScene.hpp"
#include "ResolvedStages.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/particles/Kinds.hpp"
#include "mmval/simulate/ResolvedStokes.hpp"

namespace mmval::particles {

namespace {

namespace sim = mmval::simulate;
using namespace resolved;

void declareResolved(Schema& s) {
  declareMask(s, {.mask_doc = "Grains from a binary image of the pore geometry, also looked for from the folder above the case file's; it then sets "
                             "the channel's length and width (absent: a plain channel with channel.length x channel.width)",
                 .pixel_default = "1 um",
                 .optional = true});
  s.integer("geometry.dilate", "Grow the grains by this many pixels; 0: as drawn").def(0).min(0).max(1000);
  s.integerList("geometry.crop", "Window of the image [first column, first row, columns, rows]; absent: the whole image").optional();
  s.quantity("channel.length", "um", "Channel length along x (inlet x = 0, outlet x = length)").def("160 um").positive();
  s.quantity("channel.width", "um", "Channel width (walls at y = 0 and y = width)").def("40 um").positive();
  s.quantity("channel.mean_velocity", "mm/s",
             "Mean speed of the parabolic inflow at x = 0 (open outlet at x = length); 0: a closed box of fluid at rest")
      .def(0.0)
      .nonNegative();
  s.quantity("channel.depth", "um", "Hele-Shaw depth (friction -12 mu u / h^2; the disks then span the depth); 0: plane 2D").def(0.0).nonNegative();
  declareFluid(s, {});
  s.quantity("particles.diameter", "um", "Particle (disk) diameter").def("10 um").positive();
  s.quantity("particles.density", "g/cm3", "Particle density").def("1.05 g/cm3").positive();
  s.quantityList("particles.x", "um", "Start x of each particle's centre").def(std::vector<double>{80e-6});
  s.quantityList("particles.y", "um", "Start y of each particle's centre").def(std::vector<double>{20e-6});
  s.quantityList("obstacles.x", "um", "Centres x of fixed circular obstacles (grains)").def(std::vector<double>{});
  s.quantityList("obstacles.y", "um", "Centres y of the obstacles").def(std::vector<double>{});
  s.quantityList("obstacles.diameter", "um", "Diameters of the obstacles").def(std::vector<double>{});
  s.quantity("physics.gravity_x", "m/s2", "Gravity along +x (a vertical channel: -9.81)").def(0.0);
  s.quantity("physics.gravity_y", "m/s2", "Gravity along +y (towards the wall y = 0: -9.81)").def(0.0);
  s.quantity("deposition.capture_distance", "um", "Surface gap at which a particle sticks to a wall, obstacle or deposit (0: never)").def(0.0).nonNegative();
  s.integer("numerics.cells_per_diameter", "Grid cells across a particle diameter (the paper's rule: ~8 at least)").def(16).min(4).max(200);
  s.real("numerics.max_step_fraction", "Largest particle displacement per step near a surface, in cells (up to 4 x this in open pores)").def(0.5).min(0.01).max(2);
  s.real("numerics.contact_gap", "Smallest surface gap kept between a moving particle and any surface, in cells").def(1.0).min(0.5).max(4);
  s.quantity("run.duration", "s", "Physical time simulated").def("5 s").positive();
  s.quantity("run.output_interval", "s", "Output (frame) interval").def("0.5 s").positive();
  s.quantity("output.pixel_size", "um", "Pixel size for the pixel columns of trajectories.csv (0: none)").def(0.0).nonNegative();
  s.integer("run.checkpoint_every", "Write checkpoint.json every this many output frames (0: never); `mmval run --resume` continues from it").def(10).min(0);
  s.integer("run.stop_after_frames", "Stop (as if killed) after this many output frames, leaving a checkpoint (0: run to the end; tests)").def(0).min(0);
}

/// The run as its stages (ResolvedStages.hpp): set-up -> clean channel -> transport -> files -> result.
RunOutput runResolved(const Case& c, const RunContext& ctx) {
  outputFrames(c);  // a run whose frames cannot fit in memory is refused before the mask is read
  Setup setup = setUpResolved(c);
  Scene& sc = setup.scene;
  sim::ResolvedStokes fluid(setup.problem);
  const double dp0 = cleanPressureDrop(fluid, sc);
  // Darcy: k = mu U L / dp over the span pressureDrop measures (first to last cell centre).
  const sim::Axis& x = setup.problem.x;
  const FrameScales scales{setup.viscosity_pa_s * sc.U * (x.centre(x.cells() - 1) - x.centre(0)), dp0};
  const auto t0 = std::chrono::steady_clock::now();
  Transport tr = transport(c, ctx, setup.stepping, sc, fluid, scales);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  const std::vector<std::string> files = writeResolvedFiles(ctx.out_dir, tr, sc, fluid, c.quantity("output.pixel_size"));
  RunOutput out = resolvedResult(setup, tr, sc, fluid, dp0, wall);
  out.files = files;
  return out;
}

}  // namespace

CaseKind resolvedKind() {
  CaseKind k;
  k.name = "particles-resolved";
  k.summary = "Particles spanning many cells moved through creeping flow by the resolved immersed boundary (Stokes mobility of rigid disks): "
              "trajectories, attachment, permeability over time";
  k.declare = declareResolved;
  k.run = runResolved;
  return k;
}

}  // namespace mmval::particles
