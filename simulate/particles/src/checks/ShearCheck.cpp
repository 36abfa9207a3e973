// Check 6: a free sphere near a wall in simple shear, the overdamped engine
// against Goldman, Cox & Brenner's exact tables (reference-data/goldman-cox-brenner.toml).
// The scene isolates the shear: a neutrally buoyant, non-Brownian, non-sticky
// sphere in a chip so deep (h = depth_over_radius radii) that near the bottom plate
// the parabolic profile is the simple shear gamma z with gamma = 6 u_mean / h
// (relative departure z/h, < 1e-3 at the heights checked by default) and the top
// plate is too far to matter. At each of GCB's heights the runner takes the
// engine's deterministic velocity (driftVelocity) and the displacement of a
// particle advanced over a short interval, and compares U / (gamma z) with the
// table. The rotation rate (the engine does not carry rotation) and the parallel
// drag factor come from the model the engine uses and are compared the same way.
#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "PhysicsChecks.hpp"
#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/DataPaths.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles::checks {

namespace {

constexpr const char* kKind = "physics-near-wall-shear";
constexpr const char* kReferenceFile = "goldman-cox-brenner.toml";

// GCB's table heights h/a and the metric suffix that names each.
struct Height {
  double h_over_a;
  const char* tag;
};
constexpr Height kHeights[] = {{10.0677, "10p0677"}, {3.7622, "3p7622"},     {2.3524, "2p3524"},     {1.5431, "1p5431"},
                               {1.1276, "1p1276"},   {1.0453, "1p0453"},     {1.005004, "1p005004"}, {1.003202, "1p003202"}};

void declareShear(Schema& s) {
  s.quantity("particles.diameter", "um", "Sphere diameter").def("5 um").positive();
  declareFluid(s, {.with_density = false});
  s.quantity("shear.wall_shear_rate", "1/s", "Shear rate gamma at the bottom plate (6 u_mean / h of the depth profile)").def("100 1/s").positive();
  s.real("shear.depth_over_radius", "Chip depth in sphere radii: deep, so that the profile near the bottom plate is simple shear")
      .def(1.0e4)
      .min(1.0e3);
  s.real("shear.advance_radii", "The advanced particles travel about this many radii (a check that the engine moves them at the drift velocity)")
      .def(0.5)
      .positive()
      .max(10.0);
}

void shearMetrics(Schema& s) {
  s.metric("U_over_gamma_h_at_*", "1", "Engine's free-sphere velocity over gamma h at h/a = the suffix (p for the decimal point), one per table height");
  s.metric("velocity_max_error", "1", "Largest |U/(gamma h) - GCB| / GCB over the eight heights (engine's drift velocity)");
  s.metric("velocity_max_error_without_lag", "1", "The same for a sphere moving with the fluid at its centre (the engine before this check, for comparison)");
  s.metric("advance_max_difference", "1", "Largest |displacement / time - drift velocity| / drift velocity of particles advanced by the engine");
  s.metric("rotation_max_error", "1", "Largest |Omega/gamma - GCB| / GCB over the heights (the engine's near-wall model)");
  s.metric("drag_max_error", "1", "Largest |lambda_par - GCB| / GCB over the heights: the engine's parallel drag factor against the torque-free value");
  s.metric("drag_max_error_faxen", "1", "The same for Faxen's series alone (the engine's former parallel drag), for comparison");
}

double tableValue(const ReferenceFile& ref, const std::string& quantity, double h_over_a) {
  const auto rows = ref.find(quantity, AtMap{{"h_over_a", h_over_a}});
  if (rows.size() != 1 || !rows.front()->value)
    throw InputError(InputLocation{ref.path.string(), 0, 0, quantity},
                     fmt::format("expected one value of {} at h_over_a = {}", quantity, h_over_a), fmt::format("{} rows", rows.size()));
  return *rows.front()->value;
}

RunOutput runShear(const Case& c, const RunContext& ctx) {
  const std::filesystem::path dir = referenceDataDirectory();
  if (dir.empty())
    throw InputError(InputLocation{}, fmt::format("reference data not found (looked in {})", dataDirectorySearched()), "",
                     fmt::format("a folder holding reference-data/{}", kReferenceFile));
  const ReferenceFile& ref = loadReferenceFile(dir / kReferenceFile);

  SceneConfig cfg;
  cfg.particle.diameter = c.quantity("particles.diameter");
  cfg.particle.density = cfg.fluid.density;  // neutrally buoyant: no settling
  cfg.fluid.viscosity = c.quantity("fluid.viscosity");
  cfg.gravity = 0.0;
  cfg.brownian = false;
  cfg.attachment.capture_distance = 0.0;  // nothing sticks
  cfg.attachment.hamaker = 0.0;
  cfg.max_step_fraction = 0.05;
  const double a = cfg.particle.radius(), gamma = c.quantity("shear.wall_shear_rate");
  const double h = c.real("shear.depth_over_radius") * a, u_mean = gamma * h / 6.0;
  auto flow = std::make_shared<UniformFlow>(Vec2(u_mean, 0.0), h, Bounds2{-1.0, 1.0, -1.0, 1.0});
  OverdampedEngine engine(flow, cfg);

  // One particle per height, 4 diameters apart across the flow.
  std::vector<Vec3> start;
  for (std::size_t k = 0; k < std::size(kHeights); ++k) start.emplace_back(0.0, 8.0 * a * static_cast<double>(k), kHeights[k].h_over_a * a);
  engine.insert(start);
  // The slowest (nearest) particle travels advance_radii radii.
  const double t_end = c.real("shear.advance_radii") * a / (0.4 * gamma * a);
  engine.advance(t_end);
  const auto moved = engine.particles();

  RunOutput out;
  double v_err = 0, v_err_fluid = 0, adv = 0, o_err = 0, d_err = 0, d_err_faxen = 0;
  std::ostringstream csv;
  csv << "h_over_a,U_over_gamma_h_gcb,U_over_gamma_h_engine,U_over_gamma_h_advanced,Omega_over_gamma_gcb,Omega_over_gamma_model,"
         "lambda_par_gcb,lambda_par_engine,lambda_par_faxen\n";
  nlohmann::json rows = nlohmann::json::array();
  for (std::size_t k = 0; k < std::size(kHeights); ++k) {
    const double s = kHeights[k].h_over_a, z = s * a;
    const double u_ref = tableValue(ref, "U_over_gamma_h", s), o_ref = tableValue(ref, "Omega_over_gamma", s);
    const double l_ref = tableValue(ref, "lambda_free", s);
    const double u_eng = engine.driftVelocity(start[k]).x() / (gamma * z);
    const double u_adv = (moved[k].x.x() - start[k].x()) / t_end / (gamma * z);
    const double u_fluid = engine.model().fluidVelocity(start[k]).x() / (gamma * z);
    const double o_mod = freeSphereInShear(a, z).rotation;
    const double l_eng = engine.model().hindrance(z, h).first, l_fax = faxenParallel(a, z);
    v_err = std::max(v_err, std::abs(u_eng - u_ref) / u_ref);
    v_err_fluid = std::max(v_err_fluid, std::abs(u_fluid - u_ref) / u_ref);
    adv = std::max(adv, std::abs(u_adv - u_eng) / u_eng);
    o_err = std::max(o_err, std::abs(o_mod - o_ref) / o_ref);
    d_err = std::max(d_err, std::abs(l_eng - l_ref) / l_ref);
    d_err_faxen = std::max(d_err_faxen, std::abs(l_fax - l_ref) / l_ref);
    out.metrics[fmt::format("U_over_gamma_h_at_{}", kHeights[k].tag)] = u_eng;
    csv << fmt::format("{},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f}\n", s, u_ref, u_eng, u_adv, o_ref, o_mod, l_ref, l_eng, l_fax);
    rows.push_back({{"h_over_a", s}, {"U_over_gamma_h", {{"gcb", u_ref}, {"engine", u_eng}, {"advanced", u_adv}, {"with_fluid", u_fluid}}},
                    {"Omega_over_gamma", {{"gcb", o_ref}, {"model", o_mod}}},
                    {"lambda_par", {{"gcb", l_ref}, {"engine", l_eng}, {"faxen", l_fax}}}});
  }
  out.metrics["velocity_max_error"] = v_err;
  out.metrics["velocity_max_error_without_lag"] = v_err_fluid;
  out.metrics["advance_max_difference"] = adv;
  out.metrics["rotation_max_error"] = o_err;
  out.metrics["drag_max_error"] = d_err;
  out.metrics["drag_max_error_faxen"] = d_err_faxen;
  writeFileAtomic(ctx.out_dir / "near-wall-shear.csv", csv.str());
  out.files.push_back("near-wall-shear.csv");
  out.details["heights"] = rows;
  setDetail(out.details, DetailField::reference,
            {{"description", "Goldman, Cox & Brenner (1967) exact tables of a sphere near a plane wall; a free sphere's U / (gamma h) and "
                             "Omega / gamma from their force and torque balance"},
             {"file", (dir / kReferenceFile).string()}});
  out.details["scene"] = {{"radius_um", a * 1e6}, {"depth_um", h * 1e6}, {"wall_shear_rate_1_s", gamma}, {"advance_time_s", t_end}};
  out.details["engine_settings"] = engine.describe();
  return out;
}

}  // namespace

void registerShearChecks(CaseKindRegistry& registry) {
  CaseKind k;
  k.name = kKind;
  k.summary = "Check 6: a free sphere near a wall in simple shear, the overdamped engine's velocity (and its model's rotation and "
              "parallel drag) against Goldman, Cox & Brenner's (1967) tables";
  k.declare = declareShear;
  k.run = runShear;
  registry.add(k);
  registry.declareMetrics(kKind, shearMetrics);
}

}  // namespace mmval::particles::checks
