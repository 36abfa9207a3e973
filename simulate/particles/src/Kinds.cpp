#include "mmval/particles/Kinds.hpp"
#include "mmval/particles/KindMetrics.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

#include "CaseScene.hpp"
#include "checks/PhysicsChecks.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/OutputTables.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/core/Tracks.hpp"
#include "mmval/core/VtkWriter.hpp"
#include "mmval/core/SchemaBlocks.hpp"
#include "mmval/particles/EngineFactory.hpp"
#include "mmval/particles/Micromodel.hpp"
#include "mmval/particles/SceneSelection.hpp"

namespace mmval::particles {

namespace {

void declareChannel(Schema& s) {
  s.quantity("channel.length", "um", "Channel length along the flow (inlet x = 0, outlet x = length)").def("1000 um").positive();
  s.quantity("channel.width", "um", "Channel width (side walls at y = 0 and y = width)").def("200 um").positive();
  s.quantity("channel.depth", "um", "Chip depth between the plates").def("20 um").positive();
  s.quantity("channel.mean_velocity", "mm/s", "Depth-averaged fluid speed (5 uL/min through the paper's chip: 0.72 mm/s)").def("0.72 mm/s").nonNegative();
  declareFluid(s, {.with_temperature = true});
  s.quantity("particles.diameter", "um", "Particle diameter").def("5 um").positive();
  s.quantity("particles.density", "g/cm3", "Particle density (polystyrene 1.05)").def("1.05 g/cm3").positive();
  s.integer("particles.count", "Particles injected at the inlet").def(100).min(0).max(10000000);
  s.quantity("particles.injection_time", "s", "Particles are injected evenly over [0, injection_time]").def("1 s").positive();
  s.choice("particles.engine", {"auto", "overdamped", "liggghts"}, "Particle engine; auto picks from the scene's dimensionless numbers").def("auto");
  s.quantity("particles.youngs_modulus", "Pa", "Young's modulus (LIGGGHTS engine; softened)").def("1e6 Pa").min(1e3).max(1e12);
  s.real("particles.poisson_ratio", "Poisson's ratio (LIGGGHTS engine)").def(0.3).min(0.01).max(0.49);
  s.real("particles.restitution", "Coefficient of restitution (LIGGGHTS engine)").def(0.5).min(0.02).max(1);
  s.real("particles.friction", "Coefficient of friction (LIGGGHTS engine)").def(0.5).min(0).max(10);
  s.quantity("particles.cohesion_energy_density", "J/m3", "sjkr cohesion (LIGGGHTS engine; 0: off)").def(0.0).nonNegative();
  declarePhysicsAndDeposition(s, 0.0);
  s.quantity("run.duration", "s", "Physical time simulated").def("2 s").positive();
  s.quantity("run.output_interval", "s", "Output (frame) interval").def("0.05 s").positive();
  s.integer("run.seed", "Random seed (Brownian motion, injection)").def(1).min(0);
  s.real("numerics.max_step_fraction", "Overdamped engine: largest displacement per step, in radii").def(0.1).min(1e-4).max(1);
  declareEngineNumerics(s);
  s.real("numerics.rayleigh_fraction", "LIGGGHTS engine: DEM step as a fraction of the Rayleigh time").def(0.1).min(1e-3).max(0.3);
  s.quantity("output.pixel_size", "um", "Pixel size for the pixel columns of trajectories.csv (0: none)").def(0.0).nonNegative();
}

SceneConfig sceneFromCase(const Case& c, const EngineChoice& choice, const std::filesystem::path& work_dir) {
  SceneConfig s;
  s.fluid.viscosity = c.quantity("fluid.viscosity");
  s.fluid.density = c.quantity("fluid.density");
  s.fluid.temperature = c.quantity("fluid.temperature");
  s.particle.diameter = c.quantity("particles.diameter");
  s.particle.density = c.quantity("particles.density");
  s.particle.youngs_modulus = c.quantity("particles.youngs_modulus");
  s.particle.poisson_ratio = c.real("particles.poisson_ratio");
  s.particle.restitution = c.real("particles.restitution");
  s.particle.friction = c.real("particles.friction");
  s.cohesion_energy_density = c.quantity("particles.cohesion_energy_density");
  s.gravity = c.quantity("physics.gravity");
  physicsAndDepositionFromCase(c, choice, s);
  s.seed = static_cast<std::uint64_t>(c.integer("run.seed"));
  s.max_step_fraction = c.real("numerics.max_step_fraction");
  engineNumericsFromCase(c, s);
  s.rayleigh_fraction = c.real("numerics.rayleigh_fraction");
  s.work_dir = work_dir;
  return s;
}

RunOutput runChannel(const Case& c, const RunContext& ctx) {
  const double L = c.quantity("channel.length"), W = c.quantity("channel.width"), h = c.quantity("channel.depth");
  const double U = c.quantity("channel.mean_velocity");
  const double d = c.quantity("particles.diameter");
  if (!(h > d)) throw InputError(c.where("particles.diameter"), "particles do not fit in the chip depth", fmt::format("{:.3g} um", d * 1e6), fmt::format("< depth {:.3g} um", h * 1e6));
  if (!(W > d)) throw InputError(c.where("channel.width"), "particles do not fit across the channel", fmt::format("{:.3g} um", W * 1e6), fmt::format("> diameter {:.3g} um", d * 1e6));
  const auto count = c.integer("particles.count");
  const double t_inj = c.quantity("particles.injection_time"), duration = c.quantity("run.duration"), dt_out = c.quantity("run.output_interval");
  if (dt_out > duration) throw InputError(c.where("run.output_interval"), "longer than the run", fmt::format("{:g} s", dt_out), fmt::format("<= run.duration ({:g} s)", duration));
  const std::int64_t frames = outputFrames(c);

  SceneScales scales;
  scales.fluid = {c.quantity("fluid.viscosity"), c.quantity("fluid.density"), c.quantity("fluid.temperature")};
  scales.particle.diameter = d;
  scales.particle.density = c.quantity("particles.density");
  scales.velocity = U;
  scales.length = h;
  scales.depth = h;
  scales.gravity = c.quantity("physics.gravity");
  const double flow_rate = U * W * h;
  scales.volume_fraction = flow_rate > 0 ? static_cast<double>(count) / t_inj * scales.particle.volume() / flow_rate : 0.0;
  EngineChoice choice = chooseEngine(scales);
  const std::string& forced = c.text("particles.engine");
  std::string reason = choice.reason;
  if (forced != "auto") {
    choice.engine = forced == "overdamped" ? EngineKind::overdamped : EngineKind::liggghts;
    reason = fmt::format("forced by the case (particles.engine = \"{}\"); the automatic choice would be: {}", forced, choice.reason);
  }
  if (choice.engine == EngineKind::liggghts && !liggghtsAvailable())
    throw InputError(c.where("particles.engine"), "the scene needs the LIGGGHTS engine, which this build lacks", reason,
                     "particles.engine = \"overdamped\" to force the cheaper model, or a build with libliggghts-dev");

  auto flow = std::make_shared<HeleShawChannel>(L, W, h, U);
  const SceneConfig scene = sceneFromCase(c, choice, ctx.out_dir / "liggghts");
  auto engine = makeEngine(choice.engine, flow, scene);

  const double pixel = c.quantity("output.pixel_size");
  Tracks traj;
  std::string retention = tables::retentionHeader();
  std::int64_t injected = 0, frame = 0;
  double speed_sum = 0;
  std::int64_t speed_n = 0;
  std::map<std::int64_t, Vec3> last;  // previous frame's position of mobile particles
  const auto t0 = std::chrono::steady_clock::now();
  for (std::int64_t k = 0; k <= frames; ++k) {
    const double t = k * dt_out;
    if (k > 0) engine->advance(t);
    // Injection: particles due by t (evenly spread over the injection time),
    // placed in the inlet strip the flow covers in one interval.
    const auto due = t_inj > 0 ? std::min<std::int64_t>(count, static_cast<std::int64_t>(std::floor(count * std::min(t / t_inj, 1.0) + 1e-9))) : count;
    if (due > injected) {
      const double strip = std::max(1.5 * U * dt_out, d);  // centre-line travel of one interval
      const auto pos = sampleInlet(*flow, 0.5 * d, 0.0, std::min(strip, 0.5 * L), static_cast<int>(due - injected),
                                   scene.seed * 1000003ULL + static_cast<std::uint64_t>(k), engine->particles());
      engine->insert(pos);
      injected = due;
    }
    const auto ps = engine->particles();
    std::map<std::int64_t, Vec3> now;
    for (const auto& p : ps) {
      if (p.status == ParticleStatus::left) continue;
      TrackPoint tp;
      tp.frame = frame;
      tp.particle = p.id;
      tp.t = t;
      tp.x = p.x.x();
      tp.y = p.x.y();
      tp.z = p.x.z();
      tp.state = p.status == ParticleStatus::mobile ? "mobile" : "deposited";
      traj.points.push_back(tp);
      if (p.status == ParticleStatus::mobile) {
        now[p.id] = p.x;
        if (auto it = last.find(p.id); it != last.end()) {
          speed_sum += (p.x.x() - it->second.x()) / dt_out;
          ++speed_n;
        }
      }
    }
    last = std::move(now);
    const Counts n = countParticles(ps);
    retention += tables::formatRow(tables::RetentionRow{frame, t, n.injected, n.inside, n.deposited, n.left});
    ++frame;
  }
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::sort(traj.points.begin(), traj.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  writeTracksCsv(ctx.out_dir / "trajectories.csv", traj, pixel);
  // The particles as a .vtp series (docs/outputs.md): the channel's own frame, metres.
  const std::vector<std::string> particle_series = vtk::writeParticleSeries(
      ctx.out_dir, "particles", traj, [](const TrackPoint& q) { return std::array<double, 3>{q.x, q.y, std::isfinite(q.z) ? q.z : 0.0}; });
  writeFileAtomic(ctx.out_dir / "retention.csv", retention);

  const Counts n = engine->counts();
  if (!n.balanced()) throw std::logic_error(fmt::format("particle counts do not balance: {} != {} + {} + {}", n.injected, n.inside, n.deposited, n.left));
  const EngineStats st = engine->stats();
  RunOutput out;
  out.files = {"trajectories.csv", "retention.csv"};
  if (!particle_series.empty()) out.files.push_back(particle_series.back());  // particles.pvd stands for its snapshots
  out.metrics["retained_fraction"] = n.injected ? static_cast<double>(n.deposited) / n.injected : 0.0;
  out.metrics["left_fraction"] = n.injected ? static_cast<double>(n.left) / n.injected : 0.0;
  out.metrics["injected"] = static_cast<double>(n.injected);
  out.metrics["deposited"] = static_cast<double>(n.deposited);
  out.metrics["left"] = static_cast<double>(n.left);
  out.metrics["inside"] = static_cast<double>(n.inside);
  out.metrics["count_balance_error"] = static_cast<double>(n.injected - n.inside - n.deposited - n.left);
  const double mean_speed = speed_n ? speed_sum / speed_n : 0.0;
  out.metrics["mean_speed"] = mean_speed;
  out.units["mean_speed"] = "um/s";
  const double factor = slitMeanParticleSpeed(0.5 * d, h, scene.faxen_curvature, scene.wall_hindrance && scene.near_wall_shear);
  out.metrics["mean_speed_ratio"] = U > 0 ? mean_speed / (U * factor) : 0.0;
  out.metrics["particle_steps_per_second"] = wall > 0 ? static_cast<double>(st.particle_steps) / wall : 0.0;
  out.units["particle_steps_per_second"] = "Hz";
  out.metrics["engine_wall_time"] = st.wall_seconds;
  out.units["engine_wall_time"] = "s";
  out.details["engine"] = engineName(choice.engine);
  out.details["engine_reason"] = reason;
  out.details["selection"] = choice.toJson();
  out.details["engine_settings"] = engine->describe();
  // The provenance block shows the LIGGGHTS version of runs that used it (mmval/reports/Site.hpp).
  if (const std::string v = engine->engineVersion(); !v.empty()) setDetail(out.details, DetailField::liggghts_version, v);
  out.details["counts"] = {{"injected", n.injected}, {"inside", n.inside}, {"deposited", n.deposited}, {"left", n.left}};
  out.details["steps"] = st.steps;
  out.details["particle_steps"] = st.particle_steps;
  out.details["dt_min_s"] = std::isfinite(st.min_dt) ? st.min_dt : 0.0;
  out.details["dt_max_s"] = st.max_dt;
  out.details["mean_speed_reference"] = {
      {"u_mean_m_s", U},
      {"depth_factor", factor},
      {"meaning", "mean_speed_ratio = measured mean x-speed of mobile particles / (u_mean x mean of the depth profile over the "
                  "accessible heights [a, h - a], minus Faxen 2 a^2/h^2, plus the plates' shear lag (Goldman-Cox-Brenner)): 1 for particles spread evenly across the depth"}};
  return out;
}

}  // namespace

void registerParticleKinds(CaseKindRegistry& registry) {
  CaseKind k;
  k.name = "particles-channel";
  k.summary = "Particles injected into an analytic Hele-Shaw channel, moved by the engine the scene's numbers pick, with deposition: "
              "trajectories (shared tracks schema), retention over time";
  k.declare = declareChannel;
  k.run = runChannel;
  registry.add(k);
  registry.add(micromodelKind());
  registry.add(resolvedKind());
  declareParticleMetrics(registry);
  checks::registerPhysicsChecks(registry);
}

void declareChemistry(Schema& s, bool with_temperature) {
  // Defaults from the struct (Dlvo.hpp); their sources are in reference-data/dlvo-materials.toml.
  const DlvoParameters d;
  constexpr double kMillivolt = 1e-3;
  s.real("chemistry.particle_zeta_mv",
         "Particle surface (zeta) potential in mV, taken as the double layer's surface potential. The paper gives none: "
         "an assumption (reference-data/dlvo-materials.toml)")
      .def(d.particle_potential / kMillivolt).min(-300).max(300);
  s.real("chemistry.collector_zeta_mv",
         "Collector surface (zeta) potential in mV: the chip's glass for plates and grains in particle scenes; an assumption, "
         "reference-data/dlvo-materials.toml. Used with chemistry.collector_charge = \"fixed\" only")
      .def(d.collector_potential / kMillivolt).min(-300).max(300);
  const auto& cc = d.collector_charge;
  s.choice("chemistry.collector_charge", {"fixed", "regulated"},
           "How the collector (glass) potential is set. fixed: chemistry.collector_zeta_mv. regulated: the diffuse-layer potential "
           "of the Basic Stern model of silanol dissociation (Behrens & Grier 2001) at chemistry.ph and the case's ionic strength, "
           "valence and temperature; its magnitude falls as the salt rises (then collector_zeta_mv must not be given)")
      .def(cc.regulated ? "regulated" : "fixed");
  s.real("chemistry.ph", "Bulk pH for chemistry.collector_charge = \"regulated\". The source paper gives none: 7 (neutral water) is an "
                         "assumption; water in equilibrium with air is nearer 5.6")
      .def(cc.ph).min(0).max(14);
  s.real("chemistry.silanol_pk", "pK of silanol dissociation SiOH <-> SiO- + H+ (regulated charge; Behrens & Grier 2001, "
                                 "reference-data/dlvo-materials.toml)")
      .def(cc.surface.pK).min(0).max(14);
  s.real("chemistry.silanol_sites_per_nm2", "Silanol site density Gamma in sites per nm2 (regulated charge; Behrens & Grier 2001)")
      .def(cc.surface.site_density * 1e-18).positive().max(100);
  s.real("chemistry.stern_capacitance_f_m2", "Stern-layer capacitance C in F/m2 (regulated charge; Behrens & Grier 2001)")
      .def(cc.surface.capacitance).positive().max(1000);
  s.quantity("chemistry.ionic_strength", "mol/m3", "Ionic strength I of the symmetric z:z electrolyte (mol/m3 = mM)")
      .def(d.electrolyte.ionic_strength).min(1e-4).max(5000);
  s.integer("chemistry.valence", "Valence z of both ions of the symmetric electrolyte (1: KCl, NaCl)").def(1).min(1).max(4);
  if (with_temperature) s.quantity("chemistry.temperature", "K", "Temperature").def(d.electrolyte.temperature).min(200).max(450);
  s.real("chemistry.relative_permittivity", "Relative permittivity of the solvent (water at 25 C: 78.5)").def(d.electrolyte.relative_permittivity).min(1).max(200);
  s.quantity("chemistry.hamaker", "J", "Hamaker constant particle-water-collector (an assumption, reference-data/dlvo-materials.toml)")
      .def(d.hamaker).nonNegative().max(1e-18);
  s.quantity("chemistry.retardation_wavelength", "nm", "Characteristic wavelength lambda of Gregory's (1981) retarded van der Waals form")
      .def(d.retardation_wavelength).positive();
  s.choice("chemistry.double_layer", {"hhf", "lsa"},
           "Double-layer model: hhf (Hogg-Healy-Fuerstenau, constant potential; low potentials, |psi| <~ 25 mV) or lsa (linear "
           "superposition; any potential, weak overlap kappa h >~ 1)")
      .def("lsa");
  s.boolean("chemistry.born", "Born repulsion (Ruckenstein & Prieve 1976), which bounds the primary minimum").def(d.born);
  s.quantity("chemistry.born_collision_diameter", "nm", "Collision diameter sigma of the Born term (0.5 nm: a common choice, an assumption)")
      .def(d.born_collision_diameter).positive();
}

DlvoParameters chemistryFromCase(const Case& c, const char* temperature_key) {
  DlvoParameters p;
  p.particle_potential = c.real("chemistry.particle_zeta_mv") * 1e-3;
  p.collector_potential = c.real("chemistry.collector_zeta_mv") * 1e-3;
  p.electrolyte.ionic_strength = c.quantity("chemistry.ionic_strength");
  p.electrolyte.valence = static_cast<int>(c.integer("chemistry.valence"));
  p.electrolyte.temperature = c.quantity(temperature_key);
  p.electrolyte.relative_permittivity = c.real("chemistry.relative_permittivity");
  p.hamaker = c.quantity("chemistry.hamaker");
  p.retardation_wavelength = c.quantity("chemistry.retardation_wavelength");
  p.double_layer = c.text("chemistry.double_layer") == "hhf" ? DoubleLayerModel::hhf : DoubleLayerModel::lsa;
  p.born = c.flag("chemistry.born");
  p.born_collision_diameter = c.quantity("chemistry.born_collision_diameter");
  auto& cc = p.collector_charge;
  cc.regulated = c.text("chemistry.collector_charge") == "regulated";
  cc.ph = c.real("chemistry.ph");
  cc.surface.pK = c.real("chemistry.silanol_pk");
  cc.surface.site_density = c.real("chemistry.silanol_sites_per_nm2") * 1e18;
  cc.surface.capacitance = c.real("chemistry.stern_capacitance_f_m2");
  if (cc.regulated) {
    const auto given = [&](std::string_view key) {
      if (c.where(key).line > 0) return true;
      return std::any_of(c.overrides().begin(), c.overrides().end(), [&](const CaseOverride& o) { return o.key == key; });
    };
    if (given("chemistry.collector_zeta_mv"))
      throw InputError(c.where("chemistry.collector_zeta_mv"),
                       "is computed when chemistry.collector_charge = \"regulated\" (Basic Stern model at chemistry.ph); give one or the other");
  }
  try {
    p = withRegulatedCollector(p);
    (void)DlvoInteraction(p);
  } catch (const std::invalid_argument& e) {
    throw InputError(c.where("chemistry"), fmt::format("the chemistry does not define a DLVO interaction: {}", e.what()));
  }
  return p;
}

void declareEngineNumerics(Schema& s) {
  s.integer("numerics.threads",
            "Overdamped engine: threads of a step's per-particle loops (drift, move and wall step), the results bit for bit one "
            "thread's; 0: auto (the hardware's cores, 2 to 8; in a run of mmval sweep --jobs N, its share: cores / N, at least 1). Default 1, "
            "so that the runs of mmval sweep --jobs N do not share cores")
      .def(1)
      .min(0)
      .max(OverdampedEngine::kMaxThreads);
  s.integer("numerics.substeps",
            "Overdamped engine: the most steps of its own a particle takes within one engine step, a power of 2. 1: every particle "
            "takes the step the fastest one allows; K: the engine's step is up to K times that, and a particle whose own limit "
            "(numerics.max_step_fraction radii of travel) is shorter takes up to K steps within it, stopping early at a grain "
            "or where it meets another particle (docs/validation/particle-physics.md, \"Per-particle steps\")")
      .def(1)
      .min(1)
      .max(64);
  declareDriftIntegrator(s);
}

void declareDriftIntegrator(Schema& s) {
  s.choice("numerics.drift_integrator", {"euler", "heun"},
           "Overdamped engine: the drift's part of a step. euler: v(x) dt, first order in the step (a path along a curved "
           "streamline drifts outward by ~ step^2 / (2 R) per step); heun: the mean of v at x and at the Euler predictor "
           "x + v dt, second order along curved streamlines, one more drift evaluation per step (Euler where the predictor "
           "overlaps a plate or grain wall, or leaves the fluid). The Brownian displacement is the same draw at x either way "
           "(docs/validation/particle-physics.md, \"Heun's drift\")")
      .def("euler");
}

bool heunDriftFromCase(const Case& c) { return c.text("numerics.drift_integrator") == "heun"; }

void engineNumericsFromCase(const Case& c, SceneConfig& s) {
  s.threads = static_cast<int>(c.integer("numerics.threads"));
  const auto k = c.integer("numerics.substeps");
  if ((k & (k - 1)) != 0)
    throw InputError(c.where("numerics.substeps"), fmt::format("expected a power of 2 (1, 2, 4, ... 64), got {}", k));
  s.substeps = static_cast<int>(k);
  s.heun_drift = heunDriftFromCase(c);
}

void declarePhysicsAndDeposition(Schema& s, double hamaker_default) {
  s.quantity("physics.gravity", "m/s2", "Gravity along -z (the depth); 0: no settling").def("9.81 m/s2").nonNegative();
  s.choice("physics.brownian", {"auto", "on", "off"}, "Brownian motion (overdamped engine); auto follows the Peclet numbers").def("auto");
  s.boolean("physics.wall_hindrance", "Faxen / Brenner drag corrections from the plates").def(true);
  s.boolean("physics.faxen_curvature", "Faxen's a^2/6 lap(u) term of the depth profile").def(true);
  s.boolean("physics.near_wall_shear",
            "A free sphere near a plate lags the wall shear of the depth profile (Goldman, Cox & Brenner 1967); false: it moves with the fluid at its centre")
      .def(true);
  s.boolean("physics.near_contact_drag",
            "Parallel drag near the plates of a sphere free to rotate: Goldman-Cox-Brenner lubrication joined to Faxen's series; false: Faxen's series alone")
      .def(true);
  s.boolean("physics.ito_drift",
            "For checks only: the Ito drift k_B T dM/dz of the position-dependent mobility (overdamped engine). false shows what "
            "leaving it out does (a wrong equilibrium distribution near the plates)")
      .def(SceneConfig{}.ito_drift);
  s.choice("deposition.model", {"capture", "dlvo"},
           "What decides attachment of a particle within the capture distance of a sticky surface. capture: it attaches (with "
           "plate_rule and plate_attachment_efficiency on the plates). dlvo (overdamped engine): the DLVO profile of the surface "
           "type from the [chemistry] keys (plates and grains: sphere-plate against chemistry.collector_zeta_mv; deposits: "
           "sphere-sphere against the particle's own potential), one draw per arrival: primary-minimum attachment with the "
           "interaction-force-boundary-layer efficiency, else secondary-minimum capture (Maxwell fraction, wells deeper than 1 kT; "
           "held only where the well's pull-off force holds against the local shear's torque, at plates, grain walls and deposits "
           "alike), else the particle stays mobile")
      .def("capture");
  s.quantity("deposition.capture_distance", "um", "Surface gap at which a particle attaches to a sticky surface (0: never)").def("0.1 um").nonNegative();
  s.boolean("deposition.bottom", "The bottom plate is sticky").def(true);
  s.boolean("deposition.top", "The top plate is sticky").def(false);
  s.boolean("deposition.walls", "Grains and side walls are sticky").def(true);
  s.boolean("deposition.deposited", "Deposited particles are sticky (ripening, bridging)").def(true);
  s.quantity("deposition.hamaker", "J", "Hamaker constant of the sphere-wall van der Waals attraction of the capture rule (0: none; the dlvo rule uses chemistry.hamaker)").def(hamaker_default).nonNegative();
  s.quantity("deposition.attraction_range", "um", "van der Waals cut-off gap").def("1 um").positive();
  s.choice("deposition.plate_rule", {"capture", "torque-balance"},
           "Attachment to a sticky plate. capture: within the capture distance, for good; torque-balance (overdamped engine): "
           "only if the DMT adhesion torque (Hamaker constant, adhesion_separation, contact_modulus) holds against the "
           "Goldman-Cox-Brenner drag and torque of the local wall shear, else the particle rolls on")
      .def("capture");
  s.choice("deposition.surface_rule", {"capture", "torque-balance"},
           "Attachment to sticky grain walls, side walls and deposits. capture: within the capture distance, for good; "
           "torque-balance (overdamped engine): only if the DMT contact adhesion torque (as plate_rule; against a deposit with "
           "Derjaguin's radius a/2) holds against the Goldman-Cox-Brenner drag and torque of the shear u/a, u the fluid speed at "
           "the particle's centre; else it moves on and is checked again every step (held where the flow is slow)")
      .def("capture");
  s.real("deposition.release_radii",
         "dlvo rule: after an arrival that did not attach, the gap (in particle radii) the particle must exceed before its next "
         "arrival at that surface draws again; 1: back in the bulk, beyond the DLVO force's range (an assumption, see "
         "docs/validation/particle-physics.md); at most capture_distance / radius: every re-entry into the capture distance "
         "draws, which multiplies arrivals as the step shrinks")
      .def(1.0)
      .min(0);
  s.real("deposition.plate_attachment_efficiency",
         "Overdamped engine: probability that a particle arriving on a sticky plate attaches (colloid filtration theory's alpha), "
         "drawn once per arrival; a rejected particle rolls on. 1: every arrival sticks. A calibration parameter (no surface "
         "chemistry is known to compute it from); the LIGGGHTS engine's cohesion decides attachment itself")
      .def(1.0)
      .min(0)
      .max(1);
  s.quantity("deposition.adhesion_separation", "nm", "Contact separation z0 of the adhesion A a / (6 z0^2) (0.4 nm: the usual convention)")
      .def("0.4 nm").positive();
  s.quantity("deposition.contact_modulus", "GPa",
             "Composite contact modulus K = 4/3 / ((1 - nu1^2)/E1 + (1 - nu2^2)/E2); default polystyrene (3.4 GPa, 0.33) on glass (70 GPa, 0.22)")
      .def("4.84 GPa").positive();
  declareChemistry(s, false);  // the temperature is fluid.temperature
  // Attachment only (the particle kinds' dlvo rule), so not in the shared chemistry block.
  s.real("chemistry.favourable_fraction",
         "deposition.model = \"dlvo\": area fraction lambda of favourable (barrier-free, attractive) patches on the glass, plates "
         "and grains (deposits are latex and keep their own chemistry): patchwise heterogeneity (Song, Johnson & Elimelech 1994). "
         "Per arrival a favourable patch with probability lambda (primary-minimum attachment), else the unfavourable DLVO rule: "
         "alpha = lambda + (1 - lambda) alpha_unfavourable. An assumption the experiment does not constrain "
         "(reference-data/dlvo-materials.toml); 0: homogeneous glass")
      .def(AttachmentModel{}.favourable_fraction)
      .min(0)
      .max(1);
  s.quantity("chemistry.patch_size", "um",
             "deposition.model = \"dlvo\", chemistry.favourable_fraction > 0: 0 draws the patch once per arrival; > 0 places the "
             "favourable patches in space, cells of this side on the plates (x, y) and the grain walls (x, y, z), each favourable "
             "with probability lambda from the run's seed, and a particle within the capture distance of the glass (resting, rolling "
             "or translating in the secondary minimum) attaches as soon as its contact point is on a favourable cell, checked every "
             "step. Give the length over which the glass's attachment is correlated (a heterodomain's size when it exceeds the particle's "
             "zone of influence, of order sqrt(a / kappa); else that zone), and not below a step's travel (numerics.max_step_fraction radii)")
      .def("0 um")
      .nonNegative();
}

std::int64_t outputFrames(const Case& c) {
  const double duration = c.quantity("run.duration"), dt_out = c.quantity("run.output_interval");
  const double frames = std::floor(duration / dt_out + 0.5);
  // Every output frame keeps its rows of the retention (and permeability) tables until the run
  // ends, before any particle position: 44 B per frame, measured with /usr/bin/time -v on
  // particles-channel with one particle (125.2 MB peak at 3e5 frames, 111.9 MB at 150 frames).
  // Particle positions add ~240 B per particle and frame (TrackPoint records, measured on synth),
  // not counted here: this is a lower bound, so it never refuses a run that would fit.
  constexpr double kBytesPerFrame = 44;
  // The key to change: a run longer than 1e6 s (11.6 days) is the odd value, else the interval.
  const char* key = duration > 1e6 ? "run.duration" : "run.output_interval";
  requireMemory(c, frames * kBytesPerFrame,
                fmt::format("{:.3g} output frames (run.duration {:g} s / run.output_interval {:g} s)", frames, duration, dt_out), key,
                "a longer run.output_interval or a shorter run.duration");
  return static_cast<std::int64_t>(frames);
}

void physicsAndDepositionFromCase(const Case& c, const EngineChoice& choice, SceneConfig& s) {
  const std::string& b = c.text("physics.brownian");
  s.brownian = b == "auto" ? choice.brownian : b == "on";
  s.wall_hindrance = c.flag("physics.wall_hindrance");
  s.faxen_curvature = c.flag("physics.faxen_curvature");
  s.near_wall_shear = c.flag("physics.near_wall_shear");
  s.near_contact_drag = c.flag("physics.near_contact_drag");
  s.attachment.capture_distance = c.quantity("deposition.capture_distance");
  s.attachment.bottom = c.flag("deposition.bottom");
  s.attachment.top = c.flag("deposition.top");
  s.attachment.grains = c.flag("deposition.walls");
  s.attachment.deposited = c.flag("deposition.deposited");
  s.attachment.hamaker = c.quantity("deposition.hamaker");
  s.attachment.attraction_range = c.quantity("deposition.attraction_range");
  s.attachment.torque_balance = c.text("deposition.plate_rule") == "torque-balance";
  s.attachment.surface_torque_balance = c.text("deposition.surface_rule") == "torque-balance";
  s.attachment.plate_efficiency = c.real("deposition.plate_attachment_efficiency");
  if (s.attachment.plate_efficiency < 1 && choice.engine == EngineKind::liggghts)
    throw InputError(c.where("deposition.plate_attachment_efficiency"), "an attachment efficiency applies to the overdamped engine only",
                     fmt::format("{:g} with the LIGGGHTS engine", s.attachment.plate_efficiency),
                     "1 (LIGGGHTS' sjkr cohesion decides attachment), or particles.engine = \"overdamped\"");
  s.attachment.adhesion_separation = c.quantity("deposition.adhesion_separation");
  s.attachment.contact_modulus = c.quantity("deposition.contact_modulus");
  s.ito_drift = c.flag("physics.ito_drift");
  if (c.text("deposition.model") == "dlvo") {
    const auto conflict = [&](const char* key, const std::string& value, const char* expected) {
      throw InputError(c.where(key), "does not go with deposition.model = \"dlvo\" (the DLVO profile decides attachment)", value, expected);
    };
    if (choice.engine == EngineKind::liggghts) conflict("particles.engine", "liggghts", "\"overdamped\", or deposition.model = \"capture\"");
    if (!(s.attachment.capture_distance > 0)) conflict("deposition.capture_distance", "0", "> 0: arrivals are drawn within it");
    if (s.attachment.plate_efficiency < 1) conflict("deposition.plate_attachment_efficiency", fmt::format("{:g}", s.attachment.plate_efficiency), "1");
    if (s.attachment.torque_balance) conflict("deposition.plate_rule", "torque-balance", "\"capture\"");
    if (s.attachment.surface_torque_balance) conflict("deposition.surface_rule", "torque-balance", "\"capture\"");
    s.attachment.rule = AttachmentModel::Rule::dlvo;
    s.attachment.chemistry = chemistryFromCase(c, "fluid.temperature");
    s.attachment.favourable_fraction = c.real("chemistry.favourable_fraction");
    s.attachment.patch_size = c.quantity("chemistry.patch_size");
    s.attachment.release_distance = c.real("deposition.release_radii") * 0.5 * c.quantity("particles.diameter");
  } else if (c.real("chemistry.favourable_fraction") > 0) {
    throw InputError(c.where("chemistry.favourable_fraction"), "applies to deposition.model = \"dlvo\" only (the capture rule has no chemistry)",
                     fmt::format("{:g}", c.real("chemistry.favourable_fraction")), "0, or deposition.model = \"dlvo\"");
  } else if (c.quantity("chemistry.patch_size") > 0) {
    throw InputError(c.where("chemistry.patch_size"), "applies to deposition.model = \"dlvo\" only (the capture rule has no chemistry)",
                     fmt::format("{:g} um", c.quantity("chemistry.patch_size") * 1e6), "0, or deposition.model = \"dlvo\"");
  }
}

}  // namespace mmval::particles
