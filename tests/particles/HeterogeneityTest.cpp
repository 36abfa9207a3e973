// Patchwise charge heterogeneity of the glass under deposition.model = "dlvo"
// (chemistry.favourable_fraction, lambda; Song, Johnson & Elimelech 1994, Environ. Sci. Technol.
// 28:1164): an arrival at a plate or grain lands on a favourable patch with probability lambda and
// attaches in the primary minimum, else the unfavourable DLVO rule decides, so the efficiency per
// arrival is alpha_eff = lambda + (1 - lambda) alpha_unf. Tested with one arrival per particle:
//   settling onto the bottom plate in still fluid (as in DepositionModelTest): at 3 mM the
//     unfavourable rule holds the Maxwell fraction P of the 1.5 kT secondary minimum (alpha over
//     the barrier ~ exp(-1.3e4)); each particle's fate follows from its own draw, and lambda = 0 is
//     the rule without heterogeneity particle by particle;
//   settling with no surface force at 1 mM (alpha_unf = 0, no secondary capture): the deposition
//     rate onto the plate is lambda times the Stokes settling flux, the rate of colloid filtration
//     theory (attachment efficiency times the transport rate; Yao, Habibian & O'Melia 1971).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "CaseScene.hpp"
#include "ParticleRegistry.hpp"
#include "mmval/core/Case.hpp"
#include "mmval/core/Checkpoint.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/particles/Dlvo.hpp"
#include "mmval/particles/OverdampedEngine.hpp"

