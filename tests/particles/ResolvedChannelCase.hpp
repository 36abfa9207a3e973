// A particles-resolved scene shared by tests: two 8 um disks in a 60 x 30 um channel with
// creeping inflow and gravity towards y = 0. The low disk deposits on the wall, the high one
// leaves through the open outlet, so the run's outputs change in what they hold (2 particles,
// then 1 deposited) within 0.3 s.
#pragma once
#include <string>

namespace mmval::particles {

/// The case file's text, named `name`.
inline std::string resolvedChannelCase(const std::string& name) {
  return R"(
[case]
name = ")" + name + R"("
kind = "particles-resolved"
[channel]
length = "60 um"
width = "30 um"
mean_velocity = "0.1 mm/s"
[particles]
diameter = "8 um"
x = ["15 um", "35 um"]
y = ["6 um", "24 um"]
[physics]
gravity_y = "-245 m/s2"
[deposition]
capture_distance = "0.5 um"
[numerics]
cells_per_diameter = 8
max_step_fraction = 2.0
[run]
duration = "0.3 s"
output_interval = "0.05 s"
)";
}

}  // namespace mmval::particles
