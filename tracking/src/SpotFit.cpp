#include "SpotFit.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#include "DetectionGrid.hpp"

namespace mmval::tracking::detail {

namespace {

/// maskedSums over a window whose 4 NV columns from x0 lie in the image: per-column sums
/// over the rows in NV vectors of 4 lanes (OpenCV's universal intrinsics), then over the
/// columns.
template <int NV>
void maskedSumsLanes(const cv::Mat& img, int x0, int cy, int r, const float* ex, const float* ey, double& sw, double& sx, double& sy) {
  float m[4 * NV] = {};
  for (int k = 0; k <= 2 * r; ++k) m[k] = ex[k];
  cv::v_float32x4 mv[NV], lw[NV], ly[NV];
  for (int v = 0; v < NV; ++v) {
    mv[v] = cv::v_load(m + 4 * v);
    lw[v] = ly[v] = cv::v_setzero_f32();
  }
  const int y0 = std::max(0, cy - r), y1 = std::min(img.rows - 1, cy + r);
  for (int y = y0; y <= y1; ++y) {
    const float* row = img.ptr<float>(y) + x0;
    const float g = ey[y - cy + r];
    const cv::v_float32x4 gy = cv::v_setall_f32(g), gyo = cv::v_setall_f32(g * static_cast<float>(y - cy));
    for (int v = 0; v < NV; ++v) {
      const cv::v_float32x4 w = cv::v_load(row + 4 * v) * mv[v];
      lw[v] = cv::v_muladd(w, gy, lw[v]);
      ly[v] = cv::v_muladd(w, gyo, ly[v]);
    }
  }
  float cw[4 * NV], cyy[4 * NV];
  for (int v = 0; v < NV; ++v) {
    cv::v_store(cw + 4 * v, lw[v]);
    cv::v_store(cyy + 4 * v, ly[v]);
  }
  double tw = 0, tx = 0, ty = 0;
  for (int k = 0; k <= 2 * r; ++k) {
    tw += cw[k];
    tx += static_cast<double>(cw[k]) * (k - r);
    ty += cyy[k];
  }
  sw = tw;
  sx = tx;
  sy = ty;
}

}  // namespace

// Sums of img x mask under the separable mask ex(x - cx + r) ey(y - cy + r) over the
// window of half-width r (clipped to the image): weight, and weight x offset from (cx, cy).
// Float within the window, exact to ~1e-7 relative. Windows up to 16 px wide whose
// columns, rounded up to a multiple of 4, lie in the image take the vectorised path.
void maskedSums(const cv::Mat& img, int cx, int cy, int r, const float* ex, const float* ey, double& sw, double& sx, double& sy) {
  sw = sx = sy = 0;
  const int nv = (2 * r + 1 + 3) / 4;
  if (cx - r >= 0 && nv <= 4 && cx - r + 4 * nv <= img.cols) {
    switch (nv) {
      case 1: return maskedSumsLanes<1>(img, cx - r, cy, r, ex, ey, sw, sx, sy);
      case 2: return maskedSumsLanes<2>(img, cx - r, cy, r, ex, ey, sw, sx, sy);
      case 3: return maskedSumsLanes<3>(img, cx - r, cy, r, ex, ey, sw, sx, sy);
      default: return maskedSumsLanes<4>(img, cx - r, cy, r, ex, ey, sw, sx, sy);
    }
  }
  const int y0 = std::max(0, cy - r), y1 = std::min(img.rows - 1, cy + r);
  const int x0 = std::max(0, cx - r), x1 = std::min(img.cols - 1, cx + r);
  const int n = x1 - x0 + 1;
  if (n <= 0) return;
  const float* mx = ex + (x0 - cx + r);
  float off[64];
  for (int k = 0; k < n && k < 64; ++k) off[k] = static_cast<float>(x0 + k - cx);
  for (int y = y0; y <= y1; ++y) {
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
  const double c2s2 = std::exp(-2 * inv2s2), c2g2 = std::exp(-2 * inv2g2);
  const double omega = 1.0 / (1.0 - sm * sm / (2 * sm * sm + blur * blur));  // see refineCentre
  const int W = zero_mean.cols, H = zero_mean.rows;
  struct Spot {
    int cx = 0, cy = 0;  // window centre (pixel)
    double a = 0;        // amplitude
    std::array<float, 32> ex{}, ey{};  // sigma sm: the centroid's mask and the joint fit's model
  };
  if (n > 32) return;
  std::vector<Spot> spots(dets.size());
  thread_local cv::Mat R, residual;  // per-thread buffers: no frame-sized allocation per call
  zero_mean.copyTo(R);
  // Only the joint fit's tables (sigma sm) follow the spot as it moves; the split test's
  // (sigma sg) are built where it needs them (shapeRows).
  auto tables = [&](const Detection& d, Spot& s) {
    s.cx = static_cast<int>(std::lround(d.x));
    s.cy = static_cast<int>(std::lround(d.y));
    gaussianRow(s.ex.data(), n, s.cx - r, d.x, inv2s2, c2s2);
    gaussianRow(s.ey.data(), n, s.cy - r, d.y, inv2s2, c2s2);
  };
  // Adds `sign` x the spot's model to R.
  auto render = [&](const Spot& s, float sign) {
    const float a = static_cast<float>(s.a) * sign;
    if (s.cx - r >= 0 && s.cx - r + kLanes <= W && n <= kLanes) {
      // 16 columns at a time (4 vectors); the model is 0 beyond the window's n.
      float mx[kLanes] = {};
      std::copy(s.ex.begin(), s.ex.begin() + n, mx);
      const cv::v_float32x4 m0 = cv::v_load(mx), m1 = cv::v_load(mx + 4), m2 = cv::v_load(mx + 8), m3 = cv::v_load(mx + 12);
      for (int y = std::max(0, s.cy - r); y <= std::min(H - 1, s.cy + r); ++y) {
        float* row = R.ptr<float>(y) + (s.cx - r);
        const cv::v_float32x4 ay = cv::v_setall_f32(a * s.ey[y - s.cy + r]);
        cv::v_store(row, cv::v_muladd(ay, m0, cv::v_load(row)));
        cv::v_store(row + 4, cv::v_muladd(ay, m1, cv::v_load(row + 4)));
        cv::v_store(row + 8, cv::v_muladd(ay, m2, cv::v_load(row + 8)));
        cv::v_store(row + 12, cv::v_muladd(ay, m3, cv::v_load(row + 12)));
      }
      return;
    }
    const int x0 = std::max(0, s.cx - r), x1 = std::min(W - 1, s.cx + r);
    const float* mx = s.ex.data() + (x0 - s.cx + r);
    for (int y = std::max(0, s.cy - r); y <= std::min(H - 1, s.cy + r); ++y) {
      float* row = R.ptr<float>(y) + x0;
      const float ay = a * s.ey[y - s.cy + r];
      for (int k = 0; k <= x1 - x0; ++k) row[k] += ay * mx[k];
    }
  };
  // Least-squares amplitude on R (own model already added back); the model is separable,
  // so its sum of squares is the product of its rows'.
  auto amplitude = [&](const Spot& s) {
    if (s.cx - r >= 0 && s.cx - r + kLanes <= W && n <= kLanes) {
      // Per-column sums over the rows (vectorised lanes), then over the columns.
      float mx[kLanes] = {}, lane[kLanes] = {};
      double sxx = 0, syy = 0, sd = 0;
      for (int k = 0; k < n; ++k) {
        mx[k] = s.ex[k];
        sxx += static_cast<double>(mx[k]) * mx[k];
      }
      for (int y = std::max(0, s.cy - r); y <= std::min(H - 1, s.cy + r); ++y) {
        const float* row = R.ptr<float>(y) + (s.cx - r);
        const float gy = s.ey[y - s.cy + r];
        for (int k = 0; k < kLanes; ++k) lane[k] += row[k] * mx[k] * gy;
        syy += static_cast<double>(gy) * gy;
      }
      for (int k = 0; k < n; ++k) sd += lane[k];
      const double sgg = sxx * syy;
      return sgg > 0 ? sd / sgg : 0.0;
    }
    const int x0 = std::max(0, s.cx - r), x1 = std::min(W - 1, s.cx + r);
    const float* mx = s.ex.data() + (x0 - s.cx + r);
    double sd = 0, sxx = 0, syy = 0;
    for (int k = 0; k <= x1 - x0; ++k) sxx += static_cast<double>(mx[k]) * mx[k];
    for (int y = std::max(0, s.cy - r); y <= std::min(H - 1, s.cy + r); ++y) {
      const float* row = R.ptr<float>(y) + x0;
      float rs = 0;
      for (int k = 0; k <= x1 - x0; ++k) rs += row[k] * mx[k];
      const double gy = s.ey[y - s.cy + r];
      sd += rs * gy;
      syy += gy * gy;
    }
    const double sgg = sxx * syy;
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
  // Neighbour lists (spots closer than `reach`) in compressed rows: spot i's are
  // list[first[i]] .. list[first[i + 1] - 1], found through a grid of cell `reach`; O(N).
  struct Neighbours {
    std::vector<int> first, list;
    bool none(std::size_t i) const { return first[i] == first[i + 1]; }
  };
  auto neighbours = [&]() {
    const DetectionGrid grid(dets, reach);
    Neighbours nb;
    nb.first.assign(dets.size() + 1, 0);
    for (std::size_t i = 0; i < dets.size(); ++i) {
      grid.near(dets[i].x, dets[i].y, reach, [&](int j, double dist) {
        if (j != static_cast<int>(i) && dist < reach) nb.list.push_back(j);
      });
      nb.first[i + 1] = static_cast<int>(nb.list.size());
    }
    return nb;
  };
  // Gauss-Seidel sweeps over the spots that have neighbours, in index order, until none
  // moves by 5e-3 px (at most 8 sweeps). (Refitting only the spots whose neighbourhood
  // still moves was measured: close pairs converge slowly, so it changes their positions
  // by up to ~0.05 px and, through the linker, the SNR 4 scenes' scores.)
  auto sweep = [&](const Neighbours& nb) {
    for (int pass = 0; pass < 8; ++pass) {
      double moved = 0;
      for (std::size_t i = 0; i < dets.size(); ++i)
        if (!nb.none(i)) moved = std::max(moved, refit(i));
      if (moved < 5e-3) break;
    }
  };
  for (std::size_t i = 0; i < dets.size(); ++i) {
    tables(dets[i], spots[i]);
    spots[i].a = amplitude(spots[i]);
  }
  Neighbours nb = neighbours();
  // Lone spots keep their masked-centroid positions; their models leave the residual first.
  for (std::size_t i = 0; i < dets.size(); ++i)
    if (nb.none(i)) render(spots[i], -1.0f);
  for (std::size_t i = 0; i < dets.size(); ++i)
    if (!nb.none(i)) render(spots[i], -1.0f);
  sweep(nb);
  // Residual, smoothed as the seeds were: a maximum above the seeds' level within `sep`
  // of a spot is a particle the separation hid.
  // Only the windows searched are smoothed, and only where the residual could pass the
  // test at all: a Gaussian average never exceeds the largest value it averages, and
  // after the fit the residual is mostly noise below the seeds' level.
  // The kernel is GaussianBlur's for float images (4 sigma each side), borders reflected
  // as its default does (BORDER_REFLECT_101).
  const int kr = blur > 0 ? (cvRound(blur * 8 + 1) | 1) / 2 : 0;
  cv::Mat kernel_mat = cv::getGaussianKernel(2 * kr + 1, blur > 0 ? blur : 1, CV_32F);
  const float* kernel = kernel_mat.ptr<float>();
  residual.create(R.size(), CV_32F);
  thread_local std::vector<float> rows;
  auto reflect = [](int p, int size) {
    if (size == 1) return 0;
    while (p < 0 || p >= size) p = p < 0 ? -p : 2 * size - 2 - p;
    return p;
  };
  // Smoothed residual over [xa, xb] x [ya, yb] (in the frame) into `residual`.
  auto smoothWindow = [&](int xa, int xb, int ya, int yb) {
    const int w = xb - xa + 1;
    rows.assign(static_cast<std::size_t>(w) * (yb - ya + 1 + 2 * kr), 0.0f);
    for (int yy = ya - kr; yy <= yb + kr; ++yy) {
      const float* src = R.ptr<float>(reflect(yy, H));
      float* dst = rows.data() + static_cast<std::size_t>(yy - ya + kr) * w;
      for (int x = xa; x <= xb; ++x) {
        float t = 0;
        if (x - kr >= 0 && x + kr < W)
          for (int j = 0; j <= 2 * kr; ++j) t += kernel[j] * src[x + j - kr];
        else
          for (int j = 0; j <= 2 * kr; ++j) t += kernel[j] * src[reflect(x + j - kr, W)];
        dst[x - xa] = t;
      }
    }
    for (int y = ya; y <= yb; ++y) {
      float* out = residual.ptr<float>(y) + xa;
      for (int x = 0; x < w; ++x) {
        float t = 0;
        for (int j = 0; j <= 2 * kr; ++j) t += kernel[j] * rows[static_cast<std::size_t>(y - ya + j) * w + x];
        out[x] = t;
      }
    }
  };
  const double gain = sm * sm / (sm * sm + blur * blur);  // smoothed peak / spot amplitude
  const std::size_t before = dets.size();
  // The spots found so far, one grid for the whole search: a new one is taken when it lies
  // within kTakenPx of one of them.
  constexpr double kTakenPx = 2;
  GrowingGrid found(W, H, kTakenPx);
  for (std::size_t i = 0; i < before; ++i) {
    const int cx = spots[i].cx, cy = spots[i].cy;
    // Above the seeds' level and above what a slightly wrong spot model leaves behind
    // at high SNR (a sigma off by 10 % leaves ~10 % of the amplitude).
    float best = static_cast<float>(std::max(level, 0.3 * spots[i].a * gain));
    const int xa = std::max(1, cx - sep) - 1, xb = std::min(W - 2, cx + sep) + 1;
    const int ya = std::max(1, cy - sep) - 1, yb = std::min(H - 2, cy + sep) + 1;
    if (xa > xb || ya > yb) continue;
    {
      const int x0 = std::max(0, xa - kr), x1 = std::min(W - 1, xb + kr);
      cv::v_float32x4 top4 = cv::v_setall_f32(-std::numeric_limits<float>::infinity());
      float top = -std::numeric_limits<float>::infinity();
      for (int y = std::max(0, ya - kr); y <= std::min(H - 1, yb + kr); ++y) {
        const float* row = R.ptr<float>(y);
        int x = x0;
        for (; x + 4 <= x1 + 1; x += 4) top4 = cv::v_max(top4, cv::v_load(row + x));
        for (; x <= x1; ++x) top = std::max(top, row[x]);
      }
      top = std::max(top, cv::v_reduce_max(top4));
      if (top < best - 1e-5f * std::abs(best)) continue;  // (the kernel sums to 1 within float rounding)
    }
    if (kr > 0) smoothWindow(xa, xb, ya, yb);
    const cv::Mat& smoothed = kr > 0 ? residual : R;
    int bx = -1, by = -1;
    for (int y = std::max(1, cy - sep); y <= std::min(H - 2, cy + sep); ++y) {
      const float* row = smoothed.ptr<float>(y);
      for (int x = std::max(1, cx - sep); x <= std::min(W - 2, cx + sep); ++x) {
        const float v = row[x];
        if (v <= best) continue;
        bool peak = true;
        for (int yy = y - 1; yy <= y + 1 && peak; ++yy)
          for (int xx = x - 1; xx <= x + 1; ++xx)
            if (smoothed.at<float>(yy, xx) > v) peak = false;
        if (peak) {
          best = v;
          bx = x;
          by = y;
        }
      }
    }
    if (bx < 0) continue;
    bool taken = false;
    found.near(bx, by, kTakenPx + 0.5, [&](int j, double) { taken = taken || std::hypot(dets[j].x - bx, dets[j].y - by) < kTakenPx; });
    if (taken) continue;
    Detection d = dets[i];
    d.x = bx;
    d.y = by;
    found.add(static_cast<int>(dets.size()), bx, by);
    dets.push_back(d);
    Spot s;
    tables(d, s);
    s.a = best / gain;
    spots.push_back(s);
  }
  // Their models leave the residual once the search is over (it smooths R as it was).
  for (std::size_t i = before; i < dets.size(); ++i) render(spots[i], -1.0f);
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
    constexpr double kElongation = 1.1;
    const double npix = static_cast<double>(n) * n;
    // A spot's rows over the window of half-width r around (cx, cy): its narrow model
    // (sigma sm, the fit's tables) and its shape (sigma sg, from its position), 0 where the
    // spot's own window does not reach.
    struct Rows {
      double nx[32], ny[32], gx[32], gy[32];
    };
    auto shapeRows = [&](const Detection& d, const Spot& s, int cx, int cy, Rows& w) {
      double gx[32], gy[32];
      gaussianRow(gx, n, s.cx - r, d.x, inv2g2, c2g2);
      gaussianRow(gy, n, s.cy - r, d.y, inv2g2, c2g2);
      for (int k = 0; k < n; ++k) {
        const int ox = cx - r + k - s.cx, oy = cy - r + k - s.cy;
        const bool inx = std::abs(ox) <= r, iny = std::abs(oy) <= r;
        w.nx[k] = inx ? static_cast<double>(s.ex[ox + r]) : 0.0;
        w.gx[k] = inx ? static_cast<double>(static_cast<float>(gx[ox + r])) : 0.0;
        w.ny[k] = iny ? static_cast<double>(s.ey[oy + r]) : 0.0;
        w.gy[k] = iny ? static_cast<double>(static_cast<float>(gy[oy + r])) : 0.0;
      }
    };
    // Residual sum of squares (in pixel variances) over the window around (cx, cy) of the
    // data (R plus the narrow models of `fitted`) against spots of sigma sg at the centres
    // of `fitted`, amplitudes by least squares; `energy` gets their sum of squares.
    // The window lies inside the frame (the caller keeps 2 r from the edges).
    Rows wa, wb;
    auto shapedRss = [&](int cx, int cy, std::size_t ia, const std::size_t* ib, double& energy) {
      const Spot& a = spots[ia];
      shapeRows(dets[ia], a, cx, cy, wa);
      if (ib) shapeRows(dets[*ib], spots[*ib], cx, cy, wb);
      double vv = 0, va = 0, vb = 0, aa = 0, bb = 0, ab = 0;
      double ax2 = 0, bx2 = 0, abx = 0;
      for (int k = 0; k < n; ++k) {
        ax2 += wa.gx[k] * wa.gx[k];
        if (ib) {
          bx2 += wb.gx[k] * wb.gx[k];
          abx += wa.gx[k] * wb.gx[k];
        }
      }
      for (int k = 0; k < n; ++k) {
        const float* row = R.ptr<float>(cy - r + k) + (cx - r);
        const double an = a.a * wa.ny[k], ag = wa.gy[k];
        double rvv = 0, rva = 0, rvb = 0;
        if (!ib) {
          for (int x = 0; x < n; ++x) {
            const double v = row[x] + an * wa.nx[x];
            rvv += v * v;
            rva += v * wa.gx[x];
          }
        } else {
          const double bn = spots[*ib].a * wb.ny[k];
          for (int x = 0; x < n; ++x) {
            const double v = row[x] + an * wa.nx[x] + bn * wb.nx[x];
            rvv += v * v;
            rva += v * wa.gx[x];
            rvb += v * wb.gx[x];
          }
          vb += rvb * wb.gy[k];
          bb += bx2 * wb.gy[k] * wb.gy[k];
          ab += abx * ag * wb.gy[k];
        }
        vv += rvv;
        va += rva * ag;
        aa += ax2 * ag * ag;
      }
      double explained = 0;
      if (!ib) {
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
      // Only elongated blobs: the principal variances of a round spot are equal, two spots
      // 2.3 px apart make them differ by ~50 %. Principal axis of the spot's data (residual
      // plus its own model) under the mask, whose square root is separable too. Measured
      // on the SNR 4 scenes (seeds 31, 7, 11) and the 600-particle throughput scene, no
      // accepted split was less elongated than 1.14 while round spots at high SNR are mostly
      // below 1.1: a 10 % margin skips most of the pair fits that would fail, and no split.
      // Taken before the residual test below, which costs as much and rejects fewer.
      double sw = 0, sxx = 0, syy = 0, sxy = 0;
      const Spot& s = spots[i];
      float qx[32], qy[32], dxs[32];
      for (int k = 0; k < n; ++k) {
        qx[k] = std::sqrt(s.ex[k]);
        qy[k] = std::sqrt(s.ey[k]);
        dxs[k] = static_cast<float>(cx - r + k - dets[i].x);
      }
      if (cx - r + kLanes <= W && n <= kLanes) {
        // Per-column sums over the rows (4 vectors of 4 lanes), then over the columns.
        float mx[kLanes] = {}, wx[kLanes] = {}, lw[kLanes], lwy[kLanes], lwyy[kLanes];
        for (int k = 0; k < n; ++k) {
          mx[k] = s.ex[k];
          wx[k] = qx[k];
        }
        cv::v_float32x4 vm[4], vq[4], aw[4], awy[4], awyy[4];
        for (int v = 0; v < 4; ++v) {
          vm[v] = cv::v_load(mx + 4 * v);
          vq[v] = cv::v_load(wx + 4 * v);
          aw[v] = awy[v] = awyy[v] = cv::v_setzero_f32();
        }
        const cv::v_float32x4 zero = cv::v_setzero_f32();
        for (int y = cy - r; y <= cy + r; ++y) {
          const float* row = R.ptr<float>(y) + (cx - r);
          const float dy = static_cast<float>(y - dets[i].y);
          const float q = qy[y - cy + r];
          const cv::v_float32x4 ay = cv::v_setall_f32(static_cast<float>(s.a) * s.ey[y - cy + r]), vq0 = cv::v_setall_f32(q),
                                vq1 = cv::v_setall_f32(q * dy), vq2 = cv::v_setall_f32(q * dy * dy);
          for (int v = 0; v < 4; ++v) {
            const cv::v_float32x4 w = cv::v_max(zero, cv::v_muladd(ay, vm[v], cv::v_load(row + 4 * v))) * vq[v];
            aw[v] = cv::v_muladd(w, vq0, aw[v]);
            awy[v] = cv::v_muladd(w, vq1, awy[v]);
            awyy[v] = cv::v_muladd(w, vq2, awyy[v]);
          }
        }
        for (int v = 0; v < 4; ++v) {
          cv::v_store(lw + 4 * v, aw[v]);
          cv::v_store(lwy + 4 * v, awy[v]);
          cv::v_store(lwyy + 4 * v, awyy[v]);
        }
        for (int k = 0; k < n; ++k) {
          sw += lw[k];
          sxx += static_cast<double>(lw[k]) * dxs[k] * dxs[k];
          sxy += static_cast<double>(lwy[k]) * dxs[k];
          syy += lwyy[k];
        }
      } else {
        for (int y = cy - r; y <= cy + r; ++y) {
          const float* row = R.ptr<float>(y) + (cx - r);
          const double dy = y - dets[i].y;
          const float ay = static_cast<float>(s.a) * s.ey[y - cy + r];
          float rw = 0, rx = 0, rxx = 0;
          for (int k = 0; k < n; ++k) {
            const float w = std::max(0.0f, row[k] + ay * s.ex[k]) * qx[k];
            rw += w;
            rx += w * dxs[k];
            rxx += w * dxs[k] * dxs[k];
          }
          const double q = qy[y - cy + r];
          sw += rw * q;
          sxx += rxx * q;
          syy += rw * q * dy * dy;
          sxy += rx * q * dy;
        }
      }
      if (sw <= 0) continue;
      const double tr = sxx + syy, disc = std::sqrt(std::max(0.0, 0.25 * (sxx - syy) * (sxx - syy) + sxy * sxy));
      if (tr / 2 - disc <= 0 || (tr / 2 + disc) / (tr / 2 - disc) < kElongation) continue;
      double energy = 0;
      const double r1 = shapedRss(cx, cy, i, nullptr, energy);
      const double threshold = std::max(kSplit, kFrac * energy);
      // Cheap screen: two spots cannot gain more than the excess over a good fit (about
      // half the window's pixel variances at least remain).
      if (r1 < 0.5 * npix + threshold) continue;
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
      const double r2 = shapedRss(cx, cy, i, &k, pair_energy);
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
    if (nb.none(i)) continue;
    if (i >= before && spots[i].a * gain < level) drop[i] = 1;
    for (int q = nb.first[i]; q < nb.first[i + 1]; ++q) {
      const int j = nb.list[q];
      if (!drop[j] && !drop[i] && std::hypot(dets[j].x - dets[i].x, dets[j].y - dets[i].y) < 1.0) drop[spots[i].a < spots[j].a ? i : j] = 1;
    }
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < dets.size(); ++i)
    if (!drop[i]) dets[kept++] = dets[i];
  dets.resize(kept);
}

}  // namespace mmval::tracking::detail
