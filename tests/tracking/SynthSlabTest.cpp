// The Brownian slab video (SynthSlab.hpp) checked for realism against
// independent references: Stokes-Einstein by hand, the per-axis step variance
// 2 D dt of free diffusion (and its motion-blur reduction), the uniform
// stationary height distribution of reflected diffusion, the stated defocus
// model measured on rendered spots, the file formats read back with OpenCV,
// the flicker amplitude in the frame means, and reproducibility per seed.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <numbers>
#include <sstream>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "mmval/core/Tracks.hpp"
#include "mmval/tracking/SynthSlab.hpp"

namespace mmval::tracking {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::path(MMVAL_BINARY_DIR) / "test-output" / "synth-slab" / name;
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

std::string slurp(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Mean and variance of the frame-to-frame x and y steps (um) of every particle in the box.
struct StepStats {
  double mean[2] = {0, 0}, var[2] = {0, 0};
  long n = 0;
};
StepStats stepStats(const SlabSimulation& sim, double pixel_size_um) {
  std::map<std::int64_t, const SlabRecord*> last;
  std::vector<double> dx, dy;
  for (const auto& r : sim.records) {
    auto it = last.find(r.particle);
    if (it != last.end() && it->second->frame == r.frame - 1) {
      dx.push_back((r.x_px - it->second->x_px) * pixel_size_um);
      dy.push_back((r.y_px - it->second->y_px) * pixel_size_um);
    }
    last[r.particle] = &r;
  }
  StepStats s;
  s.n = static_cast<long>(dx.size());
  const std::vector<double>* axes[2] = {&dx, &dy};
  for (int a = 0; a < 2; ++a) {
    for (double v : *axes[a]) s.mean[a] += v / s.n;
    for (double v : *axes[a]) s.var[a] += (v - s.mean[a]) * (v - s.mean[a]) / (s.n - 1);
  }
  return s;
}

BrownianSlabOptions small() {
  BrownianSlabOptions o;
  o.width = 64;
  o.height = 48;
  o.frames = 4;
  o.particles = 20;
  return o;
}

TEST(SynthSlab, StokesEinsteinByHand) {
  // kB T / (6 pi eta a) with kB = 1.380649e-23 J/K, T = 295.15 K (22 C), eta = 0.9544 mPa s
  // (water at 22 C), a = 0.5 um: 4.07499e-21 J / 8.99513e-9 N s/m = 4.5303e-13 m^2/s.
  const double d = stokesEinsteinDiffusion(295.15, 0.9544e-3, 0.5e-6);
  EXPECT_NEAR(d, 4.5303e-13, 1e-17);
  BrownianSlabOptions o;
  EXPECT_NEAR(slabDiffusion(o), 0.45303, 1e-5);  // the defaults: a 1-um sphere in water at 22 C
  o.diffusion_um2_s = 0.2;
  EXPECT_DOUBLE_EQ(slabDiffusion(o), 0.2);
}

/// Per-axis steps after drift removal have variance 2 D dt and their mean is the drift;
/// tolerance 3 standard errors (variance: sqrt(2 / (n - 1)) relative; mean: sqrt(var / n)).
void expectDiffusionAndDrift(const BrownianSlabOptions& o, double expected_var_um2) {
  const SlabSimulation sim = simulateBrownianSlab(o);
  const StepStats s = stepStats(sim, o.pixel_size_um);
  ASSERT_GT(s.n, 20000);
  const double dt = 1 / o.fps_hz;
  for (int a = 0; a < 2; ++a) {
    const double var_tol = 3 * std::sqrt(2.0 / (s.n - 1)) * expected_var_um2;
    EXPECT_NEAR(s.var[a], expected_var_um2, var_tol) << "axis " << a << ": step variance (um^2) against 2 D dt";
    const double mean_tol = 3 * std::sqrt(expected_var_um2 / s.n);
    EXPECT_NEAR(s.mean[a], o.drift_um_s[static_cast<std::size_t>(a)] * dt, mean_tol) << "axis " << a << ": mean step (um) against drift dt";
  }
}

TEST(SynthSlab, StepVarianceIsTwoDdtAndMeanStepIsTheDrift) {
  BrownianSlabOptions o;
  o.width = o.height = 400;  // a wide box: steps lost to wrapping bias the variance by < 0.2 %
  o.particles = 200;
  o.frames = 120;
  o.drift_um_s = {0.6, -0.3};
  o.slab_um = 6;
  const double d = slabDiffusion(o);
  expectDiffusionAndDrift(o, 2 * d / o.fps_hz);
}

TEST(SynthSlab, MotionBlurReducesTheStepVarianceAsSavinAndDoyle) {
  // Averaging K equally spaced positions over the exposure t_e: the steps of the averages have
  // variance 2 D (dt - t_e (1 - 1/K^2) / 3) (sum of min-overlaps of the K sample intervals).
  BrownianSlabOptions o;
  o.width = o.height = 400;
  o.particles = 200;
  o.frames = 120;
  o.slab_um = 6;
  o.exposure_s = 0.03;
  o.exposure_substeps = 8;
  const double d = slabDiffusion(o), dt = 1 / o.fps_hz, k = o.exposure_substeps;
  expectDiffusionAndDrift(o, 2 * d * (dt - o.exposure_s * (1 - 1 / (k * k)) / 3));
}

TEST(SynthSlab, DriftChangesAtTheGivenRate) {
  // v(t) = v0 + a t: the mean x step from frame f to f + 1 is v(t_f + dt/2) dt. Compared over the
  // first and the second half of the video, each within 3 standard errors of its mean.
  BrownianSlabOptions o;
  o.width = o.height = 400;
  o.particles = 200;
  o.frames = 120;
  o.slab_um = 6;
  o.drift_um_s = {0.6, 0.0};
  o.drift_change_um_s2 = {0.1, -0.05};
  const SlabSimulation sim = simulateBrownianSlab(o);
  const double dt = 1 / o.fps_hz, var = 2 * slabDiffusion(o) * dt;
  std::map<std::int64_t, const SlabRecord*> last;
  double sum[2][2] = {{0, 0}, {0, 0}}, expected[2][2] = {{0, 0}, {0, 0}};
  long n[2] = {0, 0};
  for (const auto& r : sim.records) {
    auto it = last.find(r.particle);
    if (it != last.end() && it->second->frame == r.frame - 1) {
      const int half = r.frame - 1 < o.frames / 2 ? 0 : 1;
      const double t_mid = (r.frame - 0.5) * dt;
      sum[half][0] += (r.x_px - it->second->x_px) * o.pixel_size_um;
      sum[half][1] += (r.y_px - it->second->y_px) * o.pixel_size_um;
      expected[half][0] += (o.drift_um_s[0] + o.drift_change_um_s2[0] * t_mid) * dt;
      expected[half][1] += (o.drift_um_s[1] + o.drift_change_um_s2[1] * t_mid) * dt;
      ++n[half];
    }
    last[r.particle] = &r;
  }
  for (int half = 0; half < 2; ++half)
    for (int a = 0; a < 2; ++a)
      EXPECT_NEAR(sum[half][a] / n[half], expected[half][a] / n[half], 3 * std::sqrt(var / n[half])) << "half " << half << ", axis " << a;
  // The change itself is resolved: the halves differ by 0.25 um/s along x, 4.5 standard errors (0.056 um/s) of the difference.
  EXPECT_GT((sum[1][0] / n[1] - sum[0][0] / n[0]) / dt, 0.15);
}

TEST(SynthSlab, HeightStaysInTheSlabAndIsUniform) {
  BrownianSlabOptions o;
  o.width = o.height = 100;
  o.particles = 2000;
  o.frames = 100;
  o.slab_um = 4;  // 100 frames of 0.19 um steps: many wall reflections
  const SlabSimulation sim = simulateBrownianSlab(o);
  constexpr int kBins = 20;
  std::vector<double> count(kBins, 0);
  double n = 0;
  for (const auto& r : sim.records) {
    ASSERT_GE(r.z_um, 0.0);
    ASSERT_LE(r.z_um, o.slab_um);
    if (r.frame != o.frames - 1) continue;  // one frame: independent particles
    count[static_cast<std::size_t>(std::min(kBins - 1, static_cast<int>(r.z_um / o.slab_um * kBins)))] += 1;
    n += 1;
  }
  ASSERT_GT(n, 2000);
  double chi2 = 0;
  for (double c : count) chi2 += (c - n / kBins) * (c - n / kBins) / (n / kBins);
  // 99.9 % quantile of chi-square with 19 degrees of freedom: 43.82 (a clamped wall piles up at 0 and H).
  EXPECT_LT(chi2, 43.82) << "first bin " << count.front() << ", last " << count.back() << ", expected " << n / kBins;
}

TEST(SynthSlab, SpotWidthAndContrastFollowTheDefocusModel) {
  BrownianSlabOptions o;
  o.width = o.height = 96;
  o.flicker = 0;
  const SlabOptics optics = slabOptics(o);
  // The stated model, written out independently: sigma0^2 = a^2/5 + (0.21 lambda/NA)^2, c = tan(asin(NA/n))/2.
  const double sigma0 = std::sqrt(o.radius_um * o.radius_um / 5 + std::pow(0.21 * o.wavelength_um / o.numerical_aperture, 2));
  const double c = 0.5 * std::tan(std::asin(o.numerical_aperture / o.medium_index));
  EXPECT_NEAR(optics.focus_um, 10.0, 1e-12);
  EXPECT_NEAR(optics.depth_of_field_um, 0.55 * 1.33 / 0.16, 1e-12);
  double integral0 = 0;
  for (double dz : {0.0, 1.0, 3.0, -3.0, 6.0}) {
    const cv::Point3d p(48, 48, optics.focus_um + dz);
    const cv::Mat img = renderSlabFrame(o, optics, &p, 1, 1, 1.0);
    // Darkening below the background 0.8, and its second moment per axis.
    double sum = 0, sxx = 0, syy = 0, peak = 0;
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) {
        const double w = 0.8 - img.at<float>(y, x);
        sum += w;
        sxx += w * (x - 48) * (x - 48);
        syy += w * (y - 48) * (y - 48);
        peak = std::max(peak, w);
      }
    const double model_sigma_px = std::sqrt(sigma0 * sigma0 + c * c * dz * dz) / o.pixel_size_um;
    // 0.5 %: the 4-sigma truncation removes 0.1 % of the variance; pixel sampling of a Gaussian wider than 1 px much less.
    EXPECT_NEAR(std::sqrt(sxx / sum), model_sigma_px, 0.005 * model_sigma_px) << "dz " << dz << " um";
    EXPECT_NEAR(std::sqrt(syy / sum), model_sigma_px, 0.005 * model_sigma_px) << "dz " << dz << " um";
    // Integrated darkening conserved; peak contrast falls as sigma0^2 / sigma^2.
    if (dz == 0) integral0 = sum;
    EXPECT_NEAR(sum, integral0, 0.005 * integral0) << "dz " << dz << " um";
    EXPECT_NEAR(peak, 0.8 * o.contrast * sigma0 * sigma0 / (model_sigma_px * model_sigma_px * o.pixel_size_um * o.pixel_size_um), 1e-5)
        << "dz " << dz << " um";
  }
}

TEST(SynthSlab, FormatsReadBackWithOpenCv) {
  BrownianSlabOptions o = small();
  o.format = SynthFormat::rgba_png;
  const fs::path rgba = scratch("rgba");
  auto r = writeBrownianSlabVideo(o, rgba);
  ASSERT_EQ(r.files.size(), 4u);
  const cv::Mat four = cv::imread((rgba / "frames" / "frame_00000.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(four.type(), CV_8UC4);
  EXPECT_EQ(four.cols, 64);
  EXPECT_EQ(four.rows, 48);
  std::vector<cv::Mat> ch;
  cv::split(four, ch);
  double lo = 0, hi = 0;
  cv::minMaxLoc(ch[3], &lo, &hi);
  EXPECT_EQ(lo, 255);
  EXPECT_EQ(cv::countNonZero(ch[0] != ch[2]), 0) << "grey: B = G = R";

  o.format = SynthFormat::tiff16;
  const fs::path tiff = scratch("tiff16");
  writeBrownianSlabVideo(o, tiff);
  const cv::Mat sixteen = cv::imread((tiff / "frames" / "frame_00001.tif").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(sixteen.type(), CV_16UC1);
  cv::minMaxLoc(sixteen, &lo, &hi);
  // The 16-bit range is used: background 0.8 of 65535, and far more than 256 distinct levels.
  EXPECT_GT(hi, 0.75 * 65535);
  std::map<int, int> levels;
  for (auto it = sixteen.begin<std::uint16_t>(); it != sixteen.end<std::uint16_t>(); ++it) ++levels[*it];
  EXPECT_GT(levels.size(), 256u);

  // The mp4 decodes to the same frames as the 8-bit PNGs of the same seed, up to the lossy codec.
  o.format = SynthFormat::png8;
  const fs::path png = scratch("png8");
  writeBrownianSlabVideo(o, png);
  o.format = SynthFormat::mp4;
  const fs::path mp4 = scratch("mp4");
  r = writeBrownianSlabVideo(o, mp4);
  ASSERT_EQ(r.files.size(), 1u);
  cv::VideoCapture cap((mp4 / "video.mp4").string());
  ASSERT_TRUE(cap.isOpened());
  int frames = 0;
  cv::Mat frame, grey;
  while (cap.read(frame)) {
    ASSERT_EQ(frame.cols, 64);
    cv::cvtColor(frame, grey, cv::COLOR_BGR2GRAY);
    const cv::Mat lossless = cv::imread((png / "frames" / fmt::format("frame_{:05d}.png", frames)).string(), cv::IMREAD_UNCHANGED);
    ASSERT_EQ(lossless.type(), CV_8UC1);
    cv::Mat diff;
    cv::absdiff(grey, lossless, diff);
    EXPECT_LT(cv::mean(diff)[0], 6) << "frame " << frames << ": mean |mp4 - png| in grey levels";
    EXPECT_NEAR(cv::mean(grey)[0], cv::mean(lossless)[0], 3) << "frame " << frames;  // the YUV 4:2:0 round trip shifts ~2 levels
    ++frames;
  }
  EXPECT_EQ(frames, 4);
}

TEST(SynthSlab, TruthIsTheSharedSchemaWithFocusColumns) {
  BrownianSlabOptions o = small();
  o.particles = 60;
  const fs::path dir = scratch("truth");
  const auto r = writeBrownianSlabVideo(o, dir);
  const Tracks t = readTracksCsv(dir / "truth.csv");
  long in_view = 0;
  for (const auto& rec : r.simulation.records) in_view += rec.in_view ? 1 : 0;
  ASSERT_EQ(static_cast<long>(t.points.size()), in_view);
  const SlabOptics optics = slabOptics(o);
  for (const auto& p : t.points) {
    ASSERT_TRUE(std::isfinite(p.z));
    EXPECT_GE(p.x_px, 0);
    EXPECT_LE(p.x_px, o.width - 1);
    EXPECT_NEAR(p.x, p.x_px * o.pixel_size_um * 1e-6, 1e-10);
    EXPECT_NEAR(p.t, p.frame / o.fps_hz, 1e-9 * (1 + p.t));  // written with 10 significant digits
  }
  // in_focus agrees with |z - z_f| <= dof / 2, column by column.
  std::istringstream csv(slurp(dir / "truth.csv"));
  std::string line;
  std::getline(csv, line);
  EXPECT_EQ(line, "frame,particle,x,y,x_um,y_um,t_s,z_um,dz_um,sigma_px,peak_contrast,in_focus");
  int focused = 0, rows = 0;
  while (std::getline(csv, line)) {
    std::vector<double> v;
    std::stringstream ss(line);
    for (std::string f; std::getline(ss, f, ',');) v.push_back(std::stod(f));
    ASSERT_EQ(v.size(), 12u);
    EXPECT_EQ(v[11] == 1, std::abs(v[8]) <= optics.depth_of_field_um / 2 + 1e-4) << line;
    focused += v[11] == 1;
    ++rows;
  }
  // A uniform slab of 20 um with a 4.57 um depth of field: 23 % in focus; 3 sigma of a binomial on the rows.
  const double p = optics.depth_of_field_um / o.slab_um;
  EXPECT_NEAR(static_cast<double>(focused) / rows, p, 3 * std::sqrt(p * (1 - p) / (rows / o.frames)));
  EXPECT_TRUE(fs::exists(dir / "truth.json"));
  EXPECT_EQ(static_cast<int>(readTracksCsv(dir / "truth_in_focus.csv").points.size()), focused);
}

TEST(SynthSlab, FlickerShowsInTheFrameMeans) {
  BrownianSlabOptions o = small();
  o.frames = 200;
  o.particles = 2;
  o.flicker = 0.05;
  o.format = SynthFormat::tiff16;
  auto relativeStd = [&](const std::string& name) {
    const fs::path dir = scratch(name);
    writeBrownianSlabVideo(o, dir);
    std::vector<double> means;
    for (int f = 0; f < o.frames; ++f)
      means.push_back(cv::mean(cv::imread((dir / "frames" / fmt::format("frame_{:05d}.tif", f)).string(), cv::IMREAD_UNCHANGED))[0]);
    double m = 0, v = 0;
    for (double x : means) m += x / means.size();
    for (double x : means) v += (x - m) * (x - m) / (means.size() - 1);
    return std::sqrt(v) / m;
  };
  // The sample std of n normal draws has a relative standard error of 1 / sqrt(2 (n - 1)) = 5 %: 3 of them.
  const double with = relativeStd("flicker");
  EXPECT_NEAR(with, o.flicker, 3 * o.flicker / std::sqrt(2.0 * (o.frames - 1)));
  o.flicker = 0;
  // Without flicker the frame means vary only by noise averaged over 3072 pixels and spots entering or leaving: 0.2 %.
  EXPECT_LT(relativeStd("steady"), 0.1 * with);
}

TEST(SynthSlab, SameSeedSameFiles) {
  BrownianSlabOptions o = small();
  o.exposure_s = 0.02;
  const fs::path a = scratch("seed-a"), b = scratch("seed-b"), c = scratch("seed-c");
  writeBrownianSlabVideo(o, a);
  writeBrownianSlabVideo(o, b);
  o.seed = 2;
  writeBrownianSlabVideo(o, c);
  int files = 0;
  for (const auto& e : fs::recursive_directory_iterator(a)) {
    if (!e.is_regular_file()) continue;
    const fs::path rel = fs::relative(e.path(), a);
    EXPECT_EQ(slurp(e.path()), slurp(b / rel)) << rel;
    ++files;
  }
  EXPECT_EQ(files, 7);  // four frames, truth.csv, truth_in_focus.csv, truth.json
  EXPECT_NE(slurp(a / "truth.csv"), slurp(c / "truth.csv"));
  EXPECT_NE(slurp(a / "frames" / "frame_00002.png"), slurp(c / "frames" / "frame_00002.png"));
}

TEST(SynthSlab, OptionsOutOfRangeAreRefused) {
  BrownianSlabOptions o = small();
  o.exposure_s = 0.1;  // longer than a 24 fps frame
  EXPECT_THROW(simulateBrownianSlab(o), std::invalid_argument);
  o = small();
  o.numerical_aperture = 1.4;  // beyond water's index
  EXPECT_THROW(simulateBrownianSlab(o), std::invalid_argument);
  o = small();
  o.focus_um = 25;
  EXPECT_THROW(simulateBrownianSlab(o), std::invalid_argument);
  o = small();
  o.viscosity_Pa_s = std::nan("");
  EXPECT_THROW(simulateBrownianSlab(o), std::invalid_argument);
}

}  // namespace
}  // namespace mmval::tracking
