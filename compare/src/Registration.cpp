#include "mmval/compare/Registration.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "mmval/core/MaskRule.hpp"
#include "mmval/core/Error.hpp"
#include "mmval/core/ImageHeader.hpp"
#include "mmval/core/Resources.hpp"
#include "mmval/tracking/Frames.hpp"

namespace mmval::compare {

namespace {

constexpr double kPi = 3.14159265358979323846;

cv::Mat prepare(const cv::Mat& image, double sigma) {
  cv::Mat g = tracking::toFloatGrey(image);
  if (sigma > 0) cv::GaussianBlur(g, g, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
  return g;
}

/// How well the mask, warped into the frame by W (frame px -> mask px), explains the frame.
struct Fit {
  double correlation = 0, rms = 0, overlap = 0;
};

Fit overlapFit(const cv::Mat& frame, const cv::Mat& mask, const cv::Matx23d& w) {
  cv::Mat warped, valid;
  cv::warpAffine(mask, warped, cv::Mat(w), frame.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  cv::Mat ones(mask.size(), CV_8U, cv::Scalar(255));
  cv::warpAffine(ones, valid, cv::Mat(w), frame.size(), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  double n = 0, sf = 0, sm = 0, sff = 0, smm = 0, sfm = 0;
  for (int r = 0; r < frame.rows; ++r) {
    const float* f = frame.ptr<float>(r);
    const float* m = warped.ptr<float>(r);
    const unsigned char* v = valid.ptr<unsigned char>(r);
    for (int c = 0; c < frame.cols; ++c) {
      if (v[c] == 0) continue;
      n += 1;
      sf += f[c];
      sm += m[c];
      sff += double(f[c]) * f[c];
      smm += double(m[c]) * m[c];
      sfm += double(f[c]) * m[c];
    }
  }
  Fit fit;
  fit.overlap = n / (double(frame.rows) * frame.cols);
  if (n < 16) return fit;
  const double vf = sff / n - (sf / n) * (sf / n), vm = smm / n - (sm / n) * (sm / n), cfm = sfm / n - (sf / n) * (sm / n);
  if (vf <= 0 || vm <= 0) return fit;
  fit.correlation = cfm / std::sqrt(vf * vm);
  // Least-squares gain and bias: residual variance = var_f (1 - rho^2).
  fit.rms = std::sqrt(std::max(0.0, vf * (1 - fit.correlation * fit.correlation)));
  return fit;
}

cv::Matx23d translation(cv::Point2d t) { return {1, 0, t.x, 0, 1, t.y}; }

/// Candidate shifts (frame px -> mask px) from phase correlation or template matching.
std::vector<cv::Point2d> shiftCandidates(const cv::Mat& frame, const cv::Mat& mask) {
  std::vector<cv::Point2d> out{{0, 0}};
  if (frame.rows <= mask.rows && frame.cols <= mask.cols && frame.size() != mask.size()) {
    // The frame is a window of the mask: normalised cross-correlation on a reduced copy.
    int level = 0;
    cv::Mat f = frame, m = mask;
    while (std::min(f.rows, f.cols) >= 96 && level < 4) {
      cv::pyrDown(f, f);
      cv::pyrDown(m, m);
      ++level;
    }
    cv::Mat score;
    cv::matchTemplate(m, f, score, cv::TM_CCOEFF_NORMED);
    double lo, hi;
    cv::Point plo, phi;
    cv::minMaxLoc(score, &lo, &hi, &plo, &phi);
    const double k = std::ldexp(1.0, level);
    out.push_back({phi.x * k, phi.y * k});
    out.push_back({plo.x * k, plo.y * k});  // contrast-inverted frame
    return out;
  }
  // Same size (or a frame larger than the mask): phase correlation on equal canvases.
  cv::Mat m(frame.size(), CV_32F, cv::Scalar(cv::mean(mask)[0]));
  const cv::Rect common(0, 0, std::min(frame.cols, mask.cols), std::min(frame.rows, mask.rows));
  mask(common).copyTo(m(common));
  cv::Mat window;
  cv::createHanningWindow(window, frame.size(), CV_32F);
  // phaseCorrelate multiplies its inputs by the window in place when their
  // size is already DFT-friendly (OpenCV 4.6): give it copies.
  const cv::Point2d s = cv::phaseCorrelate(frame.clone(), m.clone(), window);
  cv::Mat inv = 1.0 - frame;
  const cv::Point2d si = cv::phaseCorrelate(inv, m.clone(), window);
  for (const auto& c : {s, si}) {
    out.push_back(c);
    out.push_back(-c);
  }
  return out;
}

}  // namespace

cv::Matx23d RigidTransform::matrix() const {
  const double a = angle_deg * kPi / 180.0;
  return {scale * std::cos(a), -scale * std::sin(a), dx_px, scale * std::sin(a), scale * std::cos(a), dy_px};
}

RigidTransform RigidTransform::fromMatrix(const cv::Matx23d& m, double scale) {
  RigidTransform t;
  t.dx_px = m(0, 2);
  t.dy_px = m(1, 2);
  t.angle_deg = std::atan2(m(1, 0), m(0, 0)) * 180.0 / kPi;
  t.scale = scale;
  return t;
}

nlohmann::json RegistrationResult::toJson(double mask_pixel_size_m) const {
  nlohmann::json j{{"method", "OpenCV ECC, MOTION_EUCLIDEAN, coarse to fine"},
                   {"maps", "frame pixel -> mask pixel"},
                   {"dx_px", transform.dx_px},
                   {"dy_px", transform.dy_px},
                   {"rotation_deg", transform.angle_deg},
                   {"scale", transform.scale},
                   {"ecc_correlation", correlation},
                   {"rms_residual", rms_residual},
                   {"overlap_fraction", overlap},
                   {"contrast_inverted", inverted},
                   {"pyramid_levels", levels},
                   {"initial_shift_px", {initial_shift.x, initial_shift.y}}};
  if (mask_pixel_size_m > 0) {
    j["dx_um"] = transform.dx_px * mask_pixel_size_m * 1e6;
    j["dy_um"] = transform.dy_px * mask_pixel_size_m * 1e6;
    j["mask_pixel_size_um"] = mask_pixel_size_m * 1e6;
  }
  return j;
}

RegistrationResult registerToMask(const cv::Mat& frame_in, const cv::Mat& mask_in, const RegistrationOptions& o, double scale) {
  if (frame_in.empty() || mask_in.empty()) throw RegistrationFailed("empty image");
  if (!(scale > 0)) throw RegistrationFailed(fmt::format("frame-to-mask scale must be positive, got {}", scale));
  cv::Mat frame = prepare(frame_in, 0);
  if (std::abs(scale - 1) > 1e-12) cv::resize(frame, frame, cv::Size(), scale, scale, scale < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  if (o.blur_sigma_px > 0) cv::GaussianBlur(frame, frame, cv::Size(), o.blur_sigma_px, o.blur_sigma_px, cv::BORDER_REPLICATE);
  const cv::Mat mask = prepare(mask_in, o.blur_sigma_px);

  // Initial shift and polarity: the candidate that correlates best.
  RegistrationResult r;
  cv::Mat inverted = 1.0 - frame;
  double best = -2;
  cv::Point2d shift(0, 0);
  for (const auto& c : o.initial_guess ? shiftCandidates(frame, mask) : std::vector<cv::Point2d>{{0, 0}})
    for (bool inv : {false, true}) {
      const Fit f = overlapFit(inv ? inverted : frame, mask, translation(c));
      if (f.overlap >= 0.5 * o.min_overlap && f.correlation > best) {
        best = f.correlation;
        shift = c;
        r.inverted = inv;
      }
    }
  if (r.inverted) frame = inverted;
  r.initial_shift = shift;

  // Coarse to fine.
  int levels = o.pyramid_levels;
  if (levels < 0) {
    levels = 1;
    while (levels < 6 && std::min(frame.rows, frame.cols) / std::ldexp(1.0, levels) >= 48) ++levels;
  }
  levels = std::max(1, levels);
  std::vector<cv::Mat> pf{frame}, pm{mask};
  for (int l = 1; l < levels; ++l) {
    cv::Mat a, b;
    cv::pyrDown(pf.back(), a);
    cv::pyrDown(pm.back(), b);
    pf.push_back(a);
    pm.push_back(b);
  }
  r.levels = levels;
  cv::Mat warp = (cv::Mat_<float>(2, 3) << 1, 0, float(shift.x / std::ldexp(1.0, levels - 1)), 0, 1, float(shift.y / std::ldexp(1.0, levels - 1)));
  const cv::TermCriteria criteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, o.iterations, o.epsilon);
  auto ecc = [&](int l, cv::Mat& wm) {
    try {
      return cv::findTransformECC(pf[l], pm[l], wm, cv::MOTION_EUCLIDEAN, criteria, cv::noArray(), 5);
    } catch (const cv::Exception& e) {
      throw RegistrationFailed(fmt::format("ECC did not converge at pyramid level {} of {} ({}); the images may not overlap or show different pores",
                                           l, levels, e.err));
    }
  };
  for (int l = levels - 1; l >= 1; --l) {
    ecc(l, warp);
    warp.at<float>(0, 2) *= 2;
    warp.at<float>(1, 2) *= 2;
  }
  // Full resolution. OpenCV's ECC stops at the first step that lowers the
  // correlation, and its rotation (about the image corner) is poorly
  // conditioned against the shift, so the refinement also starts from the
  // initial shift alone; the better of the two solutions wins.
  r.correlation = -2;
  cv::Mat best_warp;
  std::string last_error;
  std::vector<cv::Mat> starts{warp};
  if (levels > 1) starts.push_back((cv::Mat_<float>(2, 3) << 1, 0, float(shift.x), 0, 1, float(shift.y)));
  for (auto& start : starts) {
    try {
      const double rho = ecc(0, start);
      if (rho > r.correlation) r.correlation = rho, best_warp = start;
    } catch (const RegistrationFailed& e) {
      last_error = e.what();
    }
  }
  if (best_warp.empty()) throw RegistrationFailed(last_error);
  warp = best_warp;
  cv::Matx23d w;
  for (int i = 0; i < 2; ++i)
    for (int j = 0; j < 3; ++j) w(i, j) = warp.at<float>(i, j);
  const Fit fit = overlapFit(frame, mask, w);
  r.overlap = fit.overlap;
  r.rms_residual = fit.rms;
  if (fit.overlap < o.min_overlap)
    throw RegistrationFailed(fmt::format("only {:.0f} % of the frame lands inside the mask after alignment (at least {:.0f} % expected); "
                                         "the images do not overlap",
                                         100 * fit.overlap, 100 * o.min_overlap));
  if (r.correlation < o.min_correlation)
    throw RegistrationFailed(fmt::format("ECC correlation {:.3f} is below the minimum {:.3f}; the frame and the mask do not show the same pores "
                                         "(or the frame is too noisy: register the tracker's background image instead)",
                                         r.correlation, o.min_correlation));
  // Undo the frame's rescaling: frame px u -> rescaled px u_s = scale u + (scale - 1) / 2.
  if (std::abs(scale - 1) > 1e-12) {
    const double off = 0.5 * (scale - 1);
    cv::Matx23d full;
    for (int i = 0; i < 2; ++i) {
      full(i, 0) = w(i, 0) * scale;
      full(i, 1) = w(i, 1) * scale;
      full(i, 2) = w(i, 0) * off + w(i, 1) * off + w(i, 2);
    }
    w = full;
  }
  r.transform = RigidTransform::fromMatrix(w, scale);
  return r;
}

RegistrationResult registerFiles(const std::filesystem::path& frame_input, const std::filesystem::path& mask_file,
                                 const RegistrationOptions& o, double scale) {
  cv::Mat frame;
  {
    tracking::FrameSource source(frame_input.string());
    int index = 0;
    if (!source.next(frame, index))
      throw InputError({frame_input.string(), 0, 0, {}}, "holds no frame", {}, "an image, a video, a folder of images or a TIFF stack");
  }
  requireImageWithin(mask_file, {mask_file.string(), 0, 0, "--register-mask"}, defaultMaxMemoryBytes(), 16, "a smaller mask: crop or downscale it");
  const cv::Mat mask = cv::imread(mask_file.string(), cv::IMREAD_UNCHANGED);
  if (mask.empty()) throw InputError({mask_file.string(), 0, 0, {}}, "cannot read the geometry mask", {}, "a PNG or TIFF image");
  try {
    return registerToMask(frame, mask, o, scale);
  } catch (const RegistrationFailed& e) {
    throw InputError({frame_input.string(), 0, 0, {}}, "cannot be registered to the mask " + mask_file.string() + ": " + e.what(), {},
                     "a frame showing the same pores as the mask; otherwise give the window's origin, rotation and pixel size instead");
  }
}

cv::Mat registrationOverlay(const std::filesystem::path& frame_input, const cv::Mat& pore, const RegistrationResult& r) {
  cv::Mat frame;
  tracking::FrameSource source(frame_input.string());
  int index = 0;
  if (!source.next(frame, index)) return {};
  cv::Mat grey, bgr;
  cv::normalize(frame, grey, 0, 255, cv::NORM_MINMAX, CV_8U);
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  cv::Mat warped, edges;
  cv::warpAffine(pore, warped, cv::Mat(r.transform.matrix()), frame.size(), cv::INTER_NEAREST | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT, 0);
  cv::morphologyEx(warped, edges, cv::MORPH_GRADIENT, cv::Mat::ones(3, 3, CV_8U));
  bgr.setTo(cv::Scalar(0, 220, 0), edges);
  return bgr;
}

cv::Point2d MaskFrame::toMetres(cv::Point2d q) const {
  return {(q.x + 0.5) * pixel_size, y_up ? (rows - q.y - 0.5) * pixel_size : (q.y + 0.5) * pixel_size};
}

cv::Point2d MaskFrame::toPixels(cv::Point2d p) const {
  return {p.x / pixel_size - 0.5, y_up ? rows - p.y / pixel_size - 0.5 : p.y / pixel_size - 0.5};
}

FrameToSimulation FrameToSimulation::fromRegistration(const RegistrationResult& r, const MaskFrame& mask) {
  const cv::Matx23d w = r.transform.matrix();
  const double s = mask.pixel_size, sy = mask.y_up ? -s : s, cy = mask.y_up ? (mask.rows - 0.5) * s : 0.5 * s;
  FrameToSimulation f;
  f.m_per_px = {s * w(0, 0), s * w(0, 1), s * w(0, 2) + 0.5 * s, sy * w(1, 0), sy * w(1, 1), sy * w(1, 2) + cy};
  f.method = "registration";
  f.details = r.toJson(s);
  f.details["mask_y_up"] = mask.y_up;
  return f;
}

FrameToSimulation FrameToSimulation::fromWindow(double ox, double oy, double a, double s, bool y_up) {
  const double sg = y_up ? -1.0 : 1.0, c = std::cos(a), sn = std::sin(a);
  FrameToSimulation f;
  f.m_per_px = {s * c, -sg * s * sn, ox, s * sn, sg * s * c, oy};
  f.method = "window";
  f.details = {{"method", "imaged window given"}, {"origin_x_um", ox * 1e6}, {"origin_y_um", oy * 1e6},
               {"rotation_deg", a * 180 / kPi}, {"pixel_size_um", s * 1e6}, {"y_up", y_up}};
  return f;
}

Tracks applyToTracks(const Tracks& tracks, const FrameToSimulation& map, double frame_pixel_size) {
  Tracks out = tracks;
  const auto& m = map.m_per_px;
  for (auto& p : out.points) {
    double u = p.x_px, v = p.y_px;
    if (!std::isfinite(u) || !std::isfinite(v)) {
      if (!(frame_pixel_size > 0))
        throw InputError({tracks.source, 0, 0, "x, y"}, "has no pixel columns and no frame pixel size was given", {},
                         "pixel columns x, y in the tracks file, or the frame's pixel size");
      u = p.x / frame_pixel_size;
      v = p.y / frame_pixel_size;
    }
    p.x = m(0, 0) * u + m(0, 1) * v + m(0, 2);
    p.y = m(1, 0) * u + m(1, 1) * v + m(1, 2);
  }
  return out;
}

cv::Mat readPoreMask(const std::filesystem::path& file, bool grains_dark) {
  requireImageWithin(file, {file.string(), 0, 0, "geometry mask"}, defaultMaxMemoryBytes(), 16, "a smaller mask: crop or downscale it");
  const cv::Mat raw = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
  if (raw.empty()) throw InputError({file.string(), 0, 0, {}}, "cannot read the geometry mask", {}, "a PNG or TIFF image, pores and grains in two grey levels");
  const cv::Mat g = tracking::toFloatGrey(raw);
  double lo, hi;
  cv::minMaxLoc(g, &lo, &hi);
  if (hi - lo < 1e-6) throw InputError({file.string(), 0, 0, {}}, "the mask has a single grey level", {}, "pores and grains in two grey levels");
  cv::Mat pore;  // mmval's mask rule (core/MaskRule.hpp) on the normalised grey: pore is not grain
  cv::compare(g, maskSplit(lo, hi, 1.0), pore, grains_dark ? cv::CMP_GT : cv::CMP_LE);
  return pore;
}

}  // namespace mmval::compare
