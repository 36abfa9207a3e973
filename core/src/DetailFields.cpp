#include "mmval/core/DetailFields.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/core/Error.hpp"

namespace mmval {

namespace {

using nlohmann::json;
using F = DetailField;
using T = DetailType;

constexpr const char* kFluidLadderKinds = "channel, cylinder-channel, periodic-array, image-permeability, `mmval peer openfoam`";
constexpr const char* kSteadyMmvalKinds = "channel, cylinder-channel (steady), periodic-array, image-permeability (2d, depth-averaged)";
constexpr const char* kPhysicsReferenceKinds = "physics-settling-slit, physics-diffusion-slit, physics-near-wall-shear, physics-sedimentation";

// The declarations, in DetailField order (checked when the table is first used).
std::vector<DetailFieldDecl> makeDeclarations() {
  const std::optional<DetailType> none;
  const std::optional<DetailField> top;
  return {
      {F::solver, "solver", top, T::string, none, 0, "-",
       "who computed the numbers: mmval's solver (its name and scheme), `openfoam <version>` for the OpenFOAM peer, `OpenFOAM (not run)` for a peer "
       "run that validate skipped; absent: mmval",
       "channel, cylinder-channel, periodic-array, image-permeability, `mmval peer openfoam`, `mmval validate` (peer not run)"},
      {F::liggghts_version, "liggghts_version", top, T::string, none, 0, "-",
       "LIGGGHTS version of a run that used it, shown in the provenance block when provenance.dependencies has none",
       "particles-channel (engine liggghts), particles-micromodel (engines.compare)"},
      {F::table3_case, "table3_case", top, T::string, none, 0, "-",
       "the case of the paper's Table 3 the run reproduces (`I`..`V`), from the case's analysis.table3_case; the report's Table 3 "
       "rows are the runs that carry it",
       "particles-micromodel (cases/particles-table3-*.toml)"},
      {F::Re, "Re", top, T::number, none, 0, "1", "Reynolds number U D / nu of the cylinder, U the reference speed of the case (the mean inflow speed in a channel)",
       "cylinder-channel, `mmval peer openfoam` (cylinder scenes)"},
      {F::status, "status", top, T::string, none, 0, "-",
       "why the run has no numbers: `not run` (validate skipped a peer run), `not converged` (the peer's finest level did not converge)",
       "`mmval validate`, `mmval peer openfoam`"},
      {F::cells, "cells", top, T::integer, none, 0, "1", "grid cells of the finest level", kFluidLadderKinds},
      {F::warnings, "warnings", top, T::array, T::string, 0, "-", "numerical warnings of the run, one sentence each (throats under-resolved, no observed order, ...)",
       "periodic-array, image-permeability, cylinder-channel (unsteady), particles-resolved, `mmval peer openfoam`"},
      {F::undeclared_metrics, "undeclared_metrics", top, T::array, T::string, 0, "-",
       "metrics the runner reported that its kind does not declare, or in another dimension (a bug in mmval)", "any kind (`mmval run`)"},

      {F::ladder, "ladder", top, T::array, T::object, 0, "-", "one entry per resolution level, coarsest first", kFluidLadderKinds},
      {F::ladder_level, "level", F::ladder, T::integer, none, 0, "1", "index of the level, 0 the coarsest", kFluidLadderKinds},
      {F::ladder_value, "value", F::ladder, T::number, none, 0, "SI",
       "the kind's primary metric at this level, in SI (absent when the level did not converge)", kFluidLadderKinds},
      {F::ladder_error, "error", F::ladder, T::number, none, 0, "1",
       "relative error of `value` against the case's first acceptance reference (absent for an interval or zero reference; an unsteady cylinder: its first single-value reference)", kFluidLadderKinds},
      {F::ladder_observed_order, "observed_order", F::ladder, T::number, none, 0, "1",
       "order of convergence from this level and the two before: log((f2 - f1) / (f3 - f2)) / log(r)", kFluidLadderKinds},
      {F::ladder_wall_seconds, "wall_seconds", F::ladder, T::number, none, 0, "s", "wall time of the level (OpenFOAM: meshing and solving)",
       kFluidLadderKinds},
      {F::ladder_cpu_seconds, "cpu_seconds", F::ladder, T::number, none, 0, "s",
       "CPU time of the level: user + system time of mmval's process (rank 0), or the OpenFOAM solver's own ExecutionTime (meshing not in it)",
       kFluidLadderKinds},
      {F::ladder_cells, "cells", F::ladder, T::integer, none, 0, "1", "grid cells of the level", kFluidLadderKinds},
      {F::ladder_time_steps, "time_steps", F::ladder, T::integer, none, 0, "1", "time steps the level took", "cylinder-channel (unsteady)"},
      {F::ladder_c_D_max, "c_D_max", F::ladder, T::number, none, 0, "1", "largest drag coefficient in the level's statistics window",
       "cylinder-channel (unsteady)"},
      {F::ladder_status, "status", F::ladder, T::string, none, 0, "-", "`not converged` when the level's solve ran out of iterations",
       "`mmval peer openfoam`"},
      {F::ladder_linear_solver, "linear_solver", F::ladder, T::string, none, 0, "-",
       "the linear solver of the level's coupled solve: `direct` or `iterative` (numerics.linear_solver = \"auto\" picks one)", kSteadyMmvalKinds},
      {F::ladder_linear_solver_reason, "linear_solver_reason", F::ladder, T::string, none, 0, "-",
       "why that solver: `requested`, or the rule `auto` applied (problem class, unknowns, ranks) and any fallback", kSteadyMmvalKinds},
      {F::ladder_linear_solver_fallback, "linear_solver_fallback", F::ladder, T::boolean, none, 0, "-",
       "true when an auto-chosen solver failed and the other solved the level instead (an iterative solve that did not converge: the direct LU; a direct LU its library could not factorise: the iterative solver)", kSteadyMmvalKinds},
      {F::ladder_linear_true_residual, "linear_true_residual", F::ladder, T::number, none, 0, "1",
       "the iterative solver's accepted answer: its true relative residual, the 2-norm of b - A x over that of b, checked against 100 times the "
       "tolerance before the answer is kept (a larger one counts as a failed solve: the fallback, or exit 5 naming it); absent after a direct solve",
       kSteadyMmvalKinds},
      {F::ladder_velocity_preconditioner, "velocity_preconditioner", F::ladder, T::string, none, 0, "-",
       "plane Stokes solved iteratively: the velocity block's preconditioner, one BoomerAMG V-cycle over both components, or on exactly two ranks "
       "one component per rank (rank 0 u, rank 1 v, a serial BoomerAMG each; PETSc option -fluidm_fieldsplit_0_by_component 0 turns it off), "
       "or the user's own choice, \"-fluidm_fieldsplit_0_pc_type VALUE (the user's)\", which the split then leaves in place; absent otherwise",
       kSteadyMmvalKinds},
      {F::ladder_flux_change, "flux_change", F::ladder, T::number, none, 0, "1",
       "the relative change the outlet flux still has to make when the steady solver stopped, estimated as the geometric tail of its last changes",
       "`mmval peer openfoam` (steady)"},
      {F::runs, "runs", top, T::array, T::object, 0, "-", "every solved level of every depth model (the ladder holds one model's)",
       "image-permeability, `mmval peer openfoam` (image cases)"},
      {F::runs_3d, "runs_3d", top, T::array, T::object, 0, "-", "the levels of the coarse 3D Stokes solve", "image-permeability (depth_model 3d or all)"},
      {F::grid_convergence, "grid_convergence", top, T::object, none, 0, "-",
       "per depth model: observed order, extrapolated value, GCI band and a status (`monotone`, `least squares`, `two levels`, ...); with four or "
       "more levels also `least_squares` (order, extrapolated permeability, scatter and uncertainty of a fit f0 + a h^p to every level, after "
       "Eca & Hoekstra 2014, which stands for the ladder where the three finest levels give no credible order)",
       "image-permeability, `mmval peer openfoam`"},
      {F::narrowest_throat, "narrowest_throat", top, T::object, none, 0, "-",
       "the mask's narrowest inlet-to-outlet throat: `x_px`, `y_px` (y down), `width_px`, `width_m`", "image-permeability"},
      {F::depth_model_throat, "depth_model_throat", top, T::object, none, 0, "-",
       "that throat as a duct of the chip's depth: `width_m`, `depth_m`, `width_over_depth`, `duct_excess` (the depth-averaged model's flow "
       "through it over exact Stokes, minus 1; docs/validation/depth-model.md)",
       "image-permeability (depth-averaged model)"},

      {F::statistics_window_s, "statistics_window_s", top, T::array, T::number, 2, "s",
       "[begin, end] of the window over which the unsteady force statistics (c_D max, St, ...) are taken", "cylinder-channel (unsteady)"},
      {F::shedding_periods, "shedding_periods", top, T::integer, none, 0, "1", "whole lift periods in the statistics window (0: no shedding found)",
       "cylinder-channel (unsteady)"},
      {F::time_steps, "time_steps", top, T::integer, none, 0, "1", "time steps of the finest level", "cylinder-channel (unsteady)"},
      {F::resumed_from_step, "resumed_from_step", top, T::integer, none, 0, "1", "time step of the checkpoint the run resumed from (0: a fresh run)",
       "cylinder-channel (unsteady)"},
      {F::resumed_levels, "resumed_levels", top, T::integer, none, 0, "1",
       "ladder levels taken from the checkpoint of a stopped run (`mmval run --resume`; 0: every level solved by this run)", "image-permeability"},

      {F::resumed_from_frame, "resumed_from_frame", top, T::integer, none, 0, "1", "output frame of the checkpoint the run resumed from (0: a fresh run)",
       "particles-micromodel, particles-resolved"},
      {F::end_time_s, "end_time_s", top, T::number, none, 0, "s", "time the run ended (earlier than the case's end time when the pump stalled)",
       "particles-micromodel"},
      {F::pump_stall, "pump_stall", top, T::object, none, 0, "-",
       "when and why the pump could no longer drive the set rate: `time_s`, `reason`, `pressure_Pa`, ... (absent: no stall)", "particles-micromodel"},
      {F::passable_diameter_um, "passable_diameter_um", top, T::number, none, 0, "um", "largest particle diameter with an open inlet-to-outlet pore path",
       "particles-micromodel"},
      {F::straining, "straining", top, T::string, none, 0, "-", "whether the largest particles are strained by the throats, in a sentence",
       "particles-micromodel"},
      {F::coupling, "coupling", top, T::object, none, 0, "-",
       "how the particles and the fluid are coupled, and what the coupling did (deposit counts, grid)", "particles-micromodel, particles-resolved"},
      {F::coupling_mode, "mode", F::coupling, T::string, none, 0, "-",
       "`four-way` (deposits change the flow, which is solved again) or `one-way` (particles-micromodel); `resolved` (particles-resolved: "
       "the particles are rigid bodies on the fluid grid)",
       "particles-micromodel, particles-resolved"},
      {F::coupling_fluid_grid_cells, "fluid_grid_cells", F::coupling, T::array, T::integer, 2, "1", "fluid grid cells along x and along y",
       "particles-micromodel, particles-resolved"},
      {F::coupling_cells_per_diameter, "cells_per_diameter", F::coupling, T::integer, none, 0, "1", "fluid grid cells across a particle diameter",
       "particles-resolved"},
      {F::coupling_deposits_at_walls, "deposits_at_walls", F::coupling, T::integer, none, 0, "1",
       "deposits at grains (booked as filled pixel columns) over the run", "particles-micromodel"},
      {F::coupling_deposits_on_plates, "deposits_on_plates", F::coupling, T::integer, none, 0, "1",
       "deposits on the chip's plates away from grains over the run (booked as aperture layers or as columns, as the case's "
       "coupling.plate_deposits says)",
       "particles-micromodel"},
      {F::reference, "reference", top, T::object, none, 0, "-",
       "what a physics check compares against: `description` always, the reference's own numbers (`l_s_um`, ...) where the check has them",
       kPhysicsReferenceKinds},
      {F::reference_description, "description", F::reference, T::string, none, 0, "-",
       "the reference in a sentence: closed form, series or tables, with their source", kPhysicsReferenceKinds},
      {F::reference_file, "file", F::reference, T::string, none, 0, "-", "the reference-data file the reference values were read from",
       "physics-near-wall-shear"},
      {F::square_array, "square_array", top, T::object, none, 0, "-",
       "the same search in the plane Stokes flow through a square array of posts (collector.square_array)", "physics-collector-interception"},
      {F::engine_comparison, "engine_comparison", top, T::array, T::object, 0, "-",
       "the overdamped engine against LIGGGHTS on a shared window of the scene, one entry per candidate step size",
       "particles-micromodel (engines comparison on)"},
      {F::engine_comparison_candidate, "candidate", F::engine_comparison, T::string, none, 0, "-", "the candidate engine and its settings",
       "particles-micromodel"},
      {F::engine_comparison_window_s, "window_s", F::engine_comparison, T::number, none, 0, "s", "length of the shared window", "particles-micromodel"},
      {F::engine_comparison_particles, "particles", F::engine_comparison, T::integer, none, 0, "1", "particles in the window", "particles-micromodel"},
      {F::engine_comparison_rms_position_difference_m, "rms_position_difference_m", F::engine_comparison, T::number, none, 0, "m",
       "RMS position difference over all particles and output times", "particles-micromodel"},
      {F::engine_comparison_median_final_difference_m, "median_final_difference_m", F::engine_comparison, T::number, none, 0, "m",
       "median over particles of the position difference at the end of the window", "particles-micromodel"},
      {F::engine_comparison_max_position_difference_m, "max_position_difference_m", F::engine_comparison, T::number, none, 0, "m",
       "largest position difference", "particles-micromodel"},
      {F::engine_comparison_captured_reference, "captured_reference", F::engine_comparison, T::integer, none, 0, "1", "particles LIGGGHTS captured",
       "particles-micromodel"},
      {F::engine_comparison_captured_candidate, "captured_candidate", F::engine_comparison, T::integer, none, 0, "1", "particles the candidate captured",
       "particles-micromodel"},
      {F::engine_comparison_captured_both, "captured_both", F::engine_comparison, T::integer, none, 0, "1", "particles both captured",
       "particles-micromodel"},
      {F::engine_comparison_rms_capture_time_difference_s, "rms_capture_time_difference_s", F::engine_comparison, T::number, none, 0, "s",
       "RMS difference of the capture times of particles both captured", "particles-micromodel"},
      {F::engine_comparison_retained_fraction_reference, "retained_fraction_reference", F::engine_comparison, T::number, none, 0, "1",
       "retained fraction of the window, LIGGGHTS", "particles-micromodel"},
      {F::engine_comparison_retained_fraction_candidate, "retained_fraction_candidate", F::engine_comparison, T::number, none, 0, "1",
       "retained fraction of the window, candidate", "particles-micromodel"},
      {F::engine_comparison_wall_seconds_reference, "wall_seconds_reference", F::engine_comparison, T::number, none, 0, "s", "wall time of LIGGGHTS",
       "particles-micromodel"},
      {F::engine_comparison_wall_seconds_candidate, "wall_seconds_candidate", F::engine_comparison, T::number, none, 0, "s",
       "wall time of the candidate", "particles-micromodel"},

      {F::detections, "detections", top, T::integer, none, 0, "1", "particle detections over all frames (0: nothing found, `mmval track` says so)",
       "tracking-video (`mmval track`)"},
      {F::scores, "scores", top, T::object, none, 0, "-",
       "the tracks scored against the truth (tracking-challenge scores): `alpha`, `beta`, `jaccard_points`, `jaccard_tracks`, `rmse_px`, ...",
       "tracking-video (with inputs.truth), tracking-synthetic, tracking-rendered"},
      {F::experiment, "experiment", top, T::object, none, 0, "-", "counts of the reference tracks (the `experiment` input) as the comparison analysed them",
       "compare-tracks"},
      {F::experiment_steps, "steps", F::experiment, T::integer, none, 0, "1", "per-frame steps of the reference tracks", "compare-tracks"},
      {F::experiment_mobile, "mobile", F::experiment, T::integer, none, 0, "1", "mobile reference tracks (not immobile)", "compare-tracks"},
  };
}

const char* typeWord(DetailType t, bool plural) {
  switch (t) {
    case T::string: return plural ? "strings" : "a string";
    case T::number: return plural ? "numbers" : "a number";
    case T::integer: return plural ? "integers" : "an integer";
    case T::boolean: return plural ? "booleans" : "true or false";
    case T::object: return plural ? "objects" : "an object";
    case T::array: return plural ? "lists" : "a list";
  }
  return "?";
}

bool hasType(const json& v, DetailType t) {
  switch (t) {
    case T::string: return v.is_string();
    case T::number: return v.is_number() || v.is_null();
    case T::integer: return v.is_number_integer();
    case T::boolean: return v.is_boolean();
    case T::object: return v.is_object();
    case T::array: return v.is_array();
  }
  return false;
}

/// The value as found, cut to a line, with its JSON type.
std::string shown(const json& v) {
  constexpr std::size_t kMaxShown = 60;
  std::string text = v.dump();
  if (text.size() > kMaxShown) text = text.substr(0, kMaxShown - 3) + "...";
  return text + " (" + v.type_name() + ")";
}

[[noreturn]] void wrongType(const std::string& file, const std::string& path, const json& v, const std::string& expected) {
  throw InputError({file, 0, 0, path}, "wrong type", shown(v), expected);
}

/// Checks `v` (found at `path`) against `d`, entries and members included.
void checkValue(const json& v, const DetailFieldDecl& d, const std::string& path, const std::string& file);

void checkMembers(const json& object, DetailField parent, const std::string& path, const std::string& file) {
  for (const auto& d : detailFields()) {
    if (d.parent != parent) continue;
    const auto it = object.find(d.key);
    if (it != object.end()) checkValue(*it, d, path + "." + d.key, file);
  }
}

void checkValue(const json& v, const DetailFieldDecl& d, const std::string& path, const std::string& file) {
  if (!hasType(v, d.type)) wrongType(file, path, v, describeDetailType(d));
  if (d.type == T::object) checkMembers(v, d.field, path, file);
  if (d.type != T::array) return;
  if (d.length > 0 && v.size() != static_cast<std::size_t>(d.length))
    throw InputError({file, 0, 0, path}, fmt::format("a list of {} entries", d.length), shown(v), describeDetailType(d));
  if (!d.element) return;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const std::string at = fmt::format("{}[{}]", path, i);
    if (!hasType(v[i], *d.element)) wrongType(file, at, v[i], typeWord(*d.element, false));
    if (*d.element == T::object) checkMembers(v[i], d.field, at, file);
  }
}

/// The value of top-level `field` in `details` after checking it, or nullptr when absent.
const json* topLevel(const json& details, DetailField field, DetailType accessor) {
  const DetailFieldDecl& d = declaration(field);
  if (d.parent) throw std::logic_error(detailPath(field) + " is a member: read it through its row");
  if (d.type != accessor) throw std::logic_error(detailPath(field) + " is declared " + describeDetailType(d) + ", not " + typeWord(accessor, false));
  if (!details.is_object()) return nullptr;
  const auto it = details.find(d.key);
  if (it == details.end()) return nullptr;
  checkValue(*it, d, std::string("details.") + d.key, {});
  return &*it;
}

/// The value of `member` in `row` after checking it, or nullptr when absent.
const json* memberOf(const DetailRow& row, DetailField member, DetailType accessor) {
  const DetailFieldDecl& d = declaration(member);
  if (d.parent != row.field) throw std::logic_error(detailPath(member) + " is not a member of " + detailPath(row.field));
  if (d.type != accessor) throw std::logic_error(detailPath(member) + " is declared " + describeDetailType(d) + ", not " + typeWord(accessor, false));
  const auto it = row.value->find(d.key);
  if (it == row.value->end()) return nullptr;
  checkValue(*it, d, row.path + "." + d.key, {});
  return &*it;
}

std::optional<double> numberOf(const json* v) {
  if (v == nullptr || v->is_null()) return std::nullopt;
  return v->get<double>();
}

std::optional<long long> integerOf(const json* v) { return v == nullptr ? std::nullopt : std::optional<long long>(v->get<long long>()); }

std::optional<std::string> stringOf(const json* v) { return v == nullptr ? std::nullopt : std::optional<std::string>(v->get<std::string>()); }

}  // namespace

