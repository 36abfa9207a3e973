// Shared key blocks (Schema.hpp: declareFluid, declareMask): every kind that
// reads one of these keys declares it through its block, so the key means the
// same thing, with the same unit, bounds and choices, in every case file.
// A kind that declares such a key by hand, differently, fails here.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "AllKinds.hpp"
#include "mmval/core/CaseKind.hpp"
#include "mmval/core/Schema.hpp"
#include "mmval/core/SchemaBlocks.hpp"

using namespace mmval;

namespace {

const mmval::CaseKindRegistry& registry() { return mmval::test::allKinds(); }

/// The blocks' own declarations, to compare every kind's against.
const Schema& reference() {
  static const Schema s = [] {
    Schema x("reference", "the blocks");
    declareFluid(x, {.with_temperature = true});
    declareMask(x, {.mask_doc = "an image"});
    return x;
  }();
  return s;
}

void expectSameMeaning(const KeyDecl& got, const KeyDecl& want, const std::string& kind) {
  const std::string where = kind + ": " + got.key;
  EXPECT_EQ(got.type, want.type) << where;
  EXPECT_EQ(got.unit, want.unit) << where;
  EXPECT_EQ(got.min, want.min) << where;
  EXPECT_EQ(got.min_exclusive, want.min_exclusive) << where;
  EXPECT_EQ(got.max, want.max) << where;
  EXPECT_EQ(got.choices, want.choices) << where;
  if (got.key != "geometry.mask") EXPECT_EQ(got.doc, want.doc) << where;  // the image's role is the kind's to say
}

TEST(SchemaBlocks, EveryKindDeclaresTheSharedKeysThroughTheirBlock) {
  const std::vector<std::string> shared = {"fluid.viscosity", "fluid.density", "fluid.temperature", "geometry.mask", "geometry.pixel_size",
                                           "geometry.grains"};
  int declarations = 0;
  for (const auto& kind : registry().names()) {
    const Schema& s = registry().schema(kind);
    for (const auto& key : shared) {
      const KeyDecl* got = s.find(key);
      // A kind with an image but without grains/pixel size is not one of these (e.g. the tracker's video is no mask).
      if (got == nullptr) continue;
      if (key.rfind("geometry.", 0) == 0 && s.find("geometry.grains") == nullptr) continue;
      expectSameMeaning(*got, *reference().find(key), kind);
      ++declarations;
    }
  }
  // Today: fluid keys in 10+ kinds, the mask block in 5; the count guards against the loop finding nothing.
  EXPECT_GE(declarations, 25);
}

TEST(SchemaBlocks, GrainsReadTheOlderSpellingAsBright) {
  EXPECT_EQ(grainChoices(), (std::vector<std::string>{"dark", "bright", "light"}));
  const KeyDecl* g = reference().find("geometry.grains");
  ASSERT_NE(g, nullptr);
  EXPECT_EQ(g->def_text, "dark");
}

}  // namespace
