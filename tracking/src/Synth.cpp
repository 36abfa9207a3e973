#include "mmval/tracking/Synth.hpp"

#include <cmath>
#include <algorithm>
#include <random>
#include <stdexcept>

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/core/Resources.hpp"

namespace mmval::tracking {

namespace {

struct Grain {
  double x, y, r;
};

/// Uniform flow U along x past a set of cylinders: superposed doublets
/// (exact for one cylinder, a smooth approximation for several).
cv::Point2d velocity(const std::vector<Grain>& grains, double U, double x, double y) {
  double u = U, v = 0;
  for (const auto& g : grains) {
    const double dx = x - g.x, dy = y - g.y, r2 = dx * dx + dy * dy;
    if (r2 < 1e-9) continue;
    const double R2 = g.r * g.r, r4 = r2 * r2;
    u -= U * R2 * (dx * dx - dy * dy) / r4;
    v -= U * R2 * 2 * dx * dy / r4;
  }
  return {u, v};
}

bool inGrain(const std::vector<Grain>& grains, double x, double y, double margin) {
  for (const auto& g : grains)
    if (std::hypot(x - g.x, y - g.y) < g.r + margin) return true;
  return false;
}

}  // namespace

SynthFormat parseSynthFormat(const std::string& name) {
  if (name == "png") return SynthFormat::png8;
  if (name == "rgba") return SynthFormat::rgba_png;
  if (name == "tiff16") return SynthFormat::tiff16;
  if (name == "mp4") return SynthFormat::mp4;
  throw std::invalid_argument("unknown synthetic frame format '" + name + "' (png, rgba, tiff16 or mp4)");
}

std::string synthFormatName(SynthFormat format) {
  switch (format) {
    case SynthFormat::png8: return "png";
    case SynthFormat::rgba_png: return "rgba";
    case SynthFormat::tiff16: return "tiff16";
    case SynthFormat::mp4: return "mp4";
  }
  return "png";
}

struct SynthFrameWriter::Video {
  cv::VideoWriter writer;
};

SynthFrameWriter::SynthFrameWriter(std::filesystem::path dir, SynthFormat format, double fps_hz)
    : m_dir(std::move(dir)), m_format(format), m_fps_hz(fps_hz) {
  std::filesystem::create_directories(m_format == SynthFormat::mp4 ? m_dir : m_dir / "frames");
}

SynthFrameWriter::~SynthFrameWriter() {
  if (m_video) {
    m_video->writer.release();
    std::error_code ec;
    std::filesystem::remove(m_video_tmp, ec);
  }
}

std::string SynthFrameWriter::write(int frame, const cv::Mat& image) {
  if (m_format == SynthFormat::mp4) {
    cv::Mat bytes, bgr;
    image.convertTo(bytes, CV_8U, 255.0);
    cv::cvtColor(bytes, bgr, cv::COLOR_GRAY2BGR);
    if (!m_video) {
      m_video = std::make_unique<Video>();
      m_video_tmp = temporaryPathFor(m_dir / "video.mp4");
      // MPEG-4 part 2 ('mp4v') is what Debian's OpenCV + FFMPEG writes into .mp4 without extra codecs.
      if (!m_video->writer.open(m_video_tmp.string(), cv::CAP_FFMPEG, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), m_fps_hz, bgr.size(), true))
        throw std::runtime_error("this OpenCV build cannot write an mp4 video (FFMPEG backend, mp4v codec): choose another frame format");
    }
    m_video->writer.write(bgr);
    return (m_dir / "video.mp4").string();
  }
  cv::Mat out;
  std::string ext = ".png";
  switch (m_format) {
    case SynthFormat::tiff16:
      image.convertTo(out, CV_16U, 65535.0);
      ext = ".tif";
      break;
    case SynthFormat::rgba_png: {
      cv::Mat bytes;
      image.convertTo(bytes, CV_8U, 255.0);
      cv::cvtColor(bytes, out, cv::COLOR_GRAY2BGRA);  // alpha 255
      break;
    }
    default: image.convertTo(out, CV_8U, 255.0);
  }
  const auto name = m_dir / "frames" / fmt::format("frame_{:05d}{}", frame, ext);
  const auto tmp = temporaryPathFor(name);
  if (!cv::imwrite(tmp.string(), out)) throw std::runtime_error("cannot write the frame " + name.string());
  commitTemporary(tmp, name);
  m_files.push_back(name.string());
  return name.string();
}

std::vector<std::string> SynthFrameWriter::finish() {
  if (m_video) {
    m_video->writer.release();
    m_video.reset();
    commitTemporary(m_video_tmp, m_dir / "video.mp4");
    m_files.push_back((m_dir / "video.mp4").string());
  }
  return m_files;
}