const std::vector<DetailFieldDecl>& detailFields() {
  static const std::vector<DetailFieldDecl> all = [] {
    std::vector<DetailFieldDecl> d = makeDeclarations();
    for (std::size_t i = 0; i < d.size(); ++i)
      if (static_cast<std::size_t>(d[i].field) != i) throw std::logic_error(fmt::format("DetailFields.cpp: declaration {} ('{}') out of order", i, d[i].key));
    return d;
  }();
  return all;
}

const DetailFieldDecl& declaration(DetailField field) {
  const auto& all = detailFields();
  const auto i = static_cast<std::size_t>(field);
  if (i >= all.size()) throw std::logic_error("DetailField without a declaration");
  return all[i];
}

std::string detailPath(DetailField field) {
  const DetailFieldDecl& d = declaration(field);
  if (!d.parent) return std::string("details.") + d.key;
  const DetailFieldDecl& p = declaration(*d.parent);
  return detailPath(*d.parent) + (p.type == T::array ? "[]." : ".") + d.key;
}

std::string describeDetailType(const DetailFieldDecl& decl) {
  if (decl.type != T::array || !decl.element) return typeWord(decl.type, false);
  if (decl.length > 0) return fmt::format("a list of {} {}", decl.length, typeWord(*decl.element, true));
  return std::string("a list of ") + typeWord(*decl.element, true);
}

