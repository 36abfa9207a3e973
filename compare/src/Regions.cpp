#include "mmval/compare/Regions.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <fmt/format.h>
#include <opencv2/imgproc.hpp>

#include "mmval/core/Error.hpp"
#include "mmval/core/JsonNumbers.hpp"

namespace mmval::compare {

Region RegionMap::at(double x, double y) const {
  const cv::Point2d q = frame.toPixels({x, y});
  const int c = static_cast<int>(std::lround(q.x)), r = static_cast<int>(std::lround(q.y));
  if (r < 0 || c < 0 || r >= label.rows || c >= label.cols) return Region::outside;
  return static_cast<Region>(label.at<unsigned char>(r, c));
}

cv::Mat RegionMap::picture() const {
  cv::Mat out(label.size(), CV_8UC3, cv::Scalar(0, 0, 0));
  for (int r = 0; r < label.rows; ++r)
    for (int c = 0; c < label.cols; ++c) {
      const auto l = label.at<unsigned char>(r, c);
      if (l == 1) out.at<cv::Vec3b>(r, c) = {200, 120, 40};   // BGR: blue bodies
      if (l == 2) out.at<cv::Vec3b>(r, c) = {30, 140, 255};   // orange throats
    }
  return out;
}

RegionMap classifyPoreSpace(const cv::Mat& pore_in, const MaskFrame& frame, const RegionOptions& o) {
  cv::Mat pore;
  cv::compare(pore_in, 0, pore, cv::CMP_NE);
  if (cv::countNonZero(pore) == 0) throw InputError({"pore mask", 0, 0, {}}, "holds no pore pixel", {}, "a mask with pore space (check the grains polarity)");
  // Distance to the nearest grain pixel; the image border counts as open (pores continue beyond the picture).
  cv::Mat padded;
  cv::copyMakeBorder(pore, padded, 1, 1, 1, 1, cv::BORDER_REPLICATE);
  cv::Mat dist_padded;
  cv::distanceTransform(padded, dist_padded, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const cv::Mat dist = dist_padded(cv::Rect(1, 1, pore.cols, pore.rows)).clone();

  // Medial axis: pore pixels where d is a (non-strict) maximum of its 3x3 neighbourhood.
  cv::Mat dmax;
  cv::dilate(dist, dmax, cv::Mat::ones(3, 3, CV_8U));
  RegionMap map;
  map.frame = frame;
  map.width_px = 2.0 * dist;  // every pore pixel lies in its own inscribed disc
  std::vector<double> ridge;
  for (int r = 0; r < pore.rows; ++r)
    for (int c = 0; c < pore.cols; ++c) {
      const float d = dist.at<float>(r, c);
      if (d <= 0 || d < dmax.at<float>(r, c)) continue;
      ridge.push_back(2.0 * d);
      // Local thickness: paint the disc of radius d with its diameter.
      const int R = static_cast<int>(std::ceil(d));
      const float w = 2 * d;
      for (int dr = -R; dr <= R; ++dr)
        for (int dc = -R; dc <= R; ++dc) {
          const int rr = r + dr, cc = c + dc;
          if (rr < 0 || cc < 0 || rr >= pore.rows || cc >= pore.cols) continue;
          if (dr * dr + dc * dc >= d * d) continue;
          float& t = map.width_px.at<float>(rr, cc);
          t = std::max(t, w);
        }
    }
  if (o.throat_width > 0) {
    map.threshold_px = o.throat_width / frame.pixel_size;
    map.rule = fmt::format("throat where the local pore width (local thickness, 2 x distance to the nearest grain of the widest inscribed disc covering the point) "
                           "is at or below {:.4g} um (given); pore body elsewhere",
                           o.throat_width * 1e6);
  } else {
    std::nth_element(ridge.begin(), ridge.begin() + ridge.size() / 2, ridge.end());
    map.threshold_px = ridge[ridge.size() / 2];
    map.rule = fmt::format("throat where the local pore width (local thickness, 2 x distance to the nearest grain of the widest inscribed disc covering the point) "
                           "is at or below the median inscribed diameter along the medial axis, {:.4g} um; pore body elsewhere",
                           map.threshold_px * frame.pixel_size * 1e6);
  }
  map.label = cv::Mat(pore.size(), CV_8U, cv::Scalar(0));
  for (int r = 0; r < pore.rows; ++r)
    for (int c = 0; c < pore.cols; ++c)
      if (pore.at<unsigned char>(r, c)) map.label.at<unsigned char>(r, c) = map.width_px.at<float>(r, c) <= map.threshold_px ? 2 : 1;
  return map;
}

nlohmann::json RegionSpeeds::toJson() const {
  auto num = [](double v) { return finiteOrNull(v * 1e6); };
  return {{"pore_body_mean_speed_um_per_s", num(body_mean)}, {"throat_mean_speed_um_per_s", num(throat_mean)},
          {"pore_body_steps", body_steps},                    {"throat_steps", throat_steps},
          {"steps_in_grains", grain_steps},                   {"steps_outside_mask", outside_steps}};
}

RegionSpeeds regionSpeeds(const std::vector<tracking::Step>& steps, const RegionMap& map) {
  RegionSpeeds s;
  double body = 0, throat = 0;
  for (const auto& st : steps) switch (map.at(st.x, st.y)) {
      case Region::body: body += st.speed, ++s.body_steps; break;
      case Region::throat: throat += st.speed, ++s.throat_steps; break;
      case Region::grain: ++s.grain_steps; break;
      case Region::outside: ++s.outside_steps; break;
    }
  const double nan = std::numeric_limits<double>::quiet_NaN();
  s.body_mean = s.body_steps ? body / s.body_steps : nan;
  s.throat_mean = s.throat_steps ? throat / s.throat_steps : nan;
  return s;
}

}  // namespace mmval::compare