SynthResult writeSyntheticVideo(const SynthOptions& options, const std::filesystem::path& dir) {
  SynthOptions o = options;
  if (!o.geometry.empty()) {
    o.width = o.geometry.cols;
    o.height = o.geometry.rows;
    o.grains = 0;
  }
  // The truth is kept in memory until truth.csv is written: 240 B per particle and frame, measured
  // with /usr/bin/time -v (synth 64 x 64 px, 2000 particles: 598 MB peak at 1000 frames, 126 MB at 10).
  // Moving particles are replaced as they leave, so frames x (particles + immobile) records.
  constexpr double kBytesPerTruthRecord = 240;
  const double records = static_cast<double>(o.frames) * (static_cast<double>(o.particles) + o.immobile);
  requireMemory(records * kBytesPerTruthRecord, defaultMaxMemoryBytes(),
                fmt::format("the ground truth of {} frames x {} particles ({:.3g} positions)", o.frames, o.particles + o.immobile, records),
                {{}, 0, 0, "synth.frames"}, "fewer frames or particles (synth.frames / --frames, synth.particles / --particles)");
  // Distance to the nearest grain pixel, for geometry masks.
  cv::Mat to_grain;
  if (!o.geometry.empty()) {
    cv::Mat pore = o.geometry == 0;
    cv::distanceTransform(pore, to_grain, cv::DIST_L2, 3);
  }
  std::mt19937_64 rng(o.seed);
  std::uniform_real_distribution<double> U01(0, 1);
  std::normal_distribution<double> N01(0, 1);
  std::vector<Grain> grains;
  for (int tries = 0; static_cast<int>(grains.size()) < o.grains && tries < 10000; ++tries) {
    const Grain g{U01(rng) * o.width, U01(rng) * o.height, o.grain_radius * (0.7 + 0.6 * U01(rng))};
    bool ok = g.x > g.r + 10 && g.x < o.width - g.r - 10;
    for (const auto& h : grains) ok = ok && std::hypot(g.x - h.x, g.y - h.y) > g.r + h.r + 12;
    if (ok) grains.push_back(g);
  }
  struct Particle {
    std::int64_t id;
    double x, y;
    int stop_frame;  // -1: never
    bool immobile;
    double sigma = 0, amplitude = 0;
  };
  if (o.snr > 0) o.noise = o.spot_amplitude / o.snr;
  std::normal_distribution<double> brownian(0, std::sqrt(2 * std::max(0.0, o.brownian_d)));
  auto solid = [&](double x, double y, double margin) {
    if (to_grain.empty()) return inGrain(grains, x, y, margin);
    const int xi = std::clamp(static_cast<int>(x), 0, o.width - 1), yi = std::clamp(static_cast<int>(y), 0, o.height - 1);
    return to_grain.at<float>(yi, xi) < margin + 0.5;
  };
  auto flow = [&](double x, double y) { return o.flow ? o.flow(x, y) : velocity(grains, o.speed, x, y); };
  std::int64_t next_id = 0;
  auto spawn = [&](bool at_inlet) {
    Particle p{next_id++, 0, 0, -1, false, o.spot_sigma, o.spot_amplitude};
    do {
      p.x = at_inlet ? U01(rng) * 2 * std::max(o.speed, 1.0) : U01(rng) * o.width;
      p.y = 4 + U01(rng) * (o.height - 8);
    } while (solid(p.x, p.y, 3));
    // Deposition late in the video, so a median background does not absorb the deposit.
    if (U01(rng) < o.deposit_fraction) p.stop_frame = static_cast<int>((0.6 + 0.3 * U01(rng)) * o.frames);
    if (o.defocus > 0) {
      // Out of focus: wider and dimmer, the same integrated brightness.
      p.sigma = o.spot_sigma * (1 + o.defocus * U01(rng));
      p.amplitude = o.spot_amplitude * (o.spot_sigma * o.spot_sigma) / (p.sigma * p.sigma);
    }
    return p;
  };
  std::vector<Particle> ps;
  for (int i = 0; i < o.particles; ++i) ps.push_back(spawn(false));
  for (int i = 0; i < o.immobile; ++i) {
    Particle p = spawn(false);
    p.immobile = true;
    p.stop_frame = 0;
    ps.push_back(p);
  }
  // Static scene: bright glass, darker grains.
  cv::Mat scene(o.height, o.width, CV_32F, cv::Scalar(0.8));
  for (const auto& g : grains) cv::circle(scene, cv::Point2d(g.x, g.y), static_cast<int>(g.r), cv::Scalar(0.3), -1, cv::LINE_AA);
  if (!o.geometry.empty()) scene.setTo(cv::Scalar(0.3), o.geometry != 0);
  cv::GaussianBlur(scene, scene, cv::Size(0, 0), 1.0);
  cv::Mat illumination;
  if (o.illumination_gradient != 0) {
    illumination = cv::Mat(o.height, o.width, CV_32F);
    for (int x = 0; x < o.width; ++x) illumination.col(x).setTo(1.0 + o.illumination_gradient * (0.5 - x / std::max(1.0, o.width - 1.0)));
  }

  SynthResult result;
  SynthFrameWriter writer(dir, o.format, o.fps);
  for (int f = 0; f < o.frames; ++f) {
    cv::Mat img = scene.clone();
    for (const auto& p : ps) {
      // Sub-pixel Gaussian spot.
      const int half = static_cast<int>(std::ceil(4 * p.sigma));
      for (int y = std::max(0, static_cast<int>(p.y) - half); y <= std::min(o.height - 1, static_cast<int>(p.y) + half); ++y)
        for (int x = std::max(0, static_cast<int>(p.x) - half); x <= std::min(o.width - 1, static_cast<int>(p.x) + half); ++x) {
          const double g = p.amplitude * std::exp(-((x - p.x) * (x - p.x) + (y - p.y) * (y - p.y)) / (2 * p.sigma * p.sigma));
          img.at<float>(y, x) += static_cast<float>(o.dark_particles ? -g : g);
        }
      TrackPoint t;
      t.frame = f;
      t.particle = p.id;
      t.t = f / o.fps;
      t.x_px = p.x;
      t.y_px = p.y;
      t.x = p.x * o.pixel_size;
      t.y = p.y * o.pixel_size;
      result.truth.points.push_back(t);
    }
    if (!illumination.empty()) img = img.mul(illumination);
    if (o.photons > 0)
      for (int y = 0; y < img.rows; ++y)
        for (int x = 0; x < img.cols; ++x) {
          float& v = img.at<float>(y, x);
          std::poisson_distribution<long> shot(std::max(0.0, static_cast<double>(v)) * o.photons);
          v = static_cast<float>(static_cast<double>(shot(rng)) / o.photons);
        }
    for (int y = 0; y < img.rows; ++y)
      for (int x = 0; x < img.cols; ++x) img.at<float>(y, x) += static_cast<float>(o.noise * N01(rng));
    writer.write(f, img);
    // Advance: RK2 in the flow field; particles leaving at the right re-enter as new ones.
    for (auto& p : ps) {
      if (p.immobile || (p.stop_frame >= 0 && f >= p.stop_frame)) continue;
      const cv::Point2d v1 = flow(p.x, p.y);
      const cv::Point2d v2 = flow(p.x + 0.5 * v1.x, p.y + 0.5 * v1.y);
      const double ox = p.x, oy = p.y;
      p.x += v2.x;
      p.y += v2.y;
      if (o.brownian_d > 0) {
        p.x += brownian(rng);
        p.y += brownian(rng);
      }
      if (!to_grain.empty() && solid(p.x, p.y, 1.5)) {  // never into a grain: stay put this frame
        p.x = ox;
        p.y = oy;
      }
      // Near a grain surface the doublet superposition is not exact: push the particle back out.
      for (const auto& g : grains) {
        const double dx = p.x - g.x, dy = p.y - g.y, r = std::hypot(dx, dy);
        if (r < g.r + 2 && r > 1e-9) {
          p.x = g.x + dx / r * (g.r + 2);
          p.y = g.y + dy / r * (g.r + 2);
        }
      }
      if (p.x >= o.width - 1 || p.x < 0 || p.y < 1 || p.y > o.height - 2) p = spawn(true);
    }
  }
  result.frames = writer.finish();
  for (const auto& p : ps) {
    if (p.immobile) {
      ++result.immobile;
      result.immobile_ids.push_back(p.id);
    }
    else if (p.stop_frame >= 0) ++result.deposited;
    else ++result.moving;
  }
  std::stable_sort(result.truth.points.begin(), result.truth.points.end(), [](const TrackPoint& a, const TrackPoint& b) {
    return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame;
  });
  writeTracksCsv(dir / "truth.csv", result.truth, o.pixel_size);
  return result;
}

void writeSynthTruth(const std::filesystem::path& dir, Tracks& truth, const SynthSceneCommon& c, nlohmann::json model) {
  std::stable_sort(truth.points.begin(), truth.points.end(),
                   [](const TrackPoint& a, const TrackPoint& b) { return a.particle != b.particle ? a.particle < b.particle : a.frame < b.frame; });
  writeTracksCsv(dir / "truth.csv", truth, c.pixel_size_um * 1e-6);
  model["scene"] = c.scene;
  model["seed"] = c.seed;
  model["frames"] = c.frames;
  model["width_px"] = c.width;
  model["height_px"] = c.height;
  model["fps_hz"] = c.fps_hz;
  model["pixel_size_um"] = c.pixel_size_um;
  model["format"] = synthFormatName(c.format);
  model["particles"] = c.particles;
  writeFileAtomic(dir / "truth.json", model.dump(2) + "\n");
}

}  // namespace mmval::tracking