const json& resultDetails(const json& result) {
  static const json kNone;
  if (!result.is_object()) return kNone;
  const auto it = result.find("details");
  return it == result.end() ? kNone : *it;
}

std::optional<std::string> detailString(const json& details, DetailField field) { return stringOf(topLevel(details, field, T::string)); }

std::optional<double> detailNumber(const json& details, DetailField field) { return numberOf(topLevel(details, field, T::number)); }

std::optional<long long> detailInteger(const json& details, DetailField field) { return integerOf(topLevel(details, field, T::integer)); }

std::optional<std::vector<double>> detailNumbers(const json& details, DetailField field) {
  if (declaration(field).element != T::number) throw std::logic_error(detailPath(field) + " is not a list of numbers");
  const json* v = topLevel(details, field, T::array);
  if (v == nullptr) return std::nullopt;
  std::vector<double> out;
  for (const auto& x : *v) out.push_back(x.is_null() ? std::nan("") : x.get<double>());
  return out;
}

std::optional<std::vector<std::string>> detailStrings(const json& details, DetailField field) {
  if (declaration(field).element != T::string) throw std::logic_error(detailPath(field) + " is not a list of strings");
  const json* v = topLevel(details, field, T::array);
  if (v == nullptr) return std::nullopt;
  return v->get<std::vector<std::string>>();
}

