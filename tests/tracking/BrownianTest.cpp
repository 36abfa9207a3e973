// Brownian analysis (Brownian.hpp) on trajectories generated here with known D,
// drift, localisation noise and motion blur: the MSD fit, the covariance-based
// estimator against Vestergaard et al. (2014)'s variance, the immobile test's
// level and power, the van Hove distributions and the flow-or-Brownian decision
// (the tracker end to end: BrownianPipelineTest.cpp). Tolerances: 4 standard errors
// of the estimator under test (a correct estimator fails about once in 16,000).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>

#include "mmval/tracking/Brownian.hpp"

namespace mmval::tracking {
namespace {

constexpr double kUm = 1e-6, kUm2 = 1e-12;

struct Walk {
  int tracks = 400;
  int points = 100;
  int start_spread = 50;     ///< first frames drawn from 0..start_spread
  double dt = 0.1;           ///< s
  double d = 0.5 * kUm2;     ///< m^2/s
  double sigma = 0.15 * kUm; ///< m, localisation error per axis
  double vx = 0, vy = 0;     ///< m/s, uniform drift
  double exposure = 0;       ///< s: positions averaged over the last `exposure` of each frame interval
  int substeps = 20;         ///< of each frame interval (motion blur)
  std::uint64_t seed = 1;
};

/// Random walks with drift, motion blur (the exposure-time average of the true path,
/// by sub-steps) and Gaussian localisation noise, in the tracks schema.
Tracks walks(const Walk& w) {
  std::mt19937_64 rng(w.seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_int_distribution<int> start(0, w.start_spread);
  std::uniform_real_distribution<double> place(0.0, 500 * kUm);
  const double h = w.dt / w.substeps, step = std::sqrt(2 * w.d * h);
  const int exposed = static_cast<int>(std::lround(w.exposure / h));
  Tracks t;
  for (int p = 0; p < w.tracks; ++p) {
    const int f0 = start(rng);
    double x = place(rng), y = place(rng);
    for (int k = 0; k < w.points; ++k) {
      // The frame interval before each frame (also the first: its exposure is blurred
      // too); the recorded position is the mean over the exposed sub-steps.
      double sx = 0, sy = 0;
      for (int s = 0; s < w.substeps; ++s) {
        x += w.vx * h + step * unit(rng);
        y += w.vy * h + step * unit(rng);
        if (s >= w.substeps - exposed) {
          sx += x;
          sy += y;
        }
      }
      if (exposed > 0) {
        sx /= exposed;
        sy /= exposed;
      } else {
        sx = x;
        sy = y;
      }
      TrackPoint q;
      q.particle = p;
      q.frame = f0 + k;
      q.t = q.frame * w.dt;
      q.x = sx + w.sigma * unit(rng);
      q.y = sy + w.sigma * unit(rng);
      t.points.push_back(q);
    }
  }
  return t;
}

/// Fractional Brownian motion of Hurst exponent `hurst` (MSD proportional to t^(2 H)):
/// increments with the fractional Gaussian noise covariance, by Cholesky factorisation.
Tracks fractional(int tracks, int points, double hurst, double dt, std::uint64_t seed) {
  const int n = points - 1;
  std::vector<double> l(static_cast<std::size_t>(n * n), 0.0);
  auto cov = [&](int k) {
    const double a = std::abs(k);
    return 0.5 * (std::pow(a + 1, 2 * hurst) - 2 * std::pow(a, 2 * hurst) + std::pow(std::abs(a - 1), 2 * hurst));
  };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j <= i; ++j) {
      double s = cov(i - j);
      for (int k = 0; k < j; ++k) s -= l[i * n + k] * l[j * n + k];
      l[i * n + j] = i == j ? std::sqrt(s) : s / l[j * n + j];
    }
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> unit(0.0, 1.0);
  const double scale = 0.3 * kUm;  // rms step per axis
  Tracks t;
  std::vector<double> zx(n), zy(n);
  for (int p = 0; p < tracks; ++p) {
    for (int i = 0; i < n; ++i) {
      zx[i] = unit(rng);
      zy[i] = unit(rng);
    }
    double x = 0, y = 0;
    for (int k = 0; k < points; ++k) {
      if (k > 0) {
        double ix = 0, iy = 0;
        for (int j = 0; j < k; ++j) {
          ix += l[(k - 1) * n + j] * zx[j];
          iy += l[(k - 1) * n + j] * zy[j];
        }
        x += scale * ix;
        y += scale * iy;
      }
      TrackPoint q;
      q.particle = p;
      q.frame = k;
      q.t = k * dt;
      q.x = x;
      q.y = y;
      t.points.push_back(q);
    }
  }
  return t;
}

TEST(BrownianFit, RecoversDiffusionDriftAndLocalisationError) {
  Walk w;
  w.vx = 2 * kUm;
  w.vy = -1 * kUm;
  const Tracks t = walks(w);
  const BrownianStats b = analyseBrownian(t, {});
  const MsdFit& f = b.msd;
  std::printf("D %.4f +- %.4f um^2/s (true %.4f), sigma^2 %.5f +- %.5f um^2 (true %.5f), alpha %.4f +- %.4f, lags %d / %d\n", f.d / kUm2,
              f.d_se / kUm2, w.d / kUm2, f.sigma2 / kUm2, f.sigma2_se / kUm2, w.sigma * w.sigma / kUm2, f.alpha, f.alpha_se, f.lags_d,
              f.lags_alpha);
  ASSERT_TRUE(std::isfinite(f.d_se));
  EXPECT_LT(f.d_se, 0.02 * w.d);  // the test can see a 2 % error
  EXPECT_NEAR(f.d, w.d, 4 * f.d_se);
  EXPECT_NEAR(f.sigma2, w.sigma * w.sigma, 4 * f.sigma2_se);
  EXPECT_LT(f.sigma2_se, 0.1 * w.sigma * w.sigma);
  EXPECT_GE(f.alpha, 0.97);
  EXPECT_LE(f.alpha, 1.03);
  EXPECT_NEAR(f.alpha, 1.0, 4 * f.alpha_se);
  EXPECT_LE(b.immobile, 0.01 * w.tracks + 4 * std::sqrt(0.01 * w.tracks));  // all free: the test's level, 1 %
  EXPECT_EQ(b.mobile + b.immobile + b.short_tracks, w.tracks);
  // Drift: the cumulative drift against v t. Its error is a random walk of the frame
  // means: per frame, (2 D dt + 4 sigma^2 per axis, the noise of both ends) / pairs.
  ASSERT_FALSE(b.drift.frame.empty());
  double var = 0;
  for (std::size_t k = 1; k < b.drift.frame.size(); ++k)
    if (b.drift.pairs[k] > 0) var += (2 * w.d * w.dt + 4 * w.sigma * w.sigma) / b.drift.pairs[k];
  const double span = b.drift.t.back() - b.drift.t.front();
  std::printf("drift %.3f, %.3f um (true %.3f, %.3f; sd %.3f um)\n", b.drift.x.back() / kUm, b.drift.y.back() / kUm, w.vx * span / kUm,
              w.vy * span / kUm, std::sqrt(var) / kUm);
  EXPECT_NEAR(b.drift.x.back(), w.vx * span, 4 * std::sqrt(var));
  EXPECT_NEAR(b.drift.y.back(), w.vy * span, 4 * std::sqrt(var));
}

TEST(BrownianFit, MotionBlurMovesOnlyTheOffset) {
  // Exposure over the whole frame interval: MSD = 4 D t + 4 sigma^2 - (4/3) D t_E.
  Walk w;
  w.exposure = w.dt;
  w.sigma = 0.1 * kUm;
  w.seed = 2;
  const Tracks t = walks(w);
  BrownianOptions with, without;
  with.exposure = w.exposure;
  const MsdFit a = analyseBrownian(t, with).msd, b = analyseBrownian(t, without).msd;
  const double blur = w.d * w.exposure / 3.0;  // sigma^2 per axis read as missing without t_E
  std::printf("blur: D %.4f +- %.4f (true %.4f); sigma^2 %.5f +- %.5f with t_E (true %.5f), %.5f without (expected %.5f)\n", a.d / kUm2,
              a.d_se / kUm2, w.d / kUm2, a.sigma2 / kUm2, a.sigma2_se / kUm2, w.sigma * w.sigma / kUm2, b.sigma2 / kUm2,
              (w.sigma * w.sigma - blur) / kUm2);
  EXPECT_NEAR(a.d, w.d, 4 * a.d_se);
  EXPECT_NEAR(a.sigma2, w.sigma * w.sigma, 4 * a.sigma2_se);
  EXPECT_NEAR(b.d, a.d, 1e-9 * a.d);  // D does not depend on the exposure
  EXPECT_NEAR(b.sigma2, w.sigma * w.sigma - blur, 4 * b.sigma2_se);
}

TEST(BrownianFit, FractionalMotionHasItsExponent) {
  // Fractional Brownian motion, H = 0.75: MSD proportional to t^1.5 at every lag.
  const Tracks t = fractional(300, 100, 0.75, 0.1, 3);
  const MsdFit f = analyseBrownian(t, {}).msd;
  std::printf("fBm H 0.75: alpha %.4f +- %.4f over %d lags\n", f.alpha, f.alpha_se, f.lags_alpha);
  ASSERT_TRUE(std::isfinite(f.alpha_se));
  EXPECT_LT(f.alpha_se, 0.03);
  EXPECT_NEAR(f.alpha, 1.5, 4 * f.alpha_se);
}

TEST(Cve, MeanAndVarianceFollowVestergaard) {
  for (int steps : {10, 50}) {
    Walk w;
    w.tracks = 4000;
    w.points = steps + 1;
    w.sigma = 0.15 * kUm;
    w.exposure = w.dt;  // R = 1/6
    w.substeps = 24;
    w.seed = 10 + static_cast<std::uint64_t>(steps);
    const Tracks t = walks(w);
    std::vector<double> d, s2;
    for (std::size_t i = 0; i < t.points.size(); i += static_cast<std::size_t>(w.points)) {
      const CveEstimate e = cveEstimate(t.points, i, i + static_cast<std::size_t>(w.points), w.dt, w.exposure);
      ASSERT_EQ(e.steps, steps);
      d.push_back(e.d);
      s2.push_back(e.sigma2);
    }
    const double n = static_cast<double>(d.size());
    double m = 0, ms = 0;
    for (std::size_t k = 0; k < d.size(); ++k) {
      m += d[k] / n;
      ms += s2[k] / n;
    }
    double v = 0, m4 = 0, vs = 0;
    for (std::size_t k = 0; k < d.size(); ++k) {
      v += (d[k] - m) * (d[k] - m) / (n - 1);
      m4 += std::pow(d[k] - m, 4) / n;
      vs += (s2[k] - ms) * (s2[k] - ms) / (n - 1);
    }
    const double predicted = cveVariance(w.d, w.sigma * w.sigma, w.dt, 1.0 / 6.0, steps) / 2.0;  // two axes
    const double var_se = std::sqrt((m4 - v * v) / n);
    std::printf("CVE %d steps: mean D %.4f (true %.4f), variance %.4g (Vestergaard %.4g, +- %.2g), mean sigma^2 %.5f (true %.5f)\n", steps,
                m / kUm2, w.d / kUm2, v / (kUm2 * kUm2), predicted / (kUm2 * kUm2), var_se / (kUm2 * kUm2), ms / kUm2,
                w.sigma * w.sigma / kUm2);
    EXPECT_NEAR(m, w.d, 4 * std::sqrt(v / n));
    EXPECT_NEAR(v, predicted, 4 * var_se);
    EXPECT_NEAR(ms, w.sigma * w.sigma, 4 * std::sqrt(vs / n));
  }
}

TEST(Immobile, EachHalfAtItsLevelAndStuckParticlesFound) {
  // 1,500 free particles and 1,000 stuck ones (D = 0, the same localisation noise), 50 points.
  Walk free, stuck;
  free.tracks = 1500;
  free.points = 50;
  free.sigma = 0.1 * kUm;
  free.seed = 5;
  stuck = free;
  stuck.tracks = 1000;
  stuck.d = 0;
  stuck.seed = 6;
  Tracks t = walks(free);
  for (auto p : walks(stuck).points) {
    p.particle += 100000;
    t.points.push_back(p);
  }
  for (double level : {0.05, 0.01}) {
    BrownianOptions o;
    o.immobile_level = level;
    const BrownianStats b = analyseBrownian(t, o);
    const double z = level == 0.05 ? 1.6449 : 2.3263;  // one-sided normal quantiles
    int called_free = 0, called_stuck = 0, below_free = 0, above_zero = 0;
    for (const auto& tr : b.tracks) {
      const bool is_stuck = tr.particle >= 100000;
      (is_stuck ? called_stuck : called_free) += tr.state == "immobile" ? 1 : 0;
      if (!is_stuck && tr.test.z_free < -z) ++below_free;
      if (is_stuck && tr.test.z_zero > z) ++above_zero;
    }
    // Each half of the test at its level: the free particles' D below the ensemble's, and
    // the stuck particles' D above zero, within 4 binomial standard errors plus what the
    // normal approximation misses. Measured (seed 5/6): 0.037 and 0.068 at level 0.05,
    // 0.009 and 0.020 at 0.01: at D = 0 the CVE is a quadratic form of the noise alone,
    // with a heavier right tail than the normal.
    const double rate_free = static_cast<double>(below_free) / free.tracks, rate_zero = static_cast<double>(above_zero) / stuck.tracks;
    const double se_free = std::sqrt(level * (1 - level) / free.tracks), se_zero = std::sqrt(level * (1 - level) / stuck.tracks);
    const double fp = static_cast<double>(called_free) / free.tracks, power = static_cast<double>(called_stuck) / stuck.tracks;
    std::printf("level %.2f: D-below-ensemble half %.4f on free, D-above-zero half %.4f on stuck; immobile: %.4f of free, %.4f of stuck; D %.4f +- %.4f um^2/s\n",
                level, rate_free, rate_zero, fp, power, b.msd.d / kUm2, b.msd.d_se / kUm2);
    EXPECT_NEAR(rate_free, level, 4 * se_free + 0.3 * level);
    EXPECT_GE(rate_zero, 0.5 * level - 4 * se_zero);
    EXPECT_LE(rate_zero, 2.5 * level + 4 * se_zero);
    // Both halves must reject: free particles are called immobile at most at the level,
    // stuck ones found unless their D came out significantly above zero.
    EXPECT_LE(fp, level + 4 * se_free);
    EXPECT_GE(power, 1 - 2.5 * level - 4 * se_zero);
    // Stuck tracks the test kept stay in the fit, at D = 0: D is the free particles' times
    // their share of the displacements (all tracks are equally long).
    const double kept_free = free.tracks - called_free, kept_stuck = stuck.tracks - called_stuck;
    const double expected = free.d * kept_free / (kept_free + kept_stuck);
    EXPECT_NEAR(b.msd.d, expected, 4 * b.msd.d_se);
  }
}

TEST(VanHove, FollowsTheGaussianOfTheFittedD) {
  Walk w;
  w.seed = 7;
  const BrownianStats b = analyseBrownian(walks(w), {});
  ASSERT_EQ(b.van_hove.size(), 3u);
  for (const auto& v : b.van_hove) {
    double l1 = 0;
    for (std::size_t k = 0; k < v.centre.size(); ++k) l1 += std::abs(v.density[k] - v.gaussian[k]) * v.bin_width;
    // Sampling: each bin's count is Poisson; the expected L1 of n samples over these
    // bins is about sum sqrt(2 p_k / (pi n)), ~0.02 at 10^4 samples.
    double expected = 0;
    for (std::size_t k = 0; k < v.centre.size(); ++k) expected += std::sqrt(2 * v.gaussian[k] * v.bin_width / (M_PI * static_cast<double>(v.samples)));
    std::printf("van Hove lag %.2f s: %lld samples, variance %.4f um^2 (model %.4f), L1 %.4f (sampling %.4f)\n", v.lag, v.samples,
                v.variance / kUm2, v.model_variance / kUm2, l1, expected);
    EXPECT_NEAR(v.variance / v.model_variance, 1.0, 0.03);
    EXPECT_LT(l1, 2 * expected + 0.005);
  }
}

TEST(Motion, AutoTellsDiffusionFromFlow) {
  Walk brown;
  brown.vx = 1 * kUm;
  brown.seed = 8;
  const MotionDecision a = decideMotion(walks(brown));
  std::printf("diffusion + drift: %s\n", a.reason.c_str());
  EXPECT_EQ(a.model, MotionModel::brownian);
  // Full-frame exposure: the steps correlate at +0.25 without localisation noise, the bound.
  Walk blurred = brown;
  blurred.sigma = 0;
  blurred.exposure = blurred.dt;
  blurred.seed = 9;
  const MotionDecision b = decideMotion(walks(blurred));
  std::printf("blurred diffusion: %s\n", b.reason.c_str());
  EXPECT_EQ(b.model, MotionModel::brownian);
  EXPECT_NEAR(b.step_correlation, 0.25, 4 * b.step_correlation_se + 0.01);
  // A pore-like flow: speed varying across streamlines, weak diffusion.
  Tracks flow;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> unit(0.0, 1.0);
  std::uniform_real_distribution<double> place(0.0, 200 * kUm);
  const double u = 20 * kUm, len = 50 * kUm, dt = 0.1;
  for (int p = 0; p < 200; ++p) {
    double x = place(rng), y = place(rng);
    for (int k = 0; k < 40; ++k) {
      TrackPoint q;
      q.particle = p;
      q.frame = k;
      q.t = k * dt;
      q.x = x + 0.05 * kUm * unit(rng);
      q.y = y + 0.05 * kUm * unit(rng);
      flow.points.push_back(q);
      const double vx = u * (1 + 0.8 * std::sin(2 * M_PI * y / len)), vy = 0.3 * u * std::cos(2 * M_PI * x / len);
      x += vx * dt + std::sqrt(2 * 0.01 * kUm2 * dt) * unit(rng);
      y += vy * dt + std::sqrt(2 * 0.01 * kUm2 * dt) * unit(rng);
    }
  }
  const MotionDecision c = decideMotion(flow);
  std::printf("pore-like flow: %s\n", c.reason.c_str());
  EXPECT_EQ(c.model, MotionModel::flow);
  // Everything carried at one velocity (plug flow): directed only as a whole.
  Walk plug;
  plug.d = 0;
  plug.sigma = 0.05 * kUm;
  plug.vx = 30 * kUm;
  plug.seed = 12;
  const MotionDecision d = decideMotion(walks(plug));
  std::printf("plug flow: %s\n", d.reason.c_str());
  EXPECT_EQ(d.model, MotionModel::flow);
  EXPECT_GT(d.drift_peclet, 1.0);
  // Nothing moves: particles at rest under localisation noise stay with flow (the default).
  Walk rest = plug;
  rest.vx = 0;
  rest.seed = 13;
  const MotionDecision e = decideMotion(walks(rest));
  std::printf("at rest: %s\n", e.reason.c_str());
  EXPECT_EQ(e.model, MotionModel::flow);
  EXPECT_NEAR(e.step_correlation, -0.5, 4 * e.step_correlation_se);
  // Diffusion under noise ten times the step is still Brownian: -0.5 + 1/22 correlation.
  Walk noisy = brown;
  noisy.sigma = std::sqrt(10 * noisy.d * noisy.dt);
  noisy.seed = 14;
  const MotionDecision f = decideMotion(walks(noisy));
  std::printf("noisy diffusion: %s\n", f.reason.c_str());
  EXPECT_EQ(f.model, MotionModel::brownian);
}

}  // namespace
}  // namespace mmval::tracking
