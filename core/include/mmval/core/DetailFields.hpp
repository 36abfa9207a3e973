// The declared fields of result.json's "details": every field that a reader
// (the report, validate, the command line, tests) takes out of a run's details
// is declared here once, with its JSON type, unit, meaning and the kinds that
// write it. Readers go through the accessors below, which take a DetailField
// (never a spelled key) and check the declared type, so a reader cannot read
// an undeclared key and a writer that changes a type is named in the error.
// Kinds may write further keys (informational; shown as they are): they are
// allowed, listed by checkDetails, and read by nobody. docs/outputs.md
// ("details fields") holds detailFieldsMarkdown(), checked by
// tests/core/DetailFieldsTest.cpp.
#pragma once
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace mmval {

/// The JSON type of a declared field. `number` accepts any JSON number, and
/// null: JSON has no NaN or infinity, so a non-finite value is written as null
/// and reads as absent. `integer` accepts JSON integers only.
enum class DetailType { string, number, integer, boolean, object, array };

/// Every declared field. Members of an object field, or of each entry of an
/// array-of-objects field, carry their parent's name as a prefix.
enum class DetailField {
  // Who computed the numbers and what of the setting the report needs.
  solver,
  liggghts_version,
  table3_case,
  Re,
  status,
  cells,
  warnings,
  undeclared_metrics,
  // Resolution ladders of the fluid kinds.
  ladder,
  ladder_level,
  ladder_value,
  ladder_error,
  ladder_observed_order,
  ladder_wall_seconds,
  ladder_cpu_seconds,
  ladder_cells,
  ladder_time_steps,
  ladder_c_D_max,
  ladder_status,
  ladder_linear_solver,
  ladder_linear_solver_reason,
  ladder_linear_solver_fallback,
  ladder_linear_true_residual,
  ladder_velocity_preconditioner,
  ladder_flux_change,
  runs,
  runs_3d,
  grid_convergence,
  narrowest_throat,
  depth_model_throat,
  // Unsteady cylinder.
  statistics_window_s,
  shedding_periods,
  time_steps,
  resumed_from_step,
  resumed_levels,
  // Particle runs.
  resumed_from_frame,
  end_time_s,
  pump_stall,
  passable_diameter_um,
  straining,
  coupling,
  coupling_mode,
  coupling_fluid_grid_cells,
  coupling_cells_per_diameter,
  coupling_deposits_at_walls,
  coupling_deposits_on_plates,
  reference,
  reference_description,
  reference_file,
  square_array,
  engine_comparison,
  engine_comparison_candidate,
  engine_comparison_window_s,
  engine_comparison_particles,
  engine_comparison_rms_position_difference_m,
  engine_comparison_median_final_difference_m,
  engine_comparison_max_position_difference_m,
  engine_comparison_captured_reference,
  engine_comparison_captured_candidate,
  engine_comparison_captured_both,
  engine_comparison_rms_capture_time_difference_s,
  engine_comparison_retained_fraction_reference,
  engine_comparison_retained_fraction_candidate,
  engine_comparison_wall_seconds_reference,
  engine_comparison_wall_seconds_candidate,
  // Tracking and comparing tracks.
  detections,
  scores,
  experiment,
  experiment_steps,
  experiment_mobile,
};

/// One declaration. `parent` is empty for a key of details itself; for a
/// member it is the object field (or array-of-objects field) holding it.
struct DetailFieldDecl {
  DetailField field;
  const char* key;                    ///< the JSON key inside its parent
  std::optional<DetailField> parent;  ///< object or array-of-objects field, or none
  DetailType type;
  std::optional<DetailType> element;  ///< entries' type, for an array
  int length;                         ///< required entries of an array; 0: any
  const char* unit;                   ///< "1": dimensionless or a count; "-": not a quantity (text, objects)
  const char* meaning;                ///< one line
  const char* writers;                ///< the kinds or commands that write it
};

/// Every declaration, in DetailField order.
const std::vector<DetailFieldDecl>& detailFields();

/// The declaration of `field`.
const DetailFieldDecl& declaration(DetailField field);

/// "details.ladder[].wall_seconds": where the field lives in result.json.
std::string detailPath(DetailField field);

/// "a number", "a list of 2 numbers", "a list of objects", ...
std::string describeDetailType(const DetailFieldDecl& decl);

/// An object that has declared members: details.experiment, or one entry of
/// details.ladder. `path` names it in errors ("details.ladder[2]").
struct DetailRow {
  const nlohmann::json* value = nullptr;  ///< an object
  DetailField field;                      ///< the object or array field it belongs to
  std::string path;
};

/// A run's "details" (result.json), or null when it has none: what the
/// accessors below take.
const nlohmann::json& resultDetails(const nlohmann::json& result);

// Accessors. `details` is a run's "details" value (of any JSON type: a
// non-object has no fields). Each returns nothing when the field is absent
// (a number also when null) and throws InputError naming details.<field>,
// the value found and the declared type when it holds another type. Asking
// for a field with an accessor of another type, or a member through the
// wrong row, is a bug in the caller (std::logic_error).

std::optional<std::string> detailString(const nlohmann::json& details, DetailField field);
std::optional<double> detailNumber(const nlohmann::json& details, DetailField field);
std::optional<long long> detailInteger(const nlohmann::json& details, DetailField field);
/// An array of numbers (of the declared length, when one is declared).
std::optional<std::vector<double>> detailNumbers(const nlohmann::json& details, DetailField field);
/// An array of strings.
std::optional<std::vector<std::string>> detailStrings(const nlohmann::json& details, DetailField field);
/// An object field, as a row for its members.
std::optional<DetailRow> detailObject(const nlohmann::json& details, DetailField field);
/// An array-of-objects field, one row per entry; empty when absent.
std::vector<DetailRow> detailRows(const nlohmann::json& details, DetailField field);
/// An object or array field as it stands (no declared members), or nullptr.
const nlohmann::json* detailJson(const nlohmann::json& details, DetailField field);

std::optional<std::string> detailString(const DetailRow& row, DetailField member);
std::optional<double> detailNumber(const DetailRow& row, DetailField member);
std::optional<long long> detailInteger(const DetailRow& row, DetailField member);

/// For writers: sets details.<field> (a key of details itself) to `value`
/// after checking it against the declaration (members and entries too), so
/// that a kind cannot write a declared field in another type; a mismatch is a
/// bug in the writer (std::logic_error naming the field).
void setDetail(nlohmann::json& details, DetailField field, nlohmann::json value);

/// Checks every declared field present in `details` (members too, in every
/// entry) against its declared type and array length; throws InputError naming
/// `file` and the field's path. Returns the keys of details that no
/// declaration names (allowed: informational, read by nobody), sorted.
std::vector<std::string> checkDetails(const nlohmann::json& details, const std::string& file);

/// The "details fields" table of docs/outputs.md: one row per declaration.
std::string detailFieldsMarkdown();

}  // namespace mmval