std::optional<DetailRow> detailObject(const json& details, DetailField field) {
  const json* v = topLevel(details, field, T::object);
  if (v == nullptr) return std::nullopt;
  return DetailRow{v, field, detailPath(field)};
}

std::vector<DetailRow> detailRows(const json& details, DetailField field) {
  if (declaration(field).element != T::object) throw std::logic_error(detailPath(field) + " is not a list of objects");
  const json* v = topLevel(details, field, T::array);
  std::vector<DetailRow> rows;
  if (v == nullptr) return rows;
  for (std::size_t i = 0; i < v->size(); ++i) rows.push_back({&(*v)[i], field, fmt::format("{}[{}]", detailPath(field), i)});
  return rows;
}

const json* detailJson(const json& details, DetailField field) {
  const DetailFieldDecl& d = declaration(field);
  return topLevel(details, field, d.type == T::object ? T::object : T::array);
}

std::optional<std::string> detailString(const DetailRow& row, DetailField member) { return stringOf(memberOf(row, member, T::string)); }

std::optional<double> detailNumber(const DetailRow& row, DetailField member) { return numberOf(memberOf(row, member, T::number)); }

std::optional<long long> detailInteger(const DetailRow& row, DetailField member) { return integerOf(memberOf(row, member, T::integer)); }

