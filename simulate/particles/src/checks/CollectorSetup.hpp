// What the two collector checks share (CollectorCheck.cpp: interception;
// CollectorDiffusion.cpp: Brownian capture): the case keys of the post and its
// fluid, the scene every collector run uses, the check of the cell's flux, and
// the run loop; and the weighted power-law fit the diffusion check's exponent
// comes from. Internal to mmval::particles (tests include it).
#pragma once
#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

#include "CollectorFlow.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles::checks {

struct CollectorSetup {
  double post_radius = 0, phi = 0, viscosity = 0, temperature = 0, capture_distance = 0, max_step_fraction = 0;
  std::uint64_t seed = 1;
  bool heun_drift = false;  ///< numerics.drift_integrator = "heun"
  double cellRadius() const { return post_radius / std::sqrt(phi); }
};

/// Keys of the post, its fluid, the capture distance and the seed, shared by both kinds.
void declareCollectorKeys(Schema& s);
/// The metrics both collector kinds report: the flow's flux check, unfinished particles, wall time.
void declareCollectorCommonMetrics(Schema& s);
/// Those keys (and numerics.max_step_fraction) read from the case.
CollectorSetup setupFromCase(const Case& c);

/// The scene every collector run uses: plane flow, no gravity, no plate hindrance,
/// only the post sticky (deposited particles are not: no ripening).
SceneConfig collectorScene(const CollectorSetup& s, double particle_radius, bool brownian, double outlet_x, std::uint64_t seed);

/// Flux through the line x = 0 from the post to the cell boundary over U b: 1 by the
/// stream function's boundary values (psi = 0 on the post, U b at the cell boundary).
/// Simpson's rule on the implemented velocity; its deviation from 1 checks the field.
double cellFluxRatio(const KuwabaraCell& flow, double a_f, double u);

/// Advances until no particle is mobile or `t_max` passes, in `chunk` steps. Returns the mobile count left.
std::int64_t runUntilDone(OverdampedEngine& engine, double chunk, double t_max);

/// InputError naming `key` when the capture radius (m) reaches half-way to the Kuwabara cell boundary.
void checkCaptureRadius(const Case& c, const char* key, const CollectorSetup& s, double capture_radius);

/// Weighted least-squares slope of ln(y) against ln(x), weights 1 / rel_err^2 (rel_err the
/// relative error of each y, i.e. the standard error of ln y), and its standard error.
std::pair<double, double> fitPowerLaw(const std::vector<double>& x, const std::vector<double>& y, const std::vector<double>& rel_err);

/// Registers physics-collector-diffusion (CollectorDiffusion.cpp).
void registerCollectorDiffusion(CaseKindRegistry& registry);

}  // namespace mmval::particles::checks
