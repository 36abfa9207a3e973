// Schema and geometry of the particles-micromodel kind (Micromodel.hpp):
// the case keys, the mask (found, cropped, dilated, isolated pores closed).
#include <cmath>

#include <fmt/format.h>
#include <fmt/ranges.h>

#include "MicromodelDetail.hpp"
#include "CaseScene.hpp"
#include "mmval/core/DataPaths.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/particles/FlowField.hpp"
#include "mmval/simulate/Geometry.hpp"
#include "mmval/simulate/PoreSpace.hpp"

namespace mmval::particles::detail {

namespace fs = std::filesystem;

void declareMicromodel(Schema& s) {
  declareMask(s, {.mask_doc = "Binary image of the pore geometry; also looked for from the folder above the case file's"});
  s.quantity("geometry.depth", "um", "Chip depth h (the experiment's chip: 20 um)").def("20 um").positive();
  s.integer("geometry.dilate", "Grow the grains by this many pixels (disc; to lower the porosity of a design mask); 0: as drawn").def(0).min(0).max(1000);
  s.integerList("geometry.crop", "Window of the image [first column, first row, columns, rows]; absent: the whole image").optional();
  s.choice("geometry.sides", {"walls", "slip"},
           "The image's top and bottom edges. The fluid solve's are slip either way (a mask with solid wall rows has its walls in "
           "the image). walls: the particles see a wall beyond each edge. slip: both edges are mirror planes for the particles "
           "too (the pore space mirrored beyond them, so a throat between a grain and an edge is twice its distance to it; "
           "particles reaching an edge are reflected, never deposited there): a strip of a wider chip without side walls "
           "(mmval chip --wall-px 0)")
      .def("walls");
  s.choice("geometry.boundary", {"pixels", "smooth"},
           "Grain boundary of the fluid solve and of the particles' walls. smooth (the default since 2026-12-07): reconstructed below pixel "
           "resolution as the image-permeability kind's geometry.boundary = \"smooth\" (the 1/2 level of the mask smoothed by "
           "geometry.smoothing, cubic interpolation, every pixel centre kept on its side): the fluid solve cuts its cells against it, "
           "and the particles' wall distance, normal and contact are measured to its contour (docs/validation/particle-physics.md, "
           "\"Smooth grain walls\"). pixels: the mask's staircase (its concave notches hold particles a real grain would let slide "
           "past, docs/validation/paper-window.md, and the near-wall layer's rays from its corners make lines the particles converge "
           "on, so counts do not converge in the step: particle-physics.md, \"Per-particle steps\"). Closed pixels (deposits, pockets) "
           "and the side walls stay pixel squares either way")
      .def("smooth");
  s.real("geometry.smoothing", "Smooth boundary: Gaussian width in pixels applied to the mask before its 1/2 level is taken (as the "
                               "image-permeability kind's; 0.75 removes the staircase's pixel-period steps, wider rounds corners more "
                               "and narrows gaps of 1-2 pixels)")
      .def(0.75)
      .min(0)
      .max(4);
  s.quantity("flow.rate", "uL/min", "Volume flow rate through the chip (the experiment: 5 uL/min)").def("5 uL/min").nonNegative();
  s.quantity("flow.rate_width", "mm",
             "Width of the chip the flow rate goes through (the experiment's 10 mm); the simulated geometry gets the same Darcy "
             "velocity rate / (width x depth). 0: the rate goes through the simulated geometry itself")
      .def("10 mm").nonNegative();
  s.quantity("flow.darcy_velocity", "cm/min", "Darcy (superficial) velocity; given, it replaces flow.rate (Table 3 gives velocities)").optional().nonNegative();
  s.quantity("flow.max_pressure", "Pa",
             "Pressure limit of the syringe pump: when the pressure drop the set flow rate needs across the simulated geometry "
             "(inlet to outlet, Darcy's law on each fluid solve) exceeds it, the pump stalls, injection stops and the run ends there "
             "(details.pump_stall). Absent: no limit, and the pump stalls only when deposits leave no flow path")
      .optional()
      .positive();
  declareFluid(s, {.with_temperature = true});
  s.quantity("particles.diameter", "um", "Fine particle diameter (the experiment: ~5 um)").def("5 um").positive();
  s.quantityList("particles.diameters", "um",
                 "Several size classes (polydisperse fines, paper Table 3); given, they replace particles.diameter. Classes do not "
                 "see each other's particles in contacts (dilute), but all see every deposit through the flow and the closed pixels")
      .optional();
  s.realList("particles.size_fractions", "Number fraction of each size class (sums to 1; Table 3 does not say whether by number or volume)").optional();
  s.integer("particles.count", "Simulated particles injected over the injection time; 0: from the concentration and the flow").def(0).min(0).max(100000000);
  s.quantity("particles.density", "g/cm3", "Particle density (polystyrene 1.05)").def("1.05 g/cm3").positive();
  s.quantity("particles.concentration", "mL^-1", "Number concentration of the injected suspension (the experiment: 2.9e7 per mL)")
      .def("2.9e7 mL^-1").nonNegative();
  s.real("particles.sample_fraction",
         "Fraction of the suspension's particles that is simulated (a random sample; 1: all). Each simulated particle then "
         "stands for 1 / sample_fraction real ones in the deposit volume when coupling.parcel_weighting is on")
      .def(1.0).min(1e-9).max(1.0);
  s.quantity("particles.injection_time", "s", "Particles enter during [0, injection_time]; 0: the whole run").def(0.0).nonNegative();
  s.choice("particles.engine", {"auto", "overdamped"},
           "Particle engine. auto: from the scene's numbers, which must allow the overdamped engine (LIGGGHTS cannot run this "
           "scene: its contact time step, set by the particles' stiffness and mass, is many orders below a 20-minute run; "
           "SceneSelection.hpp); overdamped: forced, with the automatic choice recorded")
      .def("auto");
  declarePhysicsAndDeposition(s, 1e-20);
  const StrainingModel straining;
  s.boolean("deposition.straining",
            "Straining: a particle the flow holds in a passage narrower than itself (its moves refused, or pushed off two walls "
            "closing in ahead of it) for deposition.straining_time is retained there, counted as strained (its own surface, next "
            "to the attached ones) and a deposit like them; false: it stays mobile and counts as inside")
      .def(straining.enabled);
  s.quantity("deposition.straining_time", "s",
             "How long a particle must stay held in a throat before it counts as strained (default 1 s: ~300 times the time to "
             "advect a radius at the chip's pore velocity, < 0.1 % of the run)")
      .def(straining.time)
      .positive();
  s.choice("coupling.mode", {"four-way", "one-way"},
           "four-way: deposits close pixel columns or thin the aperture and the flow is solved again; one-way: the flow never changes")
      .def("four-way");
  s.choice("coupling.plate_deposits", {"layer", "column"},
           "Deposits away from grains (on a plate): layer: a layer of coupling.layer_packing thins the pixel's aperture (the "
           "solver's local depth), at most one monolayer per deposit and pixel, and the pixel closes below coupling.min_aperture; "
           "column: they fill pixel columns like deposits at grains (coupling.fill_fraction)")
      .def("layer");
  s.real("coupling.fill_fraction", "A pore pixel's column closes when deposits at grains fill this fraction of its volume").def(0.5).min(0.01).max(1.0);
  s.real("coupling.layer_packing",
         "Solid volume fraction of a plate deposit layer. Default: a random (RSA) monolayer at its jamming coverage 0.547 "
         "(Feder 1980) holds 0.547 x 2/3 d of solid per area, so a full monolayer is one diameter d thick")
      .def(0.547 * 2.0 / 3.0).min(0.05).max(1.0);
  s.quantity("coupling.min_aperture", "um",
             "Layer mode: a pixel closes when its aperture falls below this; 0: the largest particle diameter (no particle passes)")
      .def("0 um").nonNegative();
  s.real("coupling.resolve_threshold",
         "Re-solve the flow when the aperture lost since the last solve, summed over pore pixels in whole columns (a closed "
         "pixel counts 1, a layer t thick t / depth), reaches this fraction of the pore pixels")
      .def(1e-3).min(0.0).max(1.0);
  s.boolean("coupling.final_resolve",
            "Solve the flow once more at the last frame when any aperture was lost since the last re-solve, so that the final "
            "k / k0 (permeability_reduction) includes every deposit and not only those up to the last threshold crossing")
      .def(false);
  s.boolean("coupling.parcel_weighting", "A deposit's volume is that of the 1 / sample_fraction particles it stands for").def(true);
  s.real("numerics.cells_per_pixel", "Fluid grid cells per image pixel").def(0.5).min(0.05).max(4);
  s.choice("numerics.resolve", {"warm", "direct"},
           "Fluid re-solves. warm: one solver kept for the run, the first solve's LU ordering and symbolic analysis reused by every "
           "re-solve (the same answer bit for bit; ~30 % less solve CPU on the full scene); direct: a new solver per solve")
      .def("warm");
  s.choice("numerics.resolve_pattern", {"fixed", "rebuild"},
           "Warm re-solves (numerics.resolve = warm). fixed: the clean chip's matrix pattern is kept for the run (a closed face an "
           "identity row, a closed cell pinned, inside their old stencils), so a re-solve is a numeric LU with the clean chip's "
           "ordering and symbolic analysis (about half the time of a rebuilt solve at 1 cell per pixel); a re-solve that does not fit the pattern takes a new "
           "solver. The answer equals the rebuilt solver's to rounding (~1e-12), not bit for bit. rebuild: a matrix of another "
           "pattern is ordered and analysed anew, bit for bit a new solver's")
      .def("fixed");
  s.real("numerics.max_step_fraction", "Largest particle displacement per step, in radii").def(0.5).min(1e-4).max(1);
  declareEngineNumerics(s);
  s.quantity("engines.compare_window", "s",
             "Before the run: the overdamped engine against LIGGGHTS (Hertz contacts, grains as an STL mesh wall) on a shared window of "
             "this scene's flow, from the same particles spread over the pore space, without Brownian motion; 0: no comparison")
      .def("0 s")
      .nonNegative();
  s.integer("engines.compare_particles", "Particles of that window").def(40).min(1).max(2000);
  s.real("engines.compare_gravity_factor", "Gravity multiplied by this in the window, so that particles reach the bottom plate within it").def(100).min(0).max(1e5);
  s.quantity("engines.compare_youngs_modulus", "Pa", "Young's modulus of the window's particles (softened, as the paper does, for a longer DEM step)")
      .def("1e5 Pa")
      .positive();
  s.realList("engines.compare_step_fractions", "Overdamped step settings compared (largest displacement per step, radii); empty: the scene's")
      .optional();
  s.quantityList("analysis.retention_window", "s",
                 "[from, to]: also report the retention of the particles injected in (from, to], those retained by `to` over those "
                 "injected (window_retained_fraction); a window past the end of the run is cut at it")
      .optional()
      .nonNegative();
  s.choice("analysis.table3_case", {"I", "II", "III", "IV", "V"},
           "The case of Table 3 of Elrahmani et al. (2022) this scene reproduces; written to details.table3_case, from which the report's "
           "Table 3 takes the paper's values. Absent: not a Table 3 case")
      .optional();
  s.quantity("run.duration", "s", "Physical time simulated").def("20 min").positive();
  s.quantity("run.output_interval", "s", "Output (frame) interval").def("1 s").positive();
  s.integer("run.seed", "Random seed (Brownian motion, injection)").def(1).min(0);
  s.integer("run.checkpoint_every", "Write checkpoint.bin at the first output frame after this many engine steps (0: never)")
      .def(200000).min(0);
  s.integer("run.stop_after_frames", "Stop (as if killed) after this many output frames, leaving a checkpoint (0: run to the end; tests)")
      .def(0).min(0);
}

/// Grains grown by a disc of `radius_px` pixels (Euclidean, centre to centre).
PixelMask dilate(const PixelMask& m, int radius_px) {
  if (radius_px <= 0) return m;
  const int rows = static_cast<int>(m.rows()), cols = static_cast<int>(m.cols());
  GriddedFlow g(cols, rows, 0, 0, 1.0, 1.0);
  const auto n = static_cast<std::size_t>(rows) * cols;
  std::vector<double> zero(n, 0.0), h(n, 1.0);
  std::vector<std::uint8_t> s(n);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) s[static_cast<std::size_t>(r) * cols + c] = m(r, c) ? 1 : 0;
  g.update(zero, zero, h, s);
  PixelMask out = m;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      if (!m(r, c) && g.wallDistance(c, r) + 0.5 <= radius_px + 1e-9) out(r, c) = true;
  return out;
}

