// Every file in reference-data/ loads through the one loader, with units
// that parse, sources that resolve and a value or interval per row; spot
// checks compare a few rows with the numbers in the cited sources.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "mmval/core/Error.hpp"
#include "mmval/core/ReferenceData.hpp"

namespace mmval {
namespace {

const std::filesystem::path kDir = std::filesystem::path(MMVAL_SOURCE_DIR) / "reference-data";

TEST(ReferenceData, EveryFileLoadsAndChecks) {
  int files = 0;
  for (const auto& e : std::filesystem::directory_iterator(kDir)) {
    if (e.path().extension() != ".toml") continue;
    ++files;
    SCOPED_TRACE(e.path().string());
    const ReferenceFile* f = nullptr;
    ASSERT_NO_THROW(f = &loadReferenceFile(e.path()));
    EXPECT_FALSE(f->title.empty());
    EXPECT_FALSE(f->rows.empty());
    for (const auto& r : f->rows) {
      EXPECT_NO_THROW(f->source(r.source));
      EXPECT_TRUE(r.value.has_value() != (r.low.has_value() && r.high.has_value()));
      EXPECT_GT(r.unit_si.to_si, 0.0);
    }
  }
  EXPECT_GE(files, 8);
}

double valueOf(const char* file, const char* quantity, const AtMap& at) {
  const auto rows = loadReferenceFile(kDir / file).find(quantity, at);
  EXPECT_EQ(rows.size(), 1u) << quantity << " " << toString(at);
  if (rows.size() != 1 || !rows[0]->value) return std::nan("");
  return *rows[0]->value * rows[0]->unit_si.to_si;
}

TEST(ReferenceData, SpotChecksAgainstTheSources) {
  EXPECT_DOUBLE_EQ(valueOf("schaefer-turek-2d.toml", "c_D", {{"case", std::string("2D-1")}}), 5.57953523384);
  EXPECT_DOUBLE_EQ(valueOf("cylinder-drag-dennis-chang.toml", "c_D", {{"Re", 40.0}}), 1.522);
  // Sangani & Acrivos (1982): k / L^2 = 1.941e-2 at solid fraction 0.2.
  EXPECT_DOUBLE_EQ(valueOf("square-array-permeability.toml", "k_over_L2", {{"phi", 0.2}}), 1.941e-2);
  // The micromodel: 2.5 D measured permeability, in m^2.
  const auto chip = loadReferenceFile(kDir / "chip-permeability-table2.toml");
  bool found = false;
  for (const auto& r : chip.rows)
    if (r.quantity == "permeability" && r.value && std::abs(*r.value * r.unit_si.to_si - 2.5 * 9.869233e-13) < 1e-16) found = true;
  EXPECT_TRUE(found) << "2.5 D measured chip permeability not found";
}

TEST(ReferenceData, MalformedFileNamesLineAndKey) {
  const auto dir = std::filesystem::path(MMVAL_BINARY_DIR) / "test-output";
  std::filesystem::create_directories(dir);
  const auto bad = dir / "bad-reference.toml";
  {
    std::ofstream out(bad);
    out << "format = \"mmval-reference/1\"\ntitle = \"t\"\ndescription = \"d\"\n[[sources]]\nid = \"a\"\ncitation = \"c\"\n"
           "[[rows]]\nquantity = \"x\"\nvalue = 1.0\nunit = \"furlong\"\nsource = \"a\"\n";
  }
  try {
    loadReferenceFile(bad);
    FAIL() << "expected InputError";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("bad-reference.toml:10"), std::string::npos) << msg;
    EXPECT_NE(msg.find("rows[0].unit"), std::string::npos) << msg;
  }
}

}  // namespace
}  // namespace mmval
