// Large discs: objects tens of pixels or more across imaged as a bright rim around a
// darker interior (glass or plastic discs, tubes seen end-on, large beads in a
// monolayer lit from the side). A spot detector sees a disc's rim as a string of
// bright maxima; here each disc is found once, at its centre.
//
// Method (each step stated):
// 1. Proposals: circle Hough transform by gradient voting (Yuen, Princen, Illingworth
//    & Kittler 1990, Image Vision Comput. 8:71; OpenCV's HOUGH_GRADIENT) on the 8-bit
//    frame median-filtered (5 px, as the source project of the real discs video does)
//    and stretched to its 1-99 % grey range, radii in the range given; taken most votes
//    first, and skipped when inside a disc already fitted.
// 2. Rim radius: where the median over 72 rays of the 1 px-smoothed frame's brightness
//    at that distance peaks (robust to a neighbour's rim or a glint on a few rays); it
//    must stand above the ring medians inside (0.6-0.8 of it) and outside (1.25 of it)
//    by the margin: 4 noise sigmas and at least 5 % of the frame's 1-99 % grey range.
// 3. Centre: on each ray, the local maximum nearest that radius (+-25 %, then +-10 %)
//    that stands above the darker interior side by the margin is a rim point (sub-pixel
//    by a parabola). A circle is fitted to the rim points by least squares (Kasa 1976,
//    IEEE Trans. Instrum. Meas. 25:8), points off it by more than 15 %, then 4 %, of the
//    radius (at least 1.5 px) dropped and refitted; rays are cast again from the new
//    centre, three passes. A disc keeps rim points on at least 30 % of the rays (in a
//    packing a touching neighbour or glare hides much of a rim; a blob, an edge or a
//    gap between discs gives no circle of rim points).
// 4. One detection per disc: discs do not overlap, so of two fits whose centres are
//    closer than 0.85 of their summed radii the one with more rim points stays.
#pragma once
#include <vector>

#include <opencv2/core.hpp>

#include "mmval/tracking/Detect.hpp"

namespace mmval::tracking {

/// Smallest disc radius this path handles, px: smaller round objects are spots for the
/// spot and ring detectors (the ring test looks out to 20 px).
constexpr double kMinDiscRadiusPx = 20;

/// Each disc of radius `radius_min_px` to `radius_max_px` in `frame` (float grey in
/// [0, 1]) once, at the centre of the circle fitted to its rim (x, y px); area is pi r^2
/// of the fitted radius r, peak the rim's mean brightness above the interior, mass the
/// share of rays with a rim point. Throws std::invalid_argument for a radius range that
/// is not 0 < min <= max.
std::vector<Detection> detectDiscs(const cv::Mat& frame, double radius_min_px, double radius_max_px);

}  // namespace mmval::tracking
