// A ParaView-ready overlay: the fields of a fluid run, the particles of a coupled
// particle run and the tracks of a video of the same mask land in one frame
// (docs/outputs.md). One mask (discs, grains dark) is used three times: `mmval run`
// solves its flow (image-permeability, one cell per pixel) into fields.vtr (plane)
// and fields-3d.vtr (3D Stokes, whose solver counts y down: the file must not); a
// particles-micromodel run writes particles.pvd; `mmval synth --geometry` renders
// particles carried by the flow as a video, and `mmval track` tracks it into
// tracks.csv and tracks.vtp. overlay_check.py then reads the files with VTK's own XML
// readers and checks units, time, bounds, the grains against the mask, that every
// track point and particle position lies in fluid, and that the 3D field's grains and
// velocity agree with the plane field's. The same check on the mask mirrored top to
// bottom must fail: it is the mistake (y down against y up) the common frame exists
// to prevent.
//
// VTK's Python modules come from the Debian package python3-vtk9 (scripts/packages.txt);
// without them the test fails and says so.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "RunMmval.hpp"

namespace fs = std::filesystem;
using mmval::test::freshTestFolder;
using mmval::test::runMmval;

namespace {

constexpr int kCols = 120, kRows = 80;
constexpr double kPixelUm = 2.0;

/// An 8-bit PGM of discs (grains, 0) on fluid (255); `mirror`: rows upside down.
void writeMask(const fs::path& file, bool mirror) {
  struct Disc {
    int cx, cy, r;
  };
  const std::vector<Disc> discs = {{35, 25, 10}, {80, 55, 12}, {95, 15, 7}, {30, 65, 8}};
  std::string px(static_cast<std::size_t>(kCols * kRows), static_cast<char>(255));
  for (int y = 0; y < kRows; ++y)
    for (int x = 0; x < kCols; ++x)
      for (const auto& d : discs)
        if ((x - d.cx) * (x - d.cx) + (y - d.cy) * (y - d.cy) <= d.r * d.r) px[static_cast<std::size_t>((mirror ? kRows - 1 - y : y) * kCols + x)] = 0;
  std::ofstream(file, std::ios::binary) << "P5\n" << kCols << ' ' << kRows << "\n255\n" << px;
}

/// Runs `command` with the shell; its exit status and output.
mmval::test::Outcome shell(const std::string& command) {
  mmval::test::Outcome o;
  FILE* pipe = popen((command + " 2>&1").c_str(), "r");
  std::array<char, 4096> buf{};
  while (std::fgets(buf.data(), buf.size(), pipe) != nullptr) o.output += buf.data();
  const int raw = pclose(pipe);
  o.status = WIFEXITED(raw) ? WEXITSTATUS(raw) : -1;
  return o;
}

/// The first Python that imports VTK's modules: python3 on PATH, else Debian's own
/// interpreter (where python3-vtk9 installs them); "" when neither does.
std::string pythonWithVtk() {
  for (const std::string py : {"python3", "/usr/bin/python3"})
    if (shell(py + " -c 'import vtkmodules.vtkIOXML'").status == 0) return py;
  return "";
}

}  // namespace