void setDetail(json& details, DetailField field, json value) {
  const DetailFieldDecl& d = declaration(field);
  if (d.parent) throw std::logic_error(detailPath(field) + " is a member: set its parent");
  try {
    checkValue(value, d, detailPath(field), {});
  } catch (const InputError& e) {
    throw std::logic_error(std::string("writing a declared details field (mmval/core/DetailFields.hpp): ") + e.what());
  }
  if (!details.is_object()) details = json::object();
  details[d.key] = std::move(value);
}

std::vector<std::string> checkDetails(const json& details, const std::string& file) {
  std::vector<std::string> extra;
  if (!details.is_object()) return extra;
  std::set<std::string> declared;
  for (const auto& d : detailFields())
    if (!d.parent) declared.insert(d.key);
  for (const auto& d : detailFields()) {
    if (d.parent) continue;
    const auto it = details.find(d.key);
    if (it != details.end()) checkValue(*it, d, std::string("details.") + d.key, file);
  }
  for (const auto& item : details.items())
    if (!declared.count(item.key())) extra.push_back(item.key());
  std::sort(extra.begin(), extra.end());
  return extra;
}

std::string detailFieldsMarkdown() {
  std::string out = "| field | type | unit | meaning | written by |\n|---|---|---|---|---|\n";
  for (const auto& d : detailFields())
    out += fmt::format("| `{}` | {} | {} | {} | {} |\n", detailPath(d.field).substr(std::string("details.").size()), describeDetailType(d), d.unit,
                       d.meaning, d.writers);
  return out;
}

}  // namespace mmval
