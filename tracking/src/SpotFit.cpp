#include "SpotFit.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include <opencv2/imgproc.hpp>

namespace mmval::tracking::detail {

// Sums of img x mask under the separable mask ex(x - cx + r) ey(y - cy + r) over the
// window of half-width r (clipped to the image): weight, and weight x offset from (cx, cy).
// Rows accumulate in float over offsets (vectorisable, exact to ~1e-7 relative).
void maskedSums(const cv::Mat& img, int cx, int cy, int r, const float* ex, const float* ey, double& sw, double& sx, double& sy) {
  sw = sx = sy = 0;
  const int x0 = std::max(0, cx - r), x1 = std::min(img.cols - 1, cx + r);
  const int n = x1 - x0 + 1;
  if (n <= 0) return;
  const float* mx = ex + (x0 - cx + r);
  float off[64];
  for (int k = 0; k < n && k < 64; ++k) off[k] = static_cast<float>(x0 + k - cx);
  for (int y = std::max(0, cy - r); y <= std::min(img.rows - 1, cy + r); ++y) {
    const float* row = img.ptr<float>(y) + x0;
    float rw = 0, rx = 0;
    for (int k = 0; k < n; ++k) {
      const float w = row[k] * mx[k];
      rw += w;
      rx += w * off[k];
    }
    const double gy = ey[y - cy + r];
    sw += rw * gy;
    sx += rx * gy;
    sy += rw * gy * (y - cy);
  }
}

/// Joint refinement of spots that overlap (a Gauss-Seidel least-squares fit of a sum of
/// Gaussian spots of sigma `sm`): each spot's Gaussian-masked centroid and amplitude are
/// taken on the signal minus its neighbours' current models, sweep after sweep. A lone
/// spot's masked centroid already is its least-squares position (Thompson, Larson & Webb
/// 2002); next to a neighbour it is pulled towards it by up to a pixel, which this removes.
/// Then spots hidden beside a brighter one (closer than the seeds' separation) are looked
/// for in the residual, pairs merged into one elongated blob are split when two spots fit
/// significantly better than one, and fits that merged are dropped.
/// The residual (signal minus every spot's model) is kept as an image and updated spot by
/// spot, with separable Gaussian tables, so a sweep costs O(spots x window).
void deblend(const cv::Mat& zero_mean, double sm, double blur, double level, int sep, double noise, std::vector<Detection>& dets) {
  if (dets.empty()) return;
  // The signal is smoothed: a spot of sigma `sm` appears in it with sigma `sg`. The joint
  // fit models spots with sigma `sm` (measured on the SNR 4 scenes, this narrower model
  // localises close pairs better than the true shape); the split test judges with `sg`.
  const double sg = std::sqrt(sm * sm + blur * blur);
  const int r = std::max(2, static_cast<int>(std::ceil(3 * sg)));
  const int n = 2 * r + 1;
  // Spots farther apart than 4.6 sigma bias each other's masked centroid by < 0.02 px.
  const double reach = std::max(3.0, 4.6 * sm);
  const double inv2s2 = 1.0 / (2 * sm * sm), inv2g2 = 1.0 / (2 * sg * sg);
  const double omega = 1.0 / (1.0 - sm * sm / (2 * sm * sm + blur * blur));  // see refineCentre
  const int W = zero_mean.cols, H = zero_mean.rows;
  struct Spot {
    int cx = 0, cy = 0;  // window centre (pixel)
    double a = 0;        // amplitude
    std::array<float, 32> ex{}, ey{};  // sigma sm: the centroid's mask and the joint fit's model
    std::array<float, 32> gx{}, gy{};  // sigma sg: the spot's shape in the smoothed signal
  };
  if (n > 32) return;
  std::vector<Spot> spots(dets.size());
  thread_local cv::Mat R, residual;  // per-thread buffers: no frame-sized allocation per call
  zero_mean.copyTo(R);
  auto tables = [&](const Detection& d, Spot& s) {
    s.cx = static_cast<int>(std::lround(d.x));
    s.cy = static_cast<int>(std::lround(d.y));
    gaussianRow(s.ex.data(), n, s.cx - r, d.x, inv2s2);
    gaussianRow(s.ey.data(), n, s.cy - r, d.y, inv2s2);
    gaussianRow(s.gx.data(), n, s.cx - r, d.x, inv2g2);
    gaussianRow(s.gy.data(), n, s.cy - r, d.y, inv2g2);
  };
  // Adds `sign` x the spot's model to R.
  auto render = [&](const Spot& s, float sign) {
    const float a = static_cast<float>(s.a) * sign;
    for (int y = std::max(0, s.cy - r); y <= std::min(H - 1, s.cy + r); ++y) {
      float* row = R.ptr<float>(y);
      const float ay = a * s.ey[y - s.cy + r];
      for (int x = std::max(0, s.cx - r); x <= std::min(W - 1, s.cx + r); ++x) row[x] += ay * s.ex[x - s.cx + r];
    }
  };
  // Least-squares amplitude on R (own model already added back).
  auto amplitude = [&](const Spot& s) {
    double sd = 0, sgg = 0;
    for (int y = std::max(0, s.cy - r); y <= std::min(H - 1, s.cy + r); ++y) {
      const float* row = R.ptr<float>(y);
      for (int x = std::max(0, s.cx - r); x <= std::min(W - 1, s.cx + r); ++x) {
        const double g = s.ey[y - s.cy + r] * s.ex[x - s.cx + r];
        sd += row[x] * g;
        sgg += g * g;
      }
    }
    return sgg > 0 ? sd / sgg : 0.0;
  };
  // Refits spot i on R + its own model; leaves R with the new model subtracted.
  auto refit = [&](std::size_t i) {
    Detection& d = dets[i];
    Spot& s = spots[i];
    render(s, 1.0f);
    double moved = 0;
    for (int it = 0; it < 6; ++it) {
      double sw = 0, sx = 0, sy = 0;
      maskedSums(R, s.cx, s.cy, r, s.ex.data(), s.ey.data(), sw, sx, sy);
      if (sw <= 0) break;
      const double nx = d.x + omega * (s.cx + sx / sw - d.x), ny = d.y + omega * (s.cy + sy / sw - d.y), step = std::sqrt((nx - d.x) * (nx - d.x) + (ny - d.y) * (ny - d.y));
      if (step > 2.0) break;  // lost to a neighbour: keep the last estimate
      moved = std::max(moved, step);
      d.x = nx;
      d.y = ny;
      tables(d, s);
      if (step < 1e-3) break;
    }
    s.a = amplitude(s);
    render(s, -1.0f);
    return moved;
  };
  auto neighbours = [&]() {
    // Uniform grid of cell `reach`: neighbour lists in O(N).
    std::vector<std::vector<int>> nb(dets.size());
    const int gw = static_cast<int>(W / reach) + 1, gh = static_cast<int>(H / reach) + 1;
    std::vector<std::vector<int>> cells(static_cast<std::size_t>(gw * gh));
    auto cell = [&](double v, int m) { return std::clamp(static_cast<int>(v / reach), 0, m - 1); };
    for (std::size_t i = 0; i < dets.size(); ++i) cells[cell(dets[i].y, gh) * gw + cell(dets[i].x, gw)].push_back(static_cast<int>(i));
    for (std::size_t i = 0; i < dets.size(); ++i) {
      const int gx = cell(dets[i].x, gw), gy = cell(dets[i].y, gh);
      for (int yy = std::max(0, gy - 1); yy <= std::min(gh - 1, gy + 1); ++yy)
        for (int xx = std::max(0, gx - 1); xx <= std::min(gw - 1, gx + 1); ++xx)
          for (int j : cells[yy * gw + xx])
            if (j != static_cast<int>(i) &&
                (dets[j].x - dets[i].x) * (dets[j].x - dets[i].x) + (dets[j].y - dets[i].y) * (dets[j].y - dets[i].y) < reach * reach)
              nb[i].push_back(j);
    }
    return nb;
  };
  auto sweepSome = [&](const std::vector<std::vector<int>>& nb, const std::vector<int>& which) {
    for (int pass = 0; pass < 8; ++pass) {
      double moved = 0;
      for (int i : which)
        if (!nb[i].empty()) moved = std::max(moved, refit(static_cast<std::size_t>(i)));
      if (moved < 5e-3) break;
    }
  };
  auto sweep = [&](const std::vector<std::vector<int>>& nb) {
    std::vector<int> all(dets.size());
    for (std::size_t i = 0; i < dets.size(); ++i) all[i] = static_cast<int>(i);
    sweepSome(nb, all);
  };
  for (std::size_t i = 0; i < dets.size(); ++i) {
    tables(dets[i], spots[i]);
    spots[i].a = amplitude(spots[i]);
  }
  std::vector<std::vector<int>> nb = neighbours();
  // Lone spots keep their masked-centroid positions; their models leave the residual first.
  for (std::size_t i = 0; i < dets.size(); ++i)
    if (nb[i].empty()) render(spots[i], -1.0f);
  for (std::size_t i = 0; i < dets.size(); ++i)
    if (!nb[i].empty()) render(spots[i], -1.0f);
  sweep(nb);
  // Residual, smoothed as the seeds were: a maximum above the seeds' level within `sep`
  // of a spot is a particle the separation hid.
  if (blur > 0) cv::GaussianBlur(R, residual, cv::Size(0, 0), blur);
  else R.copyTo(residual);
  const double gain = sm * sm / (sm * sm + blur * blur);  // smoothed peak / spot amplitude
  const std::size_t before = dets.size();
  for (std::size_t i = 0; i < before; ++i) {
    const int cx = spots[i].cx, cy = spots[i].cy;
    // Above the seeds' level and above what a slightly wrong spot model leaves behind
    // at high SNR (a sigma off by 10 % leaves ~10 % of the amplitude).
    float best = static_cast<float>(std::max(level, 0.3 * spots[i].a * gain));
    int bx = -1, by = -1;
    for (int y = std::max(1, cy - sep); y <= std::min(H - 2, cy + sep); ++y) {
      const float* row = residual.ptr<float>(y);
      for (int x = std::max(1, cx - sep); x <= std::min(W - 2, cx + sep); ++x) {
        const float v = row[x];
        if (v <= best) continue;
        bool peak = true;
        for (int yy = y - 1; yy <= y + 1 && peak; ++yy)
          for (int xx = x - 1; xx <= x + 1; ++xx)
            if (residual.at<float>(yy, xx) > v) peak = false;
        if (peak) {
          best = v;
          bx = x;
          by = y;
        }
      }
    }
    if (bx < 0) continue;
    bool taken = false;
    for (std::size_t j = before; j < dets.size() && !taken; ++j) taken = std::hypot(dets[j].x - bx, dets[j].y - by) < 2;
    if (taken) continue;
    Detection d = dets[i];
    d.x = bx;
    d.y = by;
    dets.push_back(d);
    Spot s;
    tables(d, s);
    s.a = best / gain;
    render(s, -1.0f);
    spots.push_back(s);
  }
  if (dets.size() > before) {
    nb = neighbours();
    sweep(nb);
  }
  // Two particles closer than the blur resolves make one elongated blob: try two spots
  // where one fits worse than the noise allows, and keep them when two spots explain the
  // data significantly better than one.
  // The test compares models of the spot's true shape in the smoothed signal (sigma sg),
  // one spot at the single fit's centre against two at the pair fit's centres, amplitudes
  // by least squares (the centres are not refitted with sg: that could only lower the
  // two spots' residual, so the test errs towards one spot). The joint fit's own model (sigma sm, narrower) is no null model: a
  // lone spot leaves ~5 % of its energy to it as a ring, which two narrow spots ~2 px apart
  // fit better than one, so at high SNR every spot would split.
  // Two spots must gain more than both
  // - what noise alone gives them (rules at low SNR): a likelihood-ratio test with three
  //   more parameters on the smoothed noise, which is correlated over the blur: a smooth
  //   model direction sees kappa = 4 pi b^2 s^2 / (s^2 + b^2) times the pixel variance
  //   (white noise blurred by b, projected on a Gaussian of sigma s; 9.2 for b = 1,
  //   s = 1.66). kSplit = 7 kappa (chi2(3) > 7 has probability 0.07, and kappa
  //   overstates the correlation the position directions see by ~25 %): measured on the
  //   clean SNR 10 sweep scenes, no lone spot's noise gains more than ~60 pixel variances;
  //   10 kappa already loses enough true pairs to break the SNR 4 scene's RMSE target;
  // - kFrac of the spot's energy (rules at high SNR): what a lone spot whose shape differs
  //   a little from the model leaves (its sigma is estimated to ~5 %, Poisson noise is
  //   stronger on the spot), which grows with SNR^2 where noise thresholds do not. Measured
  //   on the SNR 10 scenes: lone spots gain 0.25 % of their energy typically, < 2 % always;
  //   true pairs ~2 px apart 2-10 %.
  if (noise > 0) {
    const double kappa = std::max(1.0, 4 * M_PI * blur * blur * sg * sg / (sg * sg + blur * blur));
    const double kSplit = 7 * kappa;
    constexpr double kFrac = 0.025;
    constexpr double kElongation = 1.05;
    const double npix = static_cast<double>(n) * n;
    auto narrowAt = [&](const Spot& s, int x, int y) {
      return std::abs(x - s.cx) <= r && std::abs(y - s.cy) <= r ? static_cast<double>(s.ex[x - s.cx + r]) * s.ey[y - s.cy + r] : 0.0;
    };
    auto shapeAt = [&](const Spot& s, int x, int y) {
      return std::abs(x - s.cx) <= r && std::abs(y - s.cy) <= r ? static_cast<double>(s.gx[x - s.cx + r]) * s.gy[y - s.cy + r] : 0.0;
    };
    // Residual sum of squares (in pixel variances) over the window around (cx, cy) of the
    // data (R plus the narrow models of `fitted`) against spots of sigma sg at the centres
    // of `fitted`, amplitudes by least squares; `energy` gets their sum of squares.
    auto shapedRss = [&](int cx, int cy, const Spot* a, const Spot* b, double& energy) {
      double vv = 0, va = 0, vb = 0, aa = 0, bb = 0, ab = 0;
      for (int y = cy - r; y <= cy + r; ++y) {
        const float* row = R.ptr<float>(y);
        for (int x = cx - r; x <= cx + r; ++x) {
          double v = row[x] + a->a * narrowAt(*a, x, y);
          const double ga = shapeAt(*a, x, y);
          double gb = 0;
          if (b) {
            v += b->a * narrowAt(*b, x, y);
            gb = shapeAt(*b, x, y);
          }
          vv += v * v;
          va += v * ga;
          vb += v * gb;
          aa += ga * ga;
          bb += gb * gb;
          ab += ga * gb;
        }
      }
      double explained = 0;
      if (!b) {
        explained = aa > 0 ? va * va / aa : 0;
      } else {
        const double det = aa * bb - ab * ab;
        if (det > 1e-12 * aa * bb) explained = (bb * va * va - 2 * ab * va * vb + aa * vb * vb) / det;
      }
      energy = explained / (noise * noise);
      return (vv - explained) / (noise * noise);
    };
    const std::size_t n0 = dets.size();
    bool split_any = false;
    cv::Mat saved;
    for (std::size_t i = 0; i < n0; ++i) {
      const int cx = spots[i].cx, cy = spots[i].cy;
      if (cx < 2 * r || cy < 2 * r || cx >= W - 2 * r || cy >= H - 2 * r) continue;
      double energy = 0;
      const double r1 = shapedRss(cx, cy, &spots[i], nullptr, energy);
      const double threshold = std::max(kSplit, kFrac * energy);
      // Cheap screen: two spots cannot gain more than the excess over a good fit (about
      // half the window's pixel variances at least remain).
      if (r1 < 0.5 * npix + threshold) continue;
      // Principal axis of the spot's data (residual plus its own model) under the mask.
      double sw = 0, sxx = 0, syy = 0, sxy = 0;
      const Spot& s = spots[i];
      for (int y = cy - r; y <= cy + r; ++y)
        for (int x = cx - r; x <= cx + r; ++x) {
          const double g = s.ey[y - cy + r] * s.ex[x - cx + r];
          const double v = R.at<float>(y, x) + s.a * g;
          const double dx = x - dets[i].x, dy = y - dets[i].y;
          const double w = std::max(0.0, v) * std::sqrt(g);
          sw += w;
          sxx += w * dx * dx;
          syy += w * dy * dy;
          sxy += w * dx * dy;
        }
      if (sw <= 0) continue;
      // Only elongated blobs: the principal variances of a round spot are equal, two spots
      // 2.3 px apart make them differ by ~50 %. A 5 % margin keeps the test cheap and,
      // measured on the SNR 4 scenes, loses no split.
      const double tr = sxx + syy, disc = std::sqrt(std::max(0.0, 0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy));
      if (tr / 2 - disc <= 0 || (tr / 2 + disc) / (tr / 2 - disc) < kElongation) continue;
      const double theta = 0.5 * std::atan2(2 * sxy, sxx - syy);
      const cv::Rect box(cx - 2 * r, cy - 2 * r, 4 * r + 1, 4 * r + 1);
      R(box).copyTo(saved);
      const Detection keep = dets[i];
      const Spot keep_spot = spots[i];
      render(spots[i], 1.0f);
      const double half = 1.2;  // start 2.4 px apart along the axis
      Detection other = keep;
      dets[i].x = keep.x + half * std::cos(theta);
      dets[i].y = keep.y + half * std::sin(theta);
      other.x = keep.x - half * std::cos(theta);
      other.y = keep.y - half * std::sin(theta);
      dets.push_back(other);
      spots.emplace_back();
      const std::size_t k = dets.size() - 1;
      tables(dets[i], spots[i]);
      tables(dets[k], spots[k]);
      spots[i].a = spots[k].a = 0.5 * keep_spot.a;
      render(spots[i], -1.0f);
      render(spots[k], -1.0f);
      for (int pass = 0; pass < 8; ++pass)
        if (std::max(refit(i), refit(k)) < 5e-3) break;
      double pair_energy = 0;
      const double r2 = shapedRss(cx, cy, &spots[i], &spots[k], pair_energy);
      const double apart = std::hypot(dets[i].x - dets[k].x, dets[i].y - dets[k].y);
      if (r1 - r2 > threshold && apart > 1.2 && std::min(spots[i].a, spots[k].a) * gain >= level &&
          std::abs(spots[i].cx - cx) <= r && std::abs(spots[k].cx - cx) <= r && std::abs(spots[i].cy - cy) <= r && std::abs(spots[k].cy - cy) <= r) {
        split_any = true;
        continue;
      }
      saved.copyTo(R(box));
      dets[i] = keep;
      spots[i] = keep_spot;
      dets.pop_back();
      spots.pop_back();
    }
    if (split_any) {
      nb = neighbours();
      sweep(nb);
    }
  }
  if (dets.size() == before) return;
  // Two fits on one particle end up together (or a new one with a faint amplitude):
  // keep the brighter.
  std::vector<char> drop(dets.size(), 0);
  for (std::size_t i = 0; i < dets.size(); ++i) {
    if (nb[i].empty()) continue;
    if (i >= before && spots[i].a * gain < level) drop[i] = 1;
    for (int j : nb[i])
      if (!drop[j] && !drop[i] && std::hypot(dets[j].x - dets[i].x, dets[j].y - dets[i].y) < 1.0) drop[spots[i].a < spots[j].a ? i : j] = 1;
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < dets.size(); ++i)
    if (!drop[i]) dets[kept++] = dets[i];
  dets.resize(kept);
}

}  // namespace mmval::tracking::detail