namespace mmval::particles {
namespace {

SceneConfig glassScene(double ionic_strength_mM, double favourable_fraction) {
  SceneConfig c;
  c.brownian = false;
  c.wall_hindrance = false;  // Stokes settling: the arrival times below are analytic
  c.attachment.capture_distance = 0.1e-6;
  c.attachment.grains = false;
  c.attachment.rule = AttachmentModel::Rule::dlvo;
  c.attachment.chemistry.electrolyte.ionic_strength = ionic_strength_mM;
  c.attachment.chemistry.collector_potential = -0.077;
  c.attachment.chemistry.electrolyte.temperature = c.fluid.temperature;
  c.attachment.favourable_fraction = favourable_fraction;
  c.seed = 7;
  return c;
}

/// The engine's per-arrival draw, written out from its documented definition (splitmix64 of
/// seed, particle id and arrival number; OverdampedEngine::arrivalDraw): the oracle that says which
/// particle each rule must hold.
double arrivalDraw(std::uint64_t seed, std::int64_t id, std::uint32_t arrival) {
  std::uint64_t z = seed * 0x9E3779B97F4A7C15ULL ^ static_cast<std::uint64_t>(id) * 0xBF58476D1CE4E5B9ULL ^ (static_cast<std::uint64_t>(arrival) << 40);
  z += 0x9E3779B97F4A7C15ULL;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  z ^= z >> 31;
  return static_cast<double>(z >> 11) * 0x1.0p-53;
}

constexpr int kSide = 20, kN = kSide * kSide;

/// kN particles, one per 20 um column, settle onto the bottom plate in still fluid: one arrival each.
std::unique_ptr<OverdampedEngine> settle(const SceneConfig& c, const std::vector<double>& heights, double t_end) {
  const double a = c.particle.radius(), h = 42e-6 + 2 * a;
  auto e = std::make_unique<OverdampedEngine>(std::make_shared<UniformFlow>(Vec2(0, 0), h), c);
  std::vector<Vec3> xs;
  for (int k = 0; k < kN; ++k) xs.emplace_back((k % kSide) * 20e-6, (k / kSide) * 20e-6, heights[static_cast<std::size_t>(k)]);
  e->insert(xs);
  e->advance(t_end);
  return e;
}

std::vector<double> sameHeight(const SceneConfig& c) { return std::vector<double>(kN, c.particle.radius() + 20e-6); }

// 3 mM, lambda = 0, 0.1, 0.4. Every particle arrives once; its draw u decides: u < lambda attaches
// in the primary minimum (a favourable patch), else it is held in the secondary minimum when
// (u - lambda) / (1 - lambda) < P (the unfavourable rule on the rescaled draw), else it stays
// mobile. Checked particle by particle against the oracle (exact), and the fractions against
// alpha_eff = lambda + (1 - lambda) P and lambda within 4 binomial standard errors of 400 arrivals
// (0.098 at alpha_eff = 0.5; a fraction outside is a 6e-5 chance if the model holds). lambda = 0
// holds exactly the particles the rule without heterogeneity holds: the same draw, unchanged.
TEST(Heterogeneity, EachArrivalAttachesWithThePatchwiseEfficiency) {
  for (const double lambda : {0.0, 0.1, 0.4}) {
    const SceneConfig c = glassScene(3.0, lambda);
    const auto e = settle(c, sameHeight(c), 40.0);
    const SurfaceChemistry* sc = e->chemistry(Surface::bottom);
    ASSERT_NE(sc, nullptr);
    ASSERT_LT(sc->attachment.ln_alpha, -100.0);  // alpha_unf over the barrier: 0 in double
    const double p_sec = sc->secondary_capture;
    ASSERT_GT(p_sec, 0.3);
    ASSERT_LT(p_sec, 0.9);
    int primary = 0, secondary = 0, mismatched = 0;
    for (const auto& p : e->particles()) {
      ASSERT_EQ(p.arrivals, 1u) << "particle " << p.id << ": the test needs one arrival per particle";
      const double u = arrivalDraw(c.seed, p.id, 1);
      const bool want_primary = u < lambda;
      const bool want_secondary = !want_primary && (lambda > 0 ? (u - lambda) / (1 - lambda) : u) < p_sec;
      const bool held = p.status == ParticleStatus::deposited && p.held_by == Surface::bottom;
      mismatched += (held && !p.secondary) != want_primary || (held && p.secondary) != want_secondary ? 1 : 0;
      primary += held && !p.secondary ? 1 : 0;
      secondary += held && p.secondary ? 1 : 0;
    }
    EXPECT_EQ(mismatched, 0) << "lambda " << lambda;
    const double eff = patchwiseEfficiency(lambda, p_sec), frac = (primary + secondary) / double(kN);
    const double se = std::sqrt(eff * (1 - eff) / kN), se_l = std::sqrt(lambda * (1 - lambda) / kN);
    std::printf("lambda %.2f: %d primary + %d secondary of %d (%.3f), lambda + (1 - lambda) P = %.3f, 4 SE %.3f\n", lambda, primary, secondary,
                kN, frac, eff, 4 * se);
    EXPECT_NEAR(frac, eff, 4 * se) << "lambda " << lambda;
    EXPECT_NEAR(primary / double(kN), lambda, 4 * se_l) << "lambda " << lambda;
    if (lambda == 0) {
      EXPECT_EQ(primary, 0);
    }
  }
}

// Deposition rate onto a plate = alpha_eff x transport rate. 1 mM glass (barrier ~1.4e4 kT, well
// < 1 kT: alpha_unf = 0, no secondary capture) and no surface force (attraction_range 0), so the
// transport is Stokes settling alone, v_s = 2 (rho_p - rho_f) g a^2 / (9 mu), computed here: the
// particle released at height z arrives at t = (z - a - capture distance) / v_s. Heights spread
// evenly over 40 um make the arrival flux constant; the number attached by time t must be lambda
// times the number arrived, within 4 binomial standard errors, for two lambdas (rate doubles with
// lambda), and each attached particle attaches at its analytic arrival time within the 20 ms
// steps (its arrival falls in one step; 2 steps allowed for the step that ends after it). The
// step also shifts which particles count as arrived at t by at most a particle or two, below
// 1 SE. A rejected particle rests on the plate (no force lifts it): one arrival.
TEST(Heterogeneity, DepositionRateIsLambdaTimesTheSettlingFlux) {
  for (const double lambda : {0.15, 0.3}) {
    SceneConfig c = glassScene(1.0, lambda);
    c.attachment.attraction_range = 0;
    c.max_dt = 0.02;
    const double a = c.particle.radius(), cd = c.attachment.capture_distance;
    const double vs = 2.0 * (c.particle.density - c.fluid.density) * c.gravity * a * a / (9.0 * c.fluid.viscosity);
    std::vector<double> z(kN);
    for (int k = 0; k < kN; ++k) z[static_cast<std::size_t>((k * 173) % kN)] = a + cd + 0.5e-6 + 40e-6 * (k + 0.5) / kN;
    for (const double t : {20.0, 40.0, 70.0}) {
      const auto e = settle(c, z, t);
      int arrived = 0, attached = 0;
      for (const auto& p : e->particles()) {
        const double t_arrive = (z[static_cast<std::size_t>(p.id - 1)] - a - cd) / vs;
        arrived += t_arrive <= t ? 1 : 0;
        attached += p.status == ParticleStatus::deposited ? 1 : 0;
        ASSERT_LE(p.arrivals, 1u);
        if (p.status == ParticleStatus::deposited) {
          EXPECT_FALSE(p.secondary);
          // It attaches at its one arrival: in the step that takes it within the capture distance.
          EXPECT_GE(p.t_event, t_arrive - c.max_dt);
          EXPECT_LE(p.t_event, t_arrive + 2 * c.max_dt);
        }
      }
      ASSERT_GT(arrived, 50);
      const double se = std::sqrt(arrived * lambda * (1 - lambda));
      std::printf("lambda %.2f, t %.0f s: %d attached of %d arrived (Stokes), expected %.1f +- %.1f (4 SE)\n", lambda, t, attached, arrived,
                  lambda * arrived, 4 * se);
      EXPECT_NEAR(attached, lambda * arrived, 4 * se) << "lambda " << lambda << ", t " << t;
    }
  }
}

// Deposits are latex and keep their own chemistry: lambda = 1 makes every glass arrival attach and
// leaves the deposits' rule alone; the engine reports lambda and the efficiency it gives.
TEST(Heterogeneity, GlassOnlyAndReported) {
  const SceneConfig c = glassScene(1.0, 1.0);
  const auto e = settle(c, sameHeight(c), 40.0);
  int held = 0;
  for (const auto& p : e->particles()) held += p.status == ParticleStatus::deposited && p.held_by == Surface::bottom && !p.secondary ? 1 : 0;
  EXPECT_EQ(held, kN);
  const auto het = e->describe()["dlvo"]["charge_heterogeneity"];
  EXPECT_EQ(het["favourable_fraction"].get<double>(), 1.0);
  EXPECT_EQ(het["primary_attachment_efficiency"].get<double>(), 1.0);
  EXPECT_EQ(e->chemistry(Surface::deposit)->alpha, 0.0);  // latex-latex at 1 mM: the barrier stays

  EXPECT_DOUBLE_EQ(patchwiseEfficiency(0.25, 0.2), 0.25 + 0.75 * 0.2);
  EXPECT_EQ(patchwiseEfficiency(0.0, 0.3), 0.3);
  EXPECT_THROW(patchwiseEfficiency(-0.1, 0.3), std::invalid_argument);
  EXPECT_THROW(patchwiseEfficiency(0.5, 1.5), std::invalid_argument);
}

// ---- Patches placed in space (chemistry.patch_size > 0, FavourablePatchMap) ----

// Coverage: each cell is favourable with probability lambda, independently of its neighbours and
// of the other surfaces. Over n = 250 x 250 cells of each sheet the favourable fraction is within
// 4 binomial standard errors sqrt(lambda (1 - lambda) / n) of lambda, and the fraction of
// neighbouring pairs (i, j), (i + 1, j) both favourable within 4 SE of lambda^2 (independent
// cells; a hash with stripes along i would fail it). The map of a smaller lambda (same seed and
// size) lies inside the map of a larger one. A point's cell: floor(x / size) on the plates (also at
// negative x), shifted by kWallShift on the walls.
TEST(Heterogeneity, PatchMapCoversLambdaOfTheCells) {
  using Sheet = FavourablePatchMap::Sheet;
  constexpr int kCells = 250;
  const double n = double(kCells) * kCells;
  for (const double lambda : {0.01, 0.2, 0.5}) {
    for (const Sheet sheet : {Sheet::bottom, Sheet::top, Sheet::walls}) {
      const FavourablePatchMap map{lambda, 3e-6, 11};
      long fav = 0, pairs = 0;
      for (int i = -kCells / 2; i < kCells / 2; ++i)
        for (int j = 0; j < kCells; ++j) {
          const std::int64_t k = sheet == Sheet::walls ? 7 : 0;
          const bool f = map.cellValue(sheet, i, j, k) < lambda;
          fav += f ? 1 : 0;
          pairs += f && map.cellValue(sheet, i + 1, j, k) < lambda ? 1 : 0;
        }
      const double se = std::sqrt(lambda * (1 - lambda) / n), se2 = std::sqrt(lambda * lambda * (1 - lambda * lambda) / n);
      EXPECT_NEAR(fav / n, lambda, 4 * se) << "lambda " << lambda << ", sheet " << int(sheet);
      EXPECT_NEAR(pairs / n, lambda * lambda, 4 * se2) << "lambda " << lambda << ", sheet " << int(sheet);
    }
    // The bottom and top plates carry independent maps: both favourable at lambda^2.
    const FavourablePatchMap map{lambda, 3e-6, 11};
    long both = 0;
    for (int i = 0; i < kCells; ++i)
      for (int j = 0; j < kCells; ++j) both += map.cellValue(Sheet::bottom, i, j, 0) < lambda && map.cellValue(Sheet::top, i, j, 0) < lambda ? 1 : 0;
    EXPECT_NEAR(both / n, lambda * lambda, 4 * std::sqrt(lambda * lambda * (1 - lambda * lambda) / n)) << "lambda " << lambda;
  }
  const FavourablePatchMap small{0.05, 2e-6, 3}, large{0.3, 2e-6, 3};
  for (int i = 0; i < 20000; ++i) {
    const double x = -1e-3 + 1e-7 * i, y = 3.3e-7 * (i % 977), z = 1.1e-7 * (i % 113);
    if (small.favourableAt(Sheet::bottom, x, y, z)) {
      EXPECT_TRUE(large.favourableAt(Sheet::bottom, x, y, z));
    }
    EXPECT_EQ(small.favourableAt(Sheet::bottom, x, y, z), small.cellValue(Sheet::bottom, std::int64_t(std::floor(x / 2e-6)), std::int64_t(std::floor(y / 2e-6)), 0) < 0.05);
    const auto wc = [](double v) { return std::int64_t(std::floor(v / 2e-6 + FavourablePatchMap::kWallShift)); };
    EXPECT_EQ(large.favourableAt(Sheet::walls, x, y, z), large.cellValue(Sheet::walls, wc(x), wc(y), wc(z)) < 0.3);
  }
}

/// Plug flow along x at 3 mM over the bottom plate: kRows particles, one per row of cells (y at
/// the middle of row k), start at x = L / 2 (the middle of cell 0) just above the plate and are
/// carried along x in the plate's capture distance (no Brownian motion).
constexpr int kRows = 250;
constexpr double kPatch = 10e-6;
SceneConfig translatingScene(std::uint64_t seed, double lambda) {
  SceneConfig c = glassScene(3.0, lambda);
  c.attachment.patch_size = kPatch;
  c.seed = seed;
  return c;
}
std::unique_ptr<OverdampedEngine> translate(const SceneConfig& c, double t_end) {
  const double a = c.particle.radius();
  auto e = std::make_unique<OverdampedEngine>(std::make_shared<UniformFlow>(Vec2(5e-3, 0), 20e-6), c);
  std::vector<Vec3> xs;
  for (int k = 0; k < kRows; ++k) xs.emplace_back(0.5 * kPatch, (k + 0.5) * kPatch, a + 0.05e-6);
  e->insert(xs);
  e->advance(t_end);
  return e;
}

// A particle translating along the plate within the capture distance (in the 1.5 kT secondary
// minimum, which cannot hold it against this shear, or beside it: both kinds are checked to be
// present) attaches at the first
// favourable cell of its row: checked every step, not only at its arrival. Particle by particle
// its cell is the first favourable one along its row (the map's oracle), reached within one step
// of the cell's edge. Over 4 seeds x 250 rows, the number N of cells crossed before the first
// favourable one is geometric, P(N = n) = (1 - lambda)^n lambda (independent cells), so the
// distance from the start (the middle of cell 0) is D = 0 for N = 0 and N L - L / 2 otherwise:
//   E[D] = L (1 - lambda) (1 / lambda - 1 / 2),  Var[D] = sum_n (D_n - E[D])^2 P(N = n),
// (36 um at lambda = 0.2, L = 10 um, sd 45 um). The mean over the 1000 paths is within 4 SE of
// E[D] (plus the one step a detection may lag), and P(N = 0) within 4 SE of lambda. The run
// covers 60 cells: (1 - lambda)^60 = 2e-6 of paths would be cut short.
TEST(Heterogeneity, TranslatingParticleAttachesAtTheFirstFavourableCell) {
  const double lambda = 0.2, L = kPatch;
  double sum = 0, sum2 = 0, max_lag = 0;
  int n = 0, at_arrival = 0, rearrived = 0;
  for (const std::uint64_t seed : {1u, 2u, 3u, 4u}) {
    const SceneConfig c = translatingScene(seed, lambda);
    const FavourablePatchMap map{lambda, L, seed};
    const auto e = translate(c, 0.002);
    int in_well = 0, beside = 0;  // translating after 0.002 s: caught in the secondary minimum, or not
    for (const auto& p : e->particles()) {
      in_well += p.status == ParticleStatus::mobile && p.secondary ? 1 : 0;
      beside += p.status == ParticleStatus::mobile && !p.secondary ? 1 : 0;
    }
    EXPECT_GT(in_well, 20) << "seed " << seed;  // both kinds of path are tested
    EXPECT_GT(beside, 20) << "seed " << seed;
    e->advance(0.3);
    for (const auto& p : e->particles()) {
      ASSERT_EQ(p.status, ParticleStatus::deposited) << "seed " << seed << ", particle " << p.id << " at x " << p.x.x();
      ASSERT_EQ(p.held_by, Surface::bottom);
      ASSERT_FALSE(p.secondary) << "held in the secondary minimum: the test needs a shear that holds nobody there";
      rearrived += p.arrivals > 1 ? 1 : 0;  // 0 draws when cell 0 is favourable, else the arrival's
      int first = 0;  // first favourable cell along the row
      while (!map.favourableAt(FavourablePatchMap::Sheet::bottom, (first + 0.5) * L, p.x.y(), 0) && first < 100) ++first;
      const double edge = first == 0 ? 0.5 * L : first * L;  // where the path enters it
      EXPECT_GE(p.x.x(), edge) << "seed " << seed << ", particle " << p.id;
      EXPECT_LT(p.x.x(), edge + 0.3 * c.particle.radius()) << "seed " << seed << ", particle " << p.id;  // within a step (0.1 a) or so
      max_lag = std::max(max_lag, p.x.x() - edge);
      const double d = first == 0 ? 0.0 : first * L - 0.5 * L;
      at_arrival += first == 0 ? 1 : 0;
      sum += d;
      sum2 += d * d;
      ++n;
    }
  }
  EXPECT_EQ(rearrived, 0);  // at most one arrival each: the particle stayed within the capture distance
  double mean_d = 0, var_d = 0;
  for (int k = 0; k < 400; ++k) {
    const double pk = std::pow(1 - lambda, k) * lambda, dk = k == 0 ? 0.0 : k * L - 0.5 * L;
    mean_d += pk * dk;
    var_d += pk * dk * dk;
  }
  var_d -= mean_d * mean_d;
  EXPECT_NEAR(mean_d, L * (1 - lambda) * (1 / lambda - 0.5), 1e-12);
  const double mean = sum / n, se = std::sqrt(var_d / n);
  std::printf("translating: %d paths, mean distance to attachment %.2f um (exact %.2f um, 4 SE %.2f um), largest lag %.3f um, "
              "sample sd %.1f um (exact %.1f um), at arrival %d (lambda n = %.0f)\n",
              n, mean * 1e6, mean_d * 1e6, 4 * se * 1e6, max_lag * 1e6, std::sqrt(sum2 / n - mean * mean) * 1e6, std::sqrt(var_d) * 1e6,
              at_arrival, lambda * n);
  EXPECT_NEAR(mean, mean_d, 4 * se + max_lag);
  EXPECT_NEAR(at_arrival / double(n), lambda, 4 * std::sqrt(lambda * (1 - lambda) / n));
}

// Patches much larger than the path: particles settling onto the plate in still fluid (no path
// along it), one per 20 um cell of a 20 um map, at 3 mM. The contact cell decides as the
// per-arrival draw did: a favourable cell attaches in the primary minimum (the map's oracle,
// particle by particle), an unfavourable one sends the arrival's draw u to the unfavourable rule
// unscaled (held in the secondary minimum when u < P, the oracle arrivalDraw). The fractions:
// held within 4 SE of lambda + (1 - lambda) P, primary within 4 SE of lambda (400 arrivals).
TEST(Heterogeneity, LargePatchesGiveThePerArrivalEfficiency) {
  for (const double lambda : {0.1, 0.4}) {
    SceneConfig c = glassScene(3.0, lambda);
    c.attachment.patch_size = 20e-6;
    const double a = c.particle.radius(), h = 42e-6 + 2 * a;
    OverdampedEngine e(std::make_shared<UniformFlow>(Vec2(0, 0), h), c);
    std::vector<Vec3> xs;
    for (int k = 0; k < kN; ++k) xs.emplace_back((k % kSide + 0.5) * 20e-6, (k / kSide + 0.5) * 20e-6, a + 20e-6);
    e.insert(xs);
    e.advance(40.0);
    const double p_sec = e.chemistry(Surface::bottom)->secondary_capture;
    const FavourablePatchMap map{lambda, 20e-6, c.seed};
    int primary = 0, secondary = 0, mismatched = 0;
    for (const auto& p : e.particles()) {
      ASSERT_LE(p.arrivals, 1u);  // one arrival (no draw when it landed on a favourable cell)
      const bool fav = map.favourableAt(FavourablePatchMap::Sheet::bottom, p.x.x(), p.x.y(), 0);
      const bool want_secondary = !fav && arrivalDraw(c.seed, p.id, 1) < p_sec;
      const bool held = p.status == ParticleStatus::deposited && p.held_by == Surface::bottom;
      mismatched += (held && !p.secondary) != fav || (held && p.secondary) != want_secondary ? 1 : 0;
      primary += held && !p.secondary ? 1 : 0;
      secondary += held && p.secondary ? 1 : 0;
    }
    EXPECT_EQ(mismatched, 0) << "lambda " << lambda;
    const double eff = patchwiseEfficiency(lambda, p_sec), frac = (primary + secondary) / double(kN);
    const double se = std::sqrt(eff * (1 - eff) / kN), se_l = std::sqrt(lambda * (1 - lambda) / kN);
    std::printf("large patches, lambda %.2f: %d primary + %d secondary of %d (%.3f), lambda + (1 - lambda) P = %.3f, 4 SE %.3f\n", lambda,
                primary, secondary, kN, frac, eff, 4 * se);
    EXPECT_NEAR(frac, eff, 4 * se) << "lambda " << lambda;
    EXPECT_NEAR(primary / double(kN), lambda, 4 * se_l) << "lambda " << lambda;
  }
}

// The same map for every engine of a seed and in a resumed run. Two engines with the seed read the
// same cells on the plates and on a channel's side walls (contact point: the wall point at the
// centre's height); another seed reads another map (cells differ at 2 lambda (1 - lambda) of
// points, 4 SE). A run saved halfway through the translation of the test above and restored into
// a fresh engine ends bit for bit like the run straight through, with attachments after the save.
// On a side wall (plug flow along it, no gravity, plates not sticky) particles at one z cell each
// attach at the first favourable wall cell of their row, shifted by kWallShift.
TEST(Heterogeneity, PatchMapIsTheSeedsInEveryEngineAndAfterARestart) {
  const double lambda = 0.3;
  SceneConfig c = translatingScene(5, lambda);
  const auto flow = std::make_shared<HeleShawChannel>(2e-3, 400e-6, 2e-3, 5e-3);
  OverdampedEngine e1(flow, c), e2(flow, c);
  SceneConfig other = c;
  other.seed = 6;
  OverdampedEngine e3(flow, other);
  int differ = 0, same = 0, n = 0;
  for (int i = 0; i < 20000; ++i) {
    const Vec3 x(1e-6 + 0.37e-6 * i, 3e-6 + 0.19e-6 * (i % 2000), 3e-6 + 0.5e-6 * (i % 3000));
    for (const Surface s : {Surface::bottom, Surface::top, Surface::grain}) {
      same += e1.favourablePatchAt(s, x) == e2.favourablePatchAt(s, x) ? 1 : 0;
      differ += e1.favourablePatchAt(s, x) != e3.favourablePatchAt(s, x) ? 1 : 0;
      ++n;
    }
  }
  EXPECT_EQ(same, n);
  const double q = 2 * lambda * (1 - lambda);
  EXPECT_GT(differ, n * q * 0.5);  // points share cells, so the SE is wider than binomial: a loose bound
  EXPECT_FALSE(e1.favourablePatchAt(Surface::deposit, Vec3(1e-6, 1e-6, 1e-6)));

  // Restart: save at 0.01 s of the 0.3 s translation.
  const double a = c.particle.radius();
  const auto plug = std::make_shared<UniformFlow>(Vec2(5e-3, 0), 20e-6);
  std::vector<Vec3> xs;
  for (int k = 0; k < kRows; ++k) xs.emplace_back(0.5 * kPatch, (k + 0.5) * kPatch, a + 0.05e-6);
  OverdampedEngine straight(plug, c);
  straight.insert(xs);
  straight.advance(0.01);
  CheckpointWriter w;
  straight.saveState(w);
  const auto mid = straight.counts();
  straight.advance(0.3);
  OverdampedEngine resumed(plug, c);
  CheckpointReader r(w.bytes(), "memory");
  resumed.loadState(r);
  resumed.advance(0.3);
  const auto ps = straight.particles(), pr = resumed.particles();
  ASSERT_EQ(ps.size(), pr.size());
  for (std::size_t i = 0; i < ps.size(); ++i) {
    EXPECT_EQ(ps[i].x.x(), pr[i].x.x());
    EXPECT_EQ(ps[i].status, pr[i].status);
    EXPECT_EQ(ps[i].t_event, pr[i].t_event);
  }
  EXPECT_GT(straight.counts().deposited - mid.deposited, 50);  // most attach after the restart

  // Side wall y = 0 of the channel: rows at z = (k + 0.5) L - kWallShift L (the middle of wall cell k).
  SceneConfig wc = c;
  wc.gravity = 0;
  wc.depth_profile = false;  // plane flow: every height moves at the channel's speed
  wc.attachment.bottom = false;
  wc.attachment.grains = true;
  OverdampedEngine wall(flow, wc);
  std::vector<Vec3> ws;
  const double L = kPatch, s = FavourablePatchMap::kWallShift;
  for (int k = 1; k < 150; ++k) ws.emplace_back((0.5 - s) * L + 20 * L, a + 0.05e-6, (k + 0.5 - s) * L);
  wall.insert(ws);
  wall.advance(0.3);
  const FavourablePatchMap map{lambda, L, c.seed};
  int checked = 0;
  for (const auto& p : wall.particles()) {
    ASSERT_EQ(p.status, ParticleStatus::deposited) << "particle " << p.id;
    ASSERT_EQ(p.held_by, Surface::grain);
    int first = 0;
    while (!map.favourableAt(FavourablePatchMap::Sheet::walls, ws[0].x() + first * L, 0.0, p.x.z()) && first < 100) ++first;
    const double edge = first == 0 ? ws[0].x() : ws[0].x() + (first - 0.5) * L;
    EXPECT_GE(p.x.x(), edge) << "particle " << p.id;
    EXPECT_LT(p.x.x(), edge + 0.3 * a) << "particle " << p.id;
    ++checked;
  }
  EXPECT_EQ(checked, 149);
}

Case channelCase(const std::string& deposition_model, const std::string& lambda, const std::string& patch_size = "") {
  const std::string text = "[case]\nname = \"het\"\nkind = \"particles-channel\"\n[channel]\nlength = \"300 um\"\nwidth = \"100 um\"\n"
                           "[particles]\ncount = 3\n[deposition]\nmodel = \"" +
                           deposition_model + "\"\n[chemistry]\nfavourable_fraction = " + lambda + "\n" +
                           (patch_size.empty() ? "" : "patch_size = \"" + patch_size + "\"\n");
  return Case::parse(text, "het.toml", test_support::particleRegistry());
}

std::string inputErrorOf(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// deposition.surface_rule: read under the capture rule (with plate_rule alongside), refused under
// the dlvo rule, whose DLVO profile decides attachment, naming the key; reported by the engine.
TEST(Heterogeneity, SurfaceRuleIsReadAndRefusedUnderDlvo) {
  const auto withRule = [](const std::string& model) {
    const std::string text = "[case]\nname = \"rule\"\nkind = \"particles-channel\"\n[channel]\nlength = \"300 um\"\nwidth = \"100 um\"\n"
                             "[particles]\ncount = 3\n[deposition]\nmodel = \"" + model + "\"\nsurface_rule = \"torque-balance\"\n";
    return Case::parse(text, "rule.toml", test_support::particleRegistry());
  };
  SceneConfig s;
  physicsAndDepositionFromCase(withRule("capture"), EngineChoice{}, s);
  EXPECT_TRUE(s.attachment.surface_torque_balance);
  EXPECT_FALSE(s.attachment.torque_balance);  // the plates keep their own key
  SceneConfig d;
  physicsAndDepositionFromCase(channelCase("capture", "0.0"), EngineChoice{}, d);
  EXPECT_FALSE(d.attachment.surface_torque_balance);  // default: the capture rule
  const std::string msg = inputErrorOf([&] {
    SceneConfig x;
    physicsAndDepositionFromCase(withRule("dlvo"), EngineChoice{}, x);
  });
  EXPECT_NE(msg.find("deposition.surface_rule"), std::string::npos) << msg;
  const auto described = OverdampedEngine(std::make_shared<UniformFlow>(Vec2(0, 0), 20e-6), s).describe();
  EXPECT_NE(described["surface_attachment"].get<std::string>().find("torque balance"), std::string::npos);
}

// The key: read under the dlvo rule, refused outside [0, 1] and with the capture rule, naming it.
TEST(Heterogeneity, CaseKeyIsValidated) {
  SceneConfig s;
  physicsAndDepositionFromCase(channelCase("dlvo", "0.01"), EngineChoice{}, s);
  EXPECT_EQ(s.attachment.favourable_fraction, 0.01);
  SceneConfig d;
  physicsAndDepositionFromCase(channelCase("dlvo", "0.0"), EngineChoice{}, d);
  EXPECT_EQ(d.attachment.favourable_fraction, 0.0);
  for (const char* bad : {"-0.1", "1.5"}) {
    const std::string msg = inputErrorOf([&] {
      SceneConfig x;
      physicsAndDepositionFromCase(channelCase("dlvo", bad), EngineChoice{}, x);
    });
    EXPECT_NE(msg.find("chemistry.favourable_fraction"), std::string::npos) << bad << ": " << msg;
  }
  const std::string msg = inputErrorOf([&] {
    SceneConfig x;
    physicsAndDepositionFromCase(channelCase("capture", "0.2"), EngineChoice{}, x);
  });
  EXPECT_NE(msg.find("chemistry.favourable_fraction"), std::string::npos) << msg;
  // chemistry.patch_size: 0 by default (the per-arrival draw), read as a length, >= 0, dlvo only.
  EXPECT_EQ(d.attachment.patch_size, 0.0);
  SceneConfig ps;
  physicsAndDepositionFromCase(channelCase("dlvo", "0.01", "2 um"), EngineChoice{}, ps);
  EXPECT_DOUBLE_EQ(ps.attachment.patch_size, 2e-6);
  for (const auto& bad : {std::pair<std::string, std::string>{"dlvo", "-1 um"}, {"capture", "2 um"}}) {
    const std::string m = inputErrorOf([&] {
      SceneConfig x;
      physicsAndDepositionFromCase(channelCase(bad.first, "0.0", bad.second), EngineChoice{}, x);
    });
    EXPECT_NE(m.find("chemistry.patch_size"), std::string::npos) << bad.first << " " << bad.second << ": " << m;
  }
  // Reported: placement and size in the engine's charge_heterogeneity block.
  SceneConfig c = glassScene(3.0, 0.2);
  c.attachment.patch_size = 5e-6;
  const auto het = OverdampedEngine(std::make_shared<UniformFlow>(Vec2(0, 0), 20e-6), c).describe()["dlvo"]["charge_heterogeneity"];
  EXPECT_EQ(het["placement"].get<std::string>(), "spatial");
  EXPECT_DOUBLE_EQ(het["patch_size_um"].get<double>(), 5.0);
  c.attachment.patch_size = 0;
  EXPECT_EQ(OverdampedEngine(std::make_shared<UniformFlow>(Vec2(0, 0), 20e-6), c).describe()["dlvo"]["charge_heterogeneity"]["placement"].get<std::string>(),
            "per arrival");
}

}  // namespace
}  // namespace mmval::particles