fs::path maskPath(const Case& c) {
  const fs::path p = c.path("geometry.mask");
  if (pathExists(p)) return p;
  // Also relative to the folder above the case file (the repository for cases/).
  const fs::path raw = c.text("geometry.mask");
  if (raw.is_relative()) {
    const fs::path q = c.file().parent_path().parent_path() / raw;
    if (pathExists(q)) return q;
    throw InputError(c.where("geometry.mask"), "mask image not found", raw.string(),
                     fmt::format("an image at {} or {}", p.string(), q.string()));
  }
  throw InputError(c.where("geometry.mask"), "mask image not found", raw.string(), "an existing PNG/TIFF file");
}

PixelMask loadGeometry(const Case& c, nlohmann::json& details, double& porosity) {
  const fs::path file = maskPath(c);
  // The image's size from its header, before decoding. simulate::readMask + analysePoreSpace peak
  // at 12 B per pixel (measured: a 6000 x 6000 all-pore PNG as image-permeability's mask, 533 MB
  // peak against 111 MB start-up, /usr/bin/time -v); the crop and dilation copies add 2 B.
  constexpr double kMaskBytesPerPixel = 14;
  requireImageWithin(file, c.where("geometry.mask"), maxMemoryBytes(c), kMaskBytesPerPixel,
                     "a smaller image: crop or downscale it (geometry.crop applies after reading the whole image)");
  PixelMask raw;
  try {
    raw = simulate::readMask(file, c.text("geometry.grains") == "dark");
  } catch (const std::exception& e) {
    throw InputError(c.where("geometry.mask"), e.what(), file.string(), "a readable PNG/TIFF image");
  }
  details["image"] = file.string();
  details["image_pixels"] = {raw.cols(), raw.rows()};
  if (c.has("geometry.crop")) {
    const auto& v = c.integers("geometry.crop");
    if (v.size() != 4 || v[0] < 0 || v[1] < 0 || v[2] < 2 || v[3] < 2 || v[0] + v[2] > raw.cols() || v[1] + v[3] > raw.rows())
      throw InputError(c.where("geometry.crop"), "window outside the image or smaller than 2 x 2 pixels",
                       fmt::format("{}", fmt::join(v, ", ")),
                       fmt::format("[first column, first row, columns, rows] inside the {} x {} image", raw.cols(), raw.rows()));
    raw = PixelMask(raw.block(v[1], v[0], v[3], v[2]));
    details["crop"] = v;
  }
  if (const auto r = c.integer("geometry.dilate"); r > 0) {
    raw = dilate(raw, static_cast<int>(r));
    details["dilated_px"] = r;
  }
  simulate::PoreSpaceReport pores;
  try {
    pores = simulate::analysePoreSpace(raw);
  } catch (const simulate::NoFlowPath& e) {
    throw InputError(c.where("geometry.mask"), e.what(), file.string(),
                     "a mask (or crop window) with a connected pore path from the left to the right edge (check geometry.grains)");
  }
  details["porosity_total"] = pores.porosity_total;
  details["porosity_connected"] = pores.porosity_connected;
  details["pore_components"] = pores.components;
  porosity = pores.porosity_connected;
  return pores.solid_connected;
}

}  // namespace mmval::particles::detail
