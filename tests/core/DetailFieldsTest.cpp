// The declared details fields (mmval/core/DetailFields.hpp): every declaration
// is complete, the accessors check the declared type and name the field when it
// is wrong, undeclared keys are allowed and listed, and docs/outputs.md holds
// the table the declarations generate.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <stdexcept>

#include <nlohmann/json.hpp>

#include "mmval/core/DetailFields.hpp"
#include "mmval/core/Error.hpp"

#include "../InputErrorMessage.hpp"

namespace mmval {
namespace {

using ::testing::HasSubstr;
using json = nlohmann::json;
using F = DetailField;

/// The message of the InputError `f` throws ("(no InputError)" when it throws none).
std::string inputErrorOf(const std::function<void()>& f) { return mmval::test::inputErrorMessage(f); }

TEST(DetailFields, EveryDeclarationHasTypeUnitMeaningAndWriters) {
  std::set<std::string> paths;
  for (const auto& d : detailFields()) {
    const std::string path = detailPath(d.field);
    SCOPED_TRACE(path);
    EXPECT_TRUE(paths.insert(path).second) << "declared twice";
    EXPECT_EQ(&declaration(d.field), &d);
    EXPECT_STRNE(d.key, "");
    EXPECT_STRNE(d.unit, "") << "a unit, \"1\" or \"-\"";
    EXPECT_GT(std::string(d.meaning).size(), 10U);
    EXPECT_STRNE(d.writers, "");
    EXPECT_EQ(d.element.has_value(), d.type == DetailType::array) << "an array, and only an array, declares its entries' type";
    if (d.length > 0) {
      EXPECT_EQ(d.type, DetailType::array);
    }
    if (d.parent) {
      const DetailFieldDecl& p = declaration(*d.parent);
      EXPECT_TRUE(p.type == DetailType::object || p.element == DetailType::object) << "members belong to an object or a list of objects";
    }
    // A quantity carries its unit; text and objects none.
    if (d.type == DetailType::string || d.type == DetailType::object) {
      EXPECT_STREQ(d.unit, "-");
    }
  }
  EXPECT_EQ(detailPath(F::ladder_wall_seconds), "details.ladder[].wall_seconds");
  EXPECT_EQ(detailPath(F::experiment_steps), "details.experiment.steps");
}

TEST(DetailFields, ValuesOfTheDeclaredTypeAreRead) {
  const json d = json::parse(R"({"solver": "openfoam 2312", "Re": 20.0, "shedding_periods": 4, "statistics_window_s": [6.5, 7.75],
    "warnings": ["a", "b"], "ladder": [{"wall_seconds": 0.5, "error": -0.02, "cells": 64}, {"wall_seconds": 1.5}],
    "experiment": {"steps": 390, "mobile": 10}, "free text": {"anything": [1, "x"]}})");
  EXPECT_EQ(detailString(d, F::solver), "openfoam 2312");
  EXPECT_DOUBLE_EQ(detailNumber(d, F::Re).value(), 20.0);
  EXPECT_EQ(detailInteger(d, F::shedding_periods), 4);
  EXPECT_THAT(detailNumbers(d, F::statistics_window_s).value(), ::testing::ElementsAre(::testing::DoubleEq(6.5), ::testing::DoubleEq(7.75)));
  EXPECT_EQ(detailStrings(d, F::warnings), (std::vector<std::string>{"a", "b"}));
  const auto rows = detailRows(d, F::ladder);
  ASSERT_EQ(rows.size(), 2U);
  EXPECT_EQ(rows[1].path, "details.ladder[1]");
  EXPECT_DOUBLE_EQ(detailNumber(rows[0], F::ladder_error).value(), -0.02);
  EXPECT_EQ(detailInteger(rows[0], F::ladder_cells), 64);
  EXPECT_DOUBLE_EQ(detailNumber(rows[1], F::ladder_wall_seconds).value(), 1.5);
  EXPECT_FALSE(detailNumber(rows[1], F::ladder_error).has_value());
  const auto side = detailObject(d, F::experiment);
  ASSERT_TRUE(side.has_value());
  EXPECT_EQ(detailInteger(*side, F::experiment_steps), 390);
}

TEST(DetailFields, AbsentNullAndNonObjectDetailsReadAsNothing) {
  // JSON has no NaN: a non-finite number is written as null and reads as absent.
  const json d = json::parse(R"({"Re": null, "statistics_window_s": [null, 2.0]})");
  EXPECT_FALSE(detailNumber(d, F::Re).has_value());
  EXPECT_TRUE(std::isnan(detailNumbers(d, F::statistics_window_s)->at(0)));
  EXPECT_FALSE(detailString(d, F::solver).has_value());
  EXPECT_TRUE(detailRows(d, F::ladder).empty());
  for (const json& none : {json(nullptr), json(3), json::array({1})}) {
    EXPECT_FALSE(detailString(none, F::solver).has_value());
    EXPECT_TRUE(checkDetails(none, "result.json").empty());
  }
  EXPECT_TRUE(resultDetails(json::object()).is_null());
  EXPECT_DOUBLE_EQ(detailNumber(resultDetails(json{{"details", {{"Re", 1.0}}}}), F::Re).value(), 1.0);
}

TEST(DetailFields, WrongTypeNamesTheFieldTheValueAndTheDeclaredType) {
  EXPECT_EQ(inputErrorOf([] { detailNumber(json{{"Re", "twenty"}}, F::Re); }),
            "key 'details.Re': wrong type; got \"twenty\" (string); expected a number");
  EXPECT_THAT(inputErrorOf([] { detailInteger(json{{"shedding_periods", 2.5}}, F::shedding_periods); }),
              HasSubstr("key 'details.shedding_periods': wrong type; got 2.5 (number); expected an integer"));
  EXPECT_THAT(inputErrorOf([] { detailNumbers(json{{"statistics_window_s", {6.5}}}, F::statistics_window_s); }),
              HasSubstr("key 'details.statistics_window_s': a list of 2 entries; got [6.5] (array); expected a list of 2 numbers"));
  EXPECT_THAT(inputErrorOf([] { detailString(json{{"solver", 1}}, F::solver); }), HasSubstr("key 'details.solver': wrong type; got 1 (number); expected a string"));
  // Members and entries are named by their place; a list is checked whole when it is read.
  const json ladder{{"ladder", {{{"wall_seconds", 1.0}}, {{"wall_seconds", "slow"}}}}};
  EXPECT_THAT(inputErrorOf([&] { detailRows(ladder, F::ladder); }),
              HasSubstr("key 'details.ladder[1].wall_seconds': wrong type; got \"slow\" (string); expected a number"));
  EXPECT_THAT(inputErrorOf([] { detailRows(json{{"ladder", {1, 2}}}, F::ladder); }),
              HasSubstr("key 'details.ladder[0]': wrong type; got 1 (number); expected an object"));
}

TEST(DetailFields, CheckDetailsNamesTheFileAndListsUndeclaredKeys) {
  const json good = json::parse(R"({"solver": "mmval", "zeta": 1, "alpha": {"x": 2}, "engine_comparison": [{"particles": 40, "extra": "ok"}]})");
  EXPECT_EQ(checkDetails(good, "runs/x/result.json"), (std::vector<std::string>{"alpha", "zeta"}));
  json bad = good;
  bad["engine_comparison"][0]["particles"] = 40.5;
  EXPECT_THAT(inputErrorOf([&] { checkDetails(bad, "runs/x/result.json"); }),
              HasSubstr("runs/x/result.json: key 'details.engine_comparison[0].particles': wrong type; got 40.5 (number); expected an integer"));
  bad = good;
  bad["experiment"] = {{"steps", "many"}};
  EXPECT_THAT(inputErrorOf([&] { checkDetails(bad, "r.json"); }), HasSubstr("r.json: key 'details.experiment.steps': wrong type"));
}

TEST(DetailFields, ReadingWithAnAccessorOfAnotherTypeIsABug) {
  const json d{{"Re", 20.0}, {"ladder", {{{"wall_seconds", 1.0}}}}};
  EXPECT_THROW(detailString(d, F::Re), std::logic_error);
  EXPECT_THROW(detailNumber(d, F::ladder_wall_seconds), std::logic_error);  // a member, not a key of details
  const auto rows = detailRows(d, F::ladder);
  EXPECT_THROW(detailInteger(rows[0], F::experiment_steps), std::logic_error);  // a member of another field
  EXPECT_THROW(detailNumbers(d, F::ladder), std::logic_error);
}

TEST(DetailFields, SetDetailWritesTheDeclaredKeyAndRefusesAnotherType) {
  json d = json::object();
  setDetail(d, F::statistics_window_s, {6.5, 7.75});
  setDetail(d, F::solver, "mmval");
  EXPECT_EQ(detailString(d, F::solver), "mmval");
  EXPECT_THAT(detailNumbers(d, F::statistics_window_s).value(), ::testing::ElementsAre(::testing::DoubleEq(6.5), ::testing::DoubleEq(7.75)));
  EXPECT_THROW(setDetail(d, F::statistics_window_s, {6.5}), std::logic_error);
  EXPECT_THROW(setDetail(d, F::shedding_periods, 2.5), std::logic_error);
  EXPECT_THROW(setDetail(d, F::ladder_wall_seconds, 1.0), std::logic_error);
  EXPECT_EQ(d.size(), 2U) << "a refused value is not written";
}

TEST(DetailFields, OneTypePerKeyWhateverTheKind) {
  // Keys that several kinds write have one declaration each (one type whatever the kind):
  // the forms that are no longer allowed are refused at the writer.
  json d = json::object();
  EXPECT_THROW(setDetail(d, F::coupling, "resolved immersed boundary: 16 cells per diameter"), std::logic_error);  // particles-resolved's old string
  EXPECT_THROW(setDetail(d, F::reference, "Graetz series for plane Poiseuille flow"), std::logic_error);           // the slit checks' old string
  EXPECT_THROW(setDetail(d, F::warnings, "forces are coarse"), std::logic_error);                                   // a list, even of one
  EXPECT_THROW(setDetail(d, F::coupling, {{"mode", "resolved"}, {"fluid_grid_cells", {50}}}), std::logic_error);     // x and y
  EXPECT_THROW(setDetail(d, F::table3_case, 3), std::logic_error);
  EXPECT_TRUE(d.empty());
  setDetail(d, F::coupling, {{"mode", "four-way"}, {"fluid_grid_cells", {30, 15}}, {"deposits_on_plates", 3}, {"layer_packing", 0.36}});
  setDetail(d, F::reference, {{"description", "Boltzmann (Perrin 1909)"}, {"l_s_um", 0.787}});
  const auto coupling = detailObject(d, F::coupling);
  ASSERT_TRUE(coupling.has_value());
  EXPECT_EQ(detailString(*coupling, F::coupling_mode), "four-way");
  EXPECT_EQ(detailInteger(*coupling, F::coupling_deposits_on_plates), 3);
  EXPECT_FALSE(detailInteger(*coupling, F::coupling_deposits_at_walls).has_value());
  const auto reference = detailObject(d, F::reference);
  ASSERT_TRUE(reference.has_value());
  EXPECT_EQ(detailString(*reference, F::reference_description), "Boltzmann (Perrin 1909)");
  EXPECT_EQ(detailPath(F::coupling_fluid_grid_cells), "details.coupling.fluid_grid_cells");
}

TEST(DetailFields, OutputsDocListsEveryDeclaredField) {
  std::ifstream in(std::filesystem::path(MMVAL_SOURCE_DIR) / "docs" / "outputs.md");
  ASSERT_TRUE(in) << "docs/outputs.md";
  std::stringstream text;
  text << in.rdbuf();
  const std::string table = detailFieldsMarkdown();
  EXPECT_NE(text.str().find(table), std::string::npos) << "docs/outputs.md, section \"details fields\", should hold the table the declarations give:\n"
                                                       << table;
  for (const auto& d : detailFields()) EXPECT_NE(table.find("| `" + detailPath(d.field).substr(8) + "` |"), std::string::npos) << detailPath(d.field);
}

}  // namespace
}  // namespace mmval
