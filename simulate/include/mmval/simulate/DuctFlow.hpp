// Pressure-driven Stokes flow through a straight rectangular duct (width w, depth h), exactly and in
// the depth-averaged model the image kinds solve. A chip's narrowest throats are such ducts; where
// they are not much wider than the chip is deep, the depth-averaged (Brinkman-Hele-Shaw) model
// carries more flow through them than Stokes does. These formulas size that error.
#pragma once

namespace mmval::simulate {

/// Q / (w h^3 G / (12 mu)), the flow through the duct over that of plates h apart and w wide:
/// the exact series 1 - (192 h / (pi^5 w)) sum over odd n of tanh(n pi w / (2h)) / n^5 for h <= w
/// (Bruus 2008, Theoretical Microfluidics; reference-data/shallow-channels.toml), and the same
/// series with w and h exchanged times (w / h)^2 for a duct deeper than wide. w, h > 0.
double ductFlowFactorExact(double width, double depth);

/// The same ratio in the depth-averaged model: mean velocity G h^2 / (12 mu) (1 - cosh(k y) / cosh(k w / 2))
/// across the width with no slip at the sides, k = sqrt(12) / h, so 1 - tanh(k w / 2) / (k w / 2).
double ductFlowFactorDepthAveraged(double width, double depth);

/// ductFlowFactorDepthAveraged / ductFlowFactorExact - 1: the fraction by which the depth-averaged
/// model over-predicts the flow through such a duct (+0.6 % at w = 10 h, +5.5 % at w = 1.5 h,
/// +8.5 % at w = h, +11-12 % for w = 0.3-0.5 h).
double depthAveragedDuctExcess(double width, double depth);

}  // namespace mmval::simulate
