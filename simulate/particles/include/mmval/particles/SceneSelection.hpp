// Picking the particle engine (and the fluid-particle coupling mode) of a
// scene from its dimensionless numbers: model only what a scene needs, the
// cheapest engine whose physics the scene's numbers call for. The rules are deliberately few and their reason is
// returned as text that goes into result.json.
#pragma once
#include <string>

#include <nlohmann/json.hpp>

#include "mmval/particles/Physics.hpp"

namespace mmval::particles {

struct SceneScales {
  Fluid fluid;
  ParticleMaterial particle;
  double velocity = 0.0;          ///< characteristic (interstitial) fluid speed U, m/s
  double length = 0.0;            ///< characteristic length L (pore throat or chip depth), m
  double depth = 0.0;             ///< chip depth h, m (0: not a shallow chip)
  double cell_size = 0.0;         ///< fluid cell size dx, m (0: unknown)
  double volume_fraction = 0.0;   ///< particle volume concentration phi
  double gravity = 9.81;
};

struct DimensionlessNumbers {
  double reynolds = 0;        ///< rho_f U L / mu
  double stokes = 0;          ///< tau_p U / L
  double peclet = 0;          ///< U d / D (advection over diffusion across one diameter)
  double settling_peclet = 0; ///< v_s h / D (settling over diffusion across the depth)
  double d_over_dx = 0;       ///< particle diameter per fluid cell
  double d_over_h = 0;        ///< particle diameter per chip depth
  double volume_fraction = 0;
  nlohmann::json toJson() const;
};

enum class EngineKind { overdamped, liggghts };
enum class CouplingMode { resolved, dilated, unresolved };
const char* engineName(EngineKind e);
const char* couplingName(CouplingMode c);

struct EngineChoice {
  EngineKind engine = EngineKind::overdamped;
  CouplingMode coupling = CouplingMode::unresolved;
  bool wall_hindrance = false;
  bool brownian = false;
  DimensionlessNumbers numbers;
  std::string reason;  ///< one paragraph: numbers, thresholds, consequence
  nlohmann::json toJson() const;
};

/// Thresholds of the choice. Stokes: the overdamped velocity lags the fluid by
/// ~St relative (Maxey & Riley 1983), so St <= 1e-3 keeps that lag under 0.1 %.
/// Concentration: below ~5 % by volume contacts are rare, brief collisions
/// (dilute suspension); above ~20 % enduring contact networks carry force and a
/// contact-resolving DEM is needed.
struct SelectionThresholds {
  double stokes_overdamped = 1e-3;
  double volume_fraction_dilute = 0.05;
  double volume_fraction_dense = 0.2;
  double d_over_dx_resolved = 8.0;   ///< the paper: a particle must cover ~8 cells
  double d_over_h_hindrance = 0.01;  ///< wall corrections above ~1 % (Faxen: 9/16 a/h)
  double peclet_brownian = 1e6;      ///< Brownian motion kept when either Peclet is below this
};

DimensionlessNumbers dimensionlessNumbers(const SceneScales& s);

/// The engine for a scene; throws std::invalid_argument on non-positive scales.
EngineChoice chooseEngine(const SceneScales& s, const SelectionThresholds& t = {});

}  // namespace mmval::particles
