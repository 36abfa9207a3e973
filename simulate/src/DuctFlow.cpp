#include "mmval/simulate/DuctFlow.hpp"

#include <cmath>
#include <numbers>
#include <stdexcept>

namespace mmval::simulate {

namespace {
/// The series bracket for a duct whose short side over long side is r <= 1.
double shallowBracket(double r) {
  constexpr double pi = std::numbers::pi;
  double sum = 0;
  for (int n = 1; n <= 401; n += 2) sum += std::tanh(n * pi / (2 * r)) / std::pow(n, 5);  // terms fall as n^-5: 1e-13 by n = 401
  return 1 - 192 * r / std::pow(pi, 5) * sum;
}

void requirePositive(double width, double depth) {
  if (!(width > 0) || !(depth > 0) || !std::isfinite(width) || !std::isfinite(depth))
    throw std::invalid_argument("duct flow: width and depth must be finite and > 0");
}
}  // namespace

double ductFlowFactorExact(double width, double depth) {
  requirePositive(width, depth);
  if (depth <= width) return shallowBracket(depth / width);
  const double r = width / depth;  // deeper than wide: plates w apart, then scaled to the w h^3 base
  return shallowBracket(r) * r * r;
}

double ductFlowFactorDepthAveraged(double width, double depth) {
  requirePositive(width, depth);
  const double x = std::sqrt(12.0) * width / (2 * depth);
  return 1 - std::tanh(x) / x;
}

double depthAveragedDuctExcess(double width, double depth) { return ductFlowFactorDepthAveraged(width, depth) / ductFlowFactorExact(width, depth) - 1; }

}  // namespace mmval::simulate