TEST(Overlay, FieldsGrainsAndTracksShareOneFrameReadByVtk) {
  const std::string python = pythonWithVtk();
  ASSERT_FALSE(python.empty()) << "VTK's Python modules are missing: install the Debian package python3-vtk9 (scripts/packages.txt); "
                                  "this test does not skip without them";
  const fs::path dir = freshTestFolder("overlay", "fluid-and-tracks");
  writeMask(dir / "mask.pgm", false);
  writeMask(dir / "mask-mirrored.pgm", true);
  std::ofstream(dir / "fluid.toml") << "# The flow through the overlay test's mask, one cell per pixel.\n"
                                       "[case]\nname = \"overlay-fluid\"\nkind = \"image-permeability\"\n"
                                       "[geometry]\nmask = \"mask.pgm\"\npixel_size = \"2 um\"\ngrains = \"dark\"\n"
                                       "[numerics]\ncells_per_pixel = 1\ndepth_model = \"all\"\ncells_per_pixel_3d = 1\ncells_z = 4\n";
  const auto fluid = runMmval("run " + (dir / "fluid.toml").string() + " --out " + (dir / "fluid").string());
  ASSERT_EQ(fluid.status, 0) << fluid.output;
  const auto synth = runMmval(fmt::format("synth --out {} --geometry {} --pixel-size-um {} --width {} --height {} --frames 30 --particles 12 "
                                          "--immobile 0 --speed 2 --seed 3",
                                          (dir / "video").string(), (dir / "mask.pgm").string(), kPixelUm, kCols, kRows));
  ASSERT_EQ(synth.status, 0) << synth.output;
  const auto track = runMmval(fmt::format("track '{}/frames/*.png' --pixel-size-um {} --fps 10 --quiet --out {}", (dir / "video").string(), kPixelUm,
                                          (dir / "tracks").string()));
  ASSERT_EQ(track.status, 0) << track.output;
  ASSERT_TRUE(fs::exists(dir / "tracks" / "tracks.vtp"));
  // Particles carried through the same mask by the coupled particle engine (2 s, 1 um fines).
  std::ofstream(dir / "particles.toml") << "# Fines through the overlay test's mask.\n"
                                           "[case]\nname = \"overlay-particles\"\nkind = \"particles-micromodel\"\n"
                                           "[geometry]\nmask = \"mask.pgm\"\npixel_size = \"2 um\"\ngrains = \"dark\"\ndepth = \"20 um\"\n"
                                           "[flow]\nrate = \"0.05 uL/min\"\nrate_width = \"1 mm\"\n"
                                           "[particles]\ndiameter = \"1 um\"\ndensity = \"1.05 g/cm3\"\nconcentration = \"2e9 mL^-1\"\n"
                                           "[run]\nduration = \"2 s\"\noutput_interval = \"0.05 s\"\nseed = 1\n";
  const auto particles = runMmval("run " + (dir / "particles.toml").string() + " --quiet --out " + (dir / "particles").string());
  ASSERT_EQ(particles.status, 0) << particles.output;

  const std::string check = fmt::format("{} {}/tests/apps/overlay_check.py --fields {} --tracks-vtp {} --tracks-csv {} --pixel-size-m {} --particles-pvd {}"
                                        " --fields-3d {}",
                                        python, MMVAL_SOURCE_DIR, (dir / "fluid" / "fields.vtr").string(), (dir / "tracks" / "tracks.vtp").string(),
                                        (dir / "tracks" / "tracks.csv").string(), kPixelUm * 1e-6, (dir / "particles" / "particles.pvd").string(),
                                        (dir / "fluid" / "fields-3d.vtr").string());
  const auto same = shell(check + " --mask " + (dir / "mask.pgm").string());
  std::printf("%s", same.output.c_str());
  EXPECT_EQ(same.status, 0) << same.output;
  EXPECT_NE(same.output.find("overlay_check: 0 failure(s)"), std::string::npos);

  // The negative control: the mask upside down does not overlay the field.
  const auto mirrored = shell(check + " --mask " + (dir / "mask-mirrored.pgm").string());
  EXPECT_EQ(mirrored.status, 1) << mirrored.output;
  EXPECT_NE(mirrored.output.find("FAIL  grains"), std::string::npos) << mirrored.output;
}

TEST(OutputSeries, UnsteadyFieldsAndParticlesAreTimeSeriesReadByVtk) {
  const std::string python = pythonWithVtk();
  ASSERT_FALSE(python.empty()) << "VTK's Python modules are missing: install the Debian package python3-vtk9 (scripts/packages.txt)";
  const fs::path dir = freshTestFolder("overlay", "series");
  const std::string check = python + " " + MMVAL_SOURCE_DIR + "/tests/apps/overlay_check.py --pvd ";
  // The shipped unsteady cylinder case cut to 0.02 s on a coarse grid, with 4 snapshots;
  // exit status 3 (its acceptance fails so short a run) still writes every output.
  const auto unsteady = runMmval(std::string("run ") + MMVAL_SOURCE_DIR + "/cases/fluid-schaefer-turek-2d2.toml --quiet --out " + (dir / "unsteady").string() +
                                 " --set numerics.end_time=0.02 --set numerics.statistics_from=0.01 --set numerics.cells_around=16"
                                 " --set numerics.body_refine=1 --set output.snapshots=4");
  ASSERT_TRUE(unsteady.status == 0 || unsteady.status == 3) << unsteady.output;
  for (int k = 1; k <= 4; ++k) EXPECT_TRUE(fs::exists(dir / "unsteady" / "fields" / fmt::format("fields-{:04d}.vtr", k))) << k;
  const auto fields = shell(check + (dir / "unsteady" / "fields.pvd").string());
  std::printf("%s", fields.output.c_str());
  EXPECT_EQ(fields.status, 0) << fields.output;
  // The last snapshot is the state at the end time.
  EXPECT_NE(fields.output.find("TimeValue 0.02 s, timestep 0.02 s"), std::string::npos) << fields.output;

  // Particles in the shipped channel (2 mm x 200 um x 20 um): every snapshot inside it.
  const auto particles = runMmval(std::string("run ") + MMVAL_SOURCE_DIR + "/cases/particles-channel.toml --quiet --out " + (dir / "particles").string() +
                                  " --set particles.count=40");
  ASSERT_TRUE(particles.status == 0 || particles.status == 3) << particles.output;
  const auto series = shell(check + (dir / "particles" / "particles.pvd").string() + " --within 0 2e-3 0 2e-4 0 2e-5");
  EXPECT_EQ(series.status, 0) << series.output;
  EXPECT_NE(series.output.find("overlay_check: 0 failure(s)"), std::string::npos) << series.output;
}
