#include "mmval/openfoam/Peer.hpp"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <regex>
#include <sstream>
#include <stdexcept>

#include <fmt/format.h>

#include "mmval/core/AtomicFile.hpp"
#include "mmval/openfoam/DirectMesh.hpp"
#include "mmval/openfoam/FoamFile.hpp"
#include "mmval/openfoam/ImageGeometry.hpp"
#include "mmval/simulate/CylinderScene.hpp"
#include "mmval/simulate/ForceHistory.hpp"

namespace fs = std::filesystem;

namespace mmval::openfoam {

std::string foamHeader(const std::string& cls, const std::string& object, const std::string& location) {
  std::string out =
      "/*--------------------------------*- C++ -*----------------------------------*\\\n"
      "  Written by mmval (OpenFOAM peer). Edit freely and rerun by hand.\n"
      "\\*---------------------------------------------------------------------------*/\n"
      "FoamFile\n{\n    version     2.0;\n    format      ascii;\n";
  out += fmt::format("    class       {};\n", cls);
  if (!location.empty()) out += fmt::format("    location    \"{}\";\n", location);
  out += fmt::format("    object      {};\n}}\n\n", object);
  return out;
}

/// The installation's own version: WM_PROJECT_VERSION when the environment is
/// sourced, else the line `export WM_PROJECT_VERSION=...` of its etc/bashrc
/// (how OpenFOAM's packages set it); "unknown" when neither says.
std::string installedVersion(const fs::path& project_dir) {
  if (const char* env = std::getenv("WM_PROJECT_VERSION"); env != nullptr && *env != '\0') return env;
  std::ifstream in(project_dir / "etc" / "bashrc");
  const std::string key = "export WM_PROJECT_VERSION=";
  std::string line;
  while (std::getline(in, line)) {
    const std::size_t at = line.find(key);
    if (at == std::string::npos || line.find_first_not_of(" \t") != at) continue;
    std::string v = line.substr(at + key.size());
    v = v.substr(0, v.find_first_of(" \t#;"));
    if (!v.empty()) return v;
  }
  return "unknown";
}

Installation detect() {
  Installation inst;
  const char* env = std::getenv("WM_PROJECT_DIR");
  inst.project_dir = env != nullptr ? fs::path(env) : fs::path("/usr/share/openfoam");
  if (!fs::exists(inst.project_dir / "etc" / "controlDict")) {
    inst.reason = "OpenFOAM not found: no " + (inst.project_dir / "etc/controlDict").string() +
                  " (install the Debian package 'openfoam', or set WM_PROJECT_DIR)";
    return inst;
  }
  for (const char* tool : {"blockMesh", "simpleFoam", "pimpleFoam"}) {
    if (std::system(fmt::format("command -v {} >/dev/null 2>&1", tool).c_str()) != 0) {
      inst.reason = fmt::format("OpenFOAM tool '{}' not on PATH (install the Debian package 'openfoam')", tool);
      return inst;
    }
  }
  inst.available = true;
  inst.version = installedVersion(inst.project_dir);
  return inst;
}

namespace {

std::string vec(double x, double y, double z) { return fmt::format("({:.12g} {:.12g} {:.12g})", x, y, z); }

std::string boundaryField(const std::vector<std::pair<std::string, std::string>>& patches) {
  std::string out = "boundaryField\n{\n";
  for (const auto& [name, body] : patches) out += fmt::format("    {}\n    {{\n{}    }}\n", name, body);
  return out + "}\n";
}

std::string controlDict(const Scene& s, const std::string& application, const std::string& functions) {
  std::string out = foamHeader("dictionary", "controlDict", "system");
  out += fmt::format("application     {};\nstartFrom       startTime;\nstartTime       0;\nstopAt          endTime;\n", application);
  if (s.unsteady) {
    out += fmt::format("endTime         {:.12g};\ndeltaT          {:.12g};\nwriteControl    adjustableRunTime;\nwriteInterval   {:.12g};\n",
                       s.end_time, s.dt, s.end_time);
    out += "adjustTimeStep  yes;\nmaxCo           0.5;\n";
  } else {
    out += fmt::format("endTime         {};\ndeltaT          1;\nwriteControl    timeStep;\nwriteInterval   {};\n", s.max_iterations,
                       s.max_iterations);
  }
  out += "purgeWrite      1;\nwriteFormat     ascii;\nwritePrecision  12;\nwriteCompression off;\ntimeFormat      general;\n"
         "timePrecision   8;\nrunTimeModifiable false;\n\nfunctions\n{\n" +
         functions + "}\n";
  return out;
}

std::string fvSchemes(const Scene& s) {
  std::string out = foamHeader("dictionary", "fvSchemes", "system");
  out += s.unsteady ? "ddtSchemes { default backward; }\n" : "ddtSchemes { default steadyState; }\n";
  out += "gradSchemes { default Gauss linear; }\n"
         "divSchemes\n{\n    default none;\n";
  out += s.unsteady ? "    div(phi,U) Gauss linear;\n" : "    div(phi,U) bounded Gauss linearUpwind grad(U);\n";
  out += "    div((nuEff*dev2(T(grad(U))))) Gauss linear;\n}\n"
         "laplacianSchemes { default Gauss linear corrected; }\n"
         "interpolationSchemes { default linear; }\n"
         "snGradSchemes { default corrected; }\n"
         "wallDist { method meshWave; }\n";
  return out;
}

std::string fvSolution(const Scene& s, bool reference_pressure) {
  std::string out = foamHeader("dictionary", "fvSolution", "system");
  out += "solvers\n{\n"
         "    p { solver GAMG; smoother GaussSeidel; tolerance 1e-10; relTol 0.01; }\n"
         "    pFinal { $p; relTol 0; }\n"
         "    \"(U|UFinal)\" { solver smoothSolver; smoother symGaussSeidel; tolerance 1e-12; relTol 0.05; }\n}\n";
  const std::string ref = reference_pressure ? "    pRefCell 0;\n    pRefValue 0;\n" : "";
  if (s.unsteady) {
    out += "PIMPLE\n{\n    nOuterCorrectors 1;\n    nCorrectors 2;\n    nNonOrthogonalCorrectors 1;\n" + ref + "}\n";
  } else {
    const bool simplec = true;  // SIMPLEC: fastest here for creeping and Re <= 40 steady flows
    out += fmt::format("SIMPLE\n{{\n    nNonOrthogonalCorrectors 1;\n    consistent {};\n{}    residualControl {{ p {:g}; U {:g}; }}\n}}\n",
                       simplec ? "yes" : "no", ref, s.residual, s.residual);
    out += simplec ? "relaxationFactors\n{\n    equations { U 0.9; \".*\" 0.9; }\n    fields { p 1; }\n}\n"
                   : "relaxationFactors\n{\n    equations { U 0.7; \".*\" 0.7; }\n    fields { p 0.3; }\n}\n";
  }
  return out;
}

/// Slabs along x, or along y for periodic cells (a surfaceFieldValue on a
/// cyclic patch fails in parallel when the decomposition splits the pair).
std::string decomposeParDict(int ranks, bool along_y) {
  return foamHeader("dictionary", "decomposeParDict", "system") +
         fmt::format("numberOfSubdomains {};\nmethod simple;\ncoeffs {{ n ({} {} 1); }}\n", ranks, along_y ? 1 : ranks,
                     along_y ? ranks : 1);
}

std::string transportProperties(const Scene& s) {
  return foamHeader("dictionary", "transportProperties", "constant") +
         fmt::format("transportModel Newtonian;\nnu {:.12g};\n", s.nu);
}

std::string turbulenceProperties() {
  return foamHeader("dictionary", "turbulenceProperties", "constant") + "simulationType laminar;\n";
}

/// The initial velocity of an unsteady cylinder scene with Scene::initial_perturbation eps: mmval's
/// start vortex (simulate::startVortex) on a fluid at rest, written as the same expression.
std::string setExprFieldsDict(const Scene& s) {
  const auto v = simulate::startVortex(s.cx, s.cy, s.diameter, s.initial_perturbation, s.u_ref);
  const double xv = v.x_m, yv = v.y_m, amp = v.amplitude_m_s;
  return foamHeader("dictionary", "setExprFieldsDict", "system") +
         fmt::format("expressions\n(\n    U\n    {{\n        field U;\n        dimensions [0 1 -1 0 0 0 0];\n"
                     "        variables\n        (\n            \"X = (pos().x() - {0:.12g}) / {2:.12g}\"\n"
                     "            \"Y = (pos().y() - {1:.12g}) / {2:.12g}\"\n            \"g = {3:.12g} * exp(-(X * X + Y * Y))\"\n        );\n"
                     "        expression #{{ vector(-Y * g, X * g, 0) #}};\n    }}\n);\n",
                     xv, yv, s.diameter, amp);
}

/// The cellZone of every cell that the depth-averaged model's friction acts on (topoSet makes it).
const char* const kDepthZone = "depthAveraged";

/// topoSet's actions for the depth-averaged model: a cellSet of every cell (a box beyond any
/// mesh the peer writes), then the cellZone of it that explicitPorositySource needs.
std::string topoSetDict() {
  return foamHeader("dictionary", "topoSetDict", "system") +
         fmt::format("actions\n(\n"
                     "    {{ name {0}; type cellSet; action new; source boxToCell; box (-1e6 -1e6 -1e6) (1e6 1e6 1e6); }}\n"
                     "    {{ name {0}; type cellZoneSet; action new; source setToCellZone; set {0}; }}\n);\n",
                     kDepthZone);
}

/// The depth-averaged (Brinkman-Hele-Shaw) friction -12 nu u / h^2 of a parabolic profile across
/// the depth h (mmval's FlowOperator, docs/validation/depth-model.md) as a Darcy porosity with
/// d = 12 / h^2 along x and y and none along z (the empty direction). DarcyForchheimer multiplies
/// d by the laminar nu and adds tr(nu d) = 2 nu d to the momentum diagonal, taking nu d u back
/// explicitly: implicit, so SIMPLEC keeps its plane-flow convergence.
std::string heleShawFvOptions(const Scene& s) {
  const double d = 12.0 / (s.hele_shaw_depth * s.hele_shaw_depth);
  return foamHeader("dictionary", "fvOptions", "constant") +
         fmt::format("// Depth-averaged model: chip depth h = {:.12g} m, friction -12 nu U / h^2\n"
                     "depthFriction\n{{\n    type explicitPorositySource;\n    explicitPorositySourceCoeffs\n    {{\n"
                     "        selectionMode cellZone;\n        cellZone {};\n        type DarcyForchheimer;\n"
                     "        d ({:.12g} {:.12g} 0);\n        f (0 0 0);\n"
                     "        coordinateSystem {{ origin (0 0 0); e1 (1 0 0); e2 (0 1 0); }}\n    }}\n}}\n",
                     s.hele_shaw_depth, kDepthZone, d, d);
}

bool perturbedStart(const Scene& s) { return s.kind == Scene::Kind::cylinder_channel && s.unsteady && s.initial_perturbation > 0; }

const std::string kNoSlip = "        type noSlip;\n";
const std::string kZeroGradient = "        type zeroGradient;\n";
const std::string kEmpty = "        type empty;\n";
const std::string kCyclic = "        type cyclic;\n";

void put(const fs::path& file, const std::string& text) { writeFileAtomic(file, text); }

/// The image mesh's empty sides as two patches, back (z = 0, the blockMesh base vertices) and
/// front (z = thickness): extrudeMesh rebuilds the one-cell-deep mesh from the back one.
void splitFrontAndBack(BlockMeshDict& mesh) {
  const int base = static_cast<int>(mesh.vertices.size() / 2);
  for (auto it = mesh.patches.begin(); it != mesh.patches.end(); ++it) {
    if (it->name != "frontAndBack") continue;
    Patch back{"back", "empty", {}, {}}, front{"front", "empty", {}, {}};
    for (const auto& f : it->faces) (f[0] < base ? back : front).faces.push_back(f);
    mesh.patches.erase(it);
    mesh.patches.push_back(back);
    mesh.patches.push_back(front);
    return;
  }
}

/// snappyHexMesh refines in 3D, so a refined 2D mesh comes out several cells deep with its middle
/// points snapped off the planes; extruding its back patch by one cell of `thickness` gives the
/// one-cell-deep mesh the 2D solver needs, with the refined, snapped cross-section.
std::string extrudeMeshDict(double thickness) {
  return foamHeader("dictionary", "extrudeMeshDict", "system") +
         fmt::format("constructFrom patch;\nsourceCase \".\";\nsourcePatches (back);\nexposedPatchName front;\nflipNormals false;\n"
                     "extrudeModel linearNormal;\nnLayers 1;\nexpansionRatio 1.0;\nlinearNormalCoeffs {{ thickness {:.12g}; }}\n"
                     "mergeFaces false;\nmergeTol 0;\n",
                     thickness);
}

/// The snappyHexMesh route of an image scene (Scene::direct_mesh false): the grains' STL, the
/// snappyHexMeshDict and, when the grains are refined, the extrudeMeshDict that makes the refined
/// mesh one cell deep again. The background blockMeshDict is the caller's.
void writeSnappyImageCase(const Scene& s, const MaskGeometry& g, const fs::path& dir) {
  const double cell = imageBackground(s, g.fluid.cols, g.fluid.rows, g.width()).cell;  // one background cell thick
  if (s.surface_level > 0) put(dir / "system" / "extrudeMeshDict", extrudeMeshDict(cell));
  fs::create_directories(dir / "constant" / "triSurface");
  // The walls run beyond the mesh's front and back so every cut lies inside the surface.
  put(dir / "constant" / "triSurface" / "grains.stl",
      s.smooth_boundary ? extrudedStl(smoothGrainPolygons(g, s.smoothing_px), -cell, 2 * cell) : grainStl(g, -cell, 2 * cell));
  put(dir / "system" / "snappyHexMeshDict",
      foamHeader("dictionary", "snappyHexMeshDict", "system") +
          fmt::format(
              "castellatedMesh true;\nsnap true;\naddLayers false;\n\n"
              "geometry\n{{\n    grains.stl {{ type triSurfaceMesh; name grains; }}\n}}\n\n"
              "castellatedMeshControls\n{{\n    maxLocalCells 5000000;\n    maxGlobalCells 20000000;\n    minRefinementCells 0;\n"
              "    maxLoadUnbalance 0.1;\n    nCellsBetweenLevels {};\n    features ();\n"
              "    refinementSurfaces\n    {{\n        grains {{ level ({} {}); patchInfo {{ type wall; }} }}\n    }}\n"
              "    resolveFeatureAngle 30;\n    refinementRegions {{}}\n    locationInMesh {};\n    allowFreeStandingZoneFaces true;\n}}\n\n"
              "snapControls\n{{\n    nSmoothPatch 3;\n    tolerance 2.0;\n    nSolveIter 30;\n    nRelaxIter 5;\n    nFeatureSnapIter {};\n"
              "    implicitFeatureSnap false;\n    explicitFeatureSnap false;\n}}\n\n"
              "addLayersControls\n{{\n    relativeSizes true;\n    layers {{}}\n    expansionRatio 1.0;\n    finalLayerThickness 0.3;\n"
              "    minThickness 0.1;\n    nGrow 0;\n    featureAngle 60;\n    nRelaxIter 3;\n    nSmoothSurfaceNormals 1;\n"
              "    nSmoothNormals 3;\n    nSmoothThickness 10;\n    maxFaceThicknessRatio 0.5;\n    maxThicknessToMedialRatio 0.3;\n"
              "    minMedialAxisAngle 90;\n    nBufferCellsNoExtrude 0;\n    nLayerIter 50;\n}}\n\n"
              // Micrometre cells: the default volume and area guards are for metre-sized meshes.
              "meshQualityControls\n{{\n    maxNonOrtho 65;\n    maxBoundarySkewness 20;\n    maxInternalSkewness 4;\n    maxConcave 80;\n"
              "    minVol -1e30;\n    minTetQuality -1e30;\n    minArea -1;\n    minTwist 0.02;\n    minDeterminant 0.001;\n"
              "    minFaceWeight 0.05;\n    minVolRatio 0.01;\n    minTriangleTwist -1;\n    nSmoothScale 4;\n    errorReduction 0.75;\n"
              "    relaxed {{ maxNonOrtho 75; }}\n}}\n\nmergeTolerance 1e-6;\n",
              std::max(1, s.cells_between_levels), s.surface_level, s.surface_level, vec(g.inside.x, g.inside.y, 0.5 * cell),
              // The smooth outline has no sharp features to snap to: two morph iterations leave the
              // meshed volume as five do (to 1e-6 on a 60 px disc packing at 4 cells per pixel) in 2/3 of the time.
              s.smooth_boundary ? 2 : 5));
}

}  // namespace

ImageBackground imageBackground(const Scene& s, int image_cols, int image_rows, double image_width) {
  ImageBackground bg;
  const double cpp = s.cells_per_pixel / std::ldexp(1.0, std::max(0, s.surface_level));
  bg.nx = std::max(4, static_cast<int>(std::lround(image_cols * cpp)));
  bg.ny = std::max(4, static_cast<int>(std::lround(image_rows * cpp)));
  bg.cell = image_width / bg.nx;
  return bg;
}

double imageMeshThickness(const Scene& s, int image_cols, int image_rows, double image_width) {
  if (s.direct_mesh) return image_width / std::max(4, static_cast<int>(std::lround(image_cols * s.cells_per_pixel)));
  return imageBackground(s, image_cols, image_rows, image_width).cell;
}

long long writeCase(const Scene& s, const fs::path& dir, int ranks, MesherReport* mesher) {
  const bool hele_shaw = s.hele_shaw_depth > 0;
  if (!(s.hele_shaw_depth >= 0 && std::isfinite(s.hele_shaw_depth)))
    throw std::invalid_argument(fmt::format("writeCase: hele_shaw_depth {} m; expected 0 (plane 2D) or a positive depth", s.hele_shaw_depth));
  if (hele_shaw && s.kind != Scene::Kind::image && s.kind != Scene::Kind::channel)
    throw std::invalid_argument("writeCase: the depth-averaged model (hele_shaw_depth > 0) is for channel and image scenes only");
  fs::create_directories(dir / "system");
  fs::create_directories(dir / "constant");
  fs::create_directories(dir / "0");
  BlockMeshDict mesh;
  std::string functions;
  std::string u_file = foamHeader("volVectorField", "U", "0") + "dimensions [0 1 -1 0 0 0 0];\ninternalField uniform (0 0 0);\n\n";
  std::string p_file = foamHeader("volScalarField", "p", "0") + "dimensions [0 2 -2 0 0 0 0];\ninternalField uniform 0;\n\n";
  bool reference_pressure = false;
  long long direct_cells = -1;  // image scenes meshed here (Scene::direct_mesh)

  switch (s.kind) {
    case Scene::Kind::cylinder_channel: {
      CylinderChannel g{s.length, s.height, s.cx, s.cy, s.diameter, s.depth};
      mesh = cylinderChannelMesh(g, s.cells_around);
      const double zc = 0.5 * s.depth;
      functions += fmt::format(
          "    forceCoeffs1\n    {{\n        type forceCoeffs;\n        libs (\"libforces.so\");\n        writeControl timeStep;\n"
          "        writeInterval 1;\n        patches (cylinder);\n        rho rhoInf;\n        rhoInf {:.12g};\n"
          "        liftDir (0 1 0);\n        dragDir (1 0 0);\n        CofR {};\n        pitchAxis (0 0 1);\n"
          "        magUInf {:.12g};\n        lRef {:.12g};\n        Aref {:.12g};\n    }}\n",
          s.rho, vec(s.cx, s.cy, zc), s.u_ref, s.l_ref, s.l_ref * s.depth);
      if (!s.pressure_probes.empty()) {
        std::string points;
        const double r = 0.5 * s.diameter;
        for (auto [x, y] : s.pressure_probes) {
          // Points on the cylinder surface are moved a hair into the fluid so a cell contains them.
          const double dx = x - s.cx, dy = y - s.cy, d = std::hypot(dx, dy);
          if (d > 0 && d < r * (1 + 1e-6)) {
            x = s.cx + dx / d * r * (1 + 1e-6);
            y = s.cy + dy / d * r * (1 + 1e-6);
          }
          points += "            " + vec(x, y, zc) + "\n";
        }
        functions += "    probes1\n    {\n        type probes;\n        libs (\"libsampling.so\");\n        writeControl timeStep;\n"
                     "        writeInterval 1;\n        fields (p);\n        interpolationScheme cellPoint;\n        probeLocations\n        (\n" +
                     points + "        );\n    }\n";
      }
      const std::string inlet = fmt::format(
          "        type exprFixedValue;\n        value uniform (0 0 0);\n"
          "        valueExpr \"vector(4*{0:.12g}*pos().y()*({1:.12g}-pos().y())/({1:.12g}*{1:.12g}), 0, 0)\";\n",
          s.inflow_max, s.height);
      const std::string uniform = fmt::format("        type fixedValue;\n        value uniform ({:.12g} 0 0);\n", s.inflow_max);
      u_file += boundaryField({{"inlet", s.uniform_inflow ? uniform : inlet},
                               {"outlet", kZeroGradient},
                               {"walls", s.slip_walls ? std::string("        type slip;\n") : kNoSlip},
                               {"cylinder", kNoSlip},
                               {"frontAndBack", kEmpty}});
      p_file += boundaryField({{"inlet", kZeroGradient}, {"outlet", "        type fixedValue;\n        value uniform 0;\n"},
                               {"walls", kZeroGradient}, {"cylinder", kZeroGradient}, {"frontAndBack", kEmpty}});
      break;
    }
    case Scene::Kind::periodic_array: {
      mesh = periodicCellMesh(s.cell, s.radius, s.depth, s.cells_around);
      reference_pressure = true;
      // The superficial velocity is measured as the flux through one periodic face.
      functions += "    fluxLeft\n    {\n        type surfaceFieldValue;\n        libs (\"libfieldFunctionObjects.so\");\n"
                   "        writeControl timeStep;\n        writeInterval 1;\n        log false;\n        writeFields false;\n"
                   "        regionType patch;\n        name left;\n        operation sum;\n        fields (phi);\n    }\n";
      u_file += boundaryField({{"left", kCyclic}, {"right", kCyclic}, {"bottom", kCyclic}, {"top", kCyclic}, {"cylinder", kNoSlip}, {"frontAndBack", kEmpty}});
      p_file += boundaryField({{"left", kCyclic}, {"right", kCyclic}, {"bottom", kCyclic}, {"top", kCyclic}, {"cylinder", kZeroGradient}, {"frontAndBack", kEmpty}});
      put(dir / "constant" / "fvOptions",
          foamHeader("dictionary", "fvOptions", "constant") +
              fmt::format("momentumSource\n{{\n    type meanVelocityForce;\n    selectionMode all;\n    fields (U);\n"
                          "    Ubar ({:.12g} 0 0);\n}}\n",
                          s.mean_velocity));
      break;
    }
    case Scene::Kind::image: {
      const MaskGeometry g = loadMask(s.mask, s.pixel, s.grain_dark);
      if (s.direct_mesh) {
        const auto t0 = std::chrono::steady_clock::now();
        const DirectMesh2D m = s.smooth_boundary ? directImageMesh(g, s.smoothing_px, s.cells_per_pixel)
                                                 : pixelImageMesh(g, static_cast<int>(std::lround(s.cells_per_pixel)));
        const PolyMesh poly = extrude(m, m.dx(), "symmetry");
        fs::remove_all(dir / "constant" / "polyMesh");
        writePolyMesh(poly, dir);
        direct_cells = poly.cells;
        if (mesher != nullptr) {
          *mesher = MesherReport{true, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), m.wall_vertices, m.snapped,
                                 m.pulled_back, m.pinned, m.dropped_disconnected, m.max_move_cells, m.minCellAreaRatio()};
        }
      } else {
        writeSnappyImageCase(s, g, dir);
      }
      functions += "    flowRate\n    {\n        type surfaceFieldValue;\n        libs (\"libfieldFunctionObjects.so\");\n"
                   "        writeControl timeStep;\n        writeInterval 1;\n        log false;\n        writeFields false;\n"
                   "        regionType patch;\n        name outlet;\n        operation sum;\n        fields (phi);\n    }\n";
      u_file += boundaryField({{"inlet", "        type pressureInletOutletVelocity;\n        value uniform (0 0 0);\n"},
                               {"outlet", "        type pressureInletOutletVelocity;\n        value uniform (0 0 0);\n"},
                               {"walls", "        type symmetry;\n"}, {"grains", kNoSlip}, {"back", kEmpty}, {"front", kEmpty}});
      p_file += boundaryField({{"inlet", fmt::format("        type fixedValue;\n        value uniform {:.12g};\n", s.pressure_drop)},
                               {"outlet", "        type fixedValue;\n        value uniform 0;\n"},
                               {"walls", "        type symmetry;\n"}, {"grains", kZeroGradient}, {"back", kEmpty}, {"front", kEmpty}});
      if (!s.direct_mesh) {
        const ImageBackground bg = imageBackground(s, g.fluid.cols, g.fluid.rows, g.width());
        mesh = channelMesh(g.width(), g.height(), bg.cell, bg.nx, bg.ny, "symmetry");
        splitFrontAndBack(mesh);
      }
      break;
    }
    case Scene::Kind::channel: {
      const int ny = std::max(4, s.cells_around);
      const int nx = std::max(4, static_cast<int>(std::lround(ny * s.length / s.height / 4)));
      mesh = channelMesh(s.length, s.height, s.depth, nx, ny);
      functions += "    flowRate\n    {\n        type surfaceFieldValue;\n        libs (\"libfieldFunctionObjects.so\");\n"
                   "        writeControl timeStep;\n        writeInterval 1;\n        log false;\n        writeFields false;\n"
                   "        regionType patch;\n        name outlet;\n        operation sum;\n        fields (phi);\n    }\n";
      u_file += boundaryField({{"inlet", "        type pressureInletOutletVelocity;\n        value uniform (0 0 0);\n"},
                               {"outlet", "        type pressureInletOutletVelocity;\n        value uniform (0 0 0);\n"},
                               {"walls", kNoSlip}, {"frontAndBack", kEmpty}});
      p_file += boundaryField({{"inlet", fmt::format("        type fixedValue;\n        value uniform {:.12g};\n", s.pressure_drop)},
                               {"outlet", "        type fixedValue;\n        value uniform 0;\n"},
                               {"walls", kZeroGradient}, {"frontAndBack", kEmpty}});
      break;
    }
  }
  if (direct_cells < 0) put(dir / "system" / "blockMeshDict", mesh.text());
  put(dir / "system" / "controlDict", controlDict(s, s.unsteady ? "pimpleFoam" : "simpleFoam", functions));
  put(dir / "system" / "fvSchemes", fvSchemes(s));
  put(dir / "system" / "fvSolution", fvSolution(s, reference_pressure));
  put(dir / "system" / "decomposeParDict", decomposeParDict(std::max(1, ranks), s.kind == Scene::Kind::periodic_array));
  put(dir / "constant" / "transportProperties", transportProperties(s));
  put(dir / "constant" / "turbulenceProperties", turbulenceProperties());
  put(dir / "0" / "U", u_file);
  put(dir / "0" / "p", p_file);
  if (perturbedStart(s)) put(dir / "system" / "setExprFieldsDict", setExprFieldsDict(s));
  if (hele_shaw) {
    put(dir / "system" / "topoSetDict", topoSetDict());
    put(dir / "constant" / "fvOptions", heleShawFvOptions(s));
  }
  // Allrun repeats the runner's steps (runWrittenCase): mesh, topoSet (depth-averaged model), checkMesh, solve, and for a
  // parallel run the latest time reconstructed so that case.foam opens it whole in ParaView.
  put(dir / "Allrun",
      fmt::format("#!/bin/sh\n# Reruns this case by hand (written by mmval); ./Allclean undoes it.\ncd \"$(dirname \"$0\")\"\n"
                  "export WM_PROJECT_DIR=${{WM_PROJECT_DIR:-/usr/share/openfoam}}\n"
                  "{}{}"
                  "{}checkMesh > log.checkMesh 2>&1 || exit 1\n{}{}",
                  direct_cells >= 0 ? "# constant/polyMesh was written by mmval's own mesher (directImageMesh)\n" : "blockMesh > log.blockMesh 2>&1 || exit 1\n",
                  s.kind == Scene::Kind::image && direct_cells < 0 ? std::string("snappyHexMesh -overwrite > log.snappyHexMesh 2>&1 || exit 1\n") +
                                                     (s.surface_level > 0 ? "extrudeMesh > log.extrudeMesh 2>&1 || exit 1\n" : "")
                                               : std::string(),
                  hele_shaw ? "# the cellZone of every cell that the depth-averaged friction (constant/fvOptions) acts on\n"
                              "topoSet > log.topoSet 2>&1 || exit 1\n"
                            : "",
                  perturbedStart(s) ? "setExprFields > log.setExprFields 2>&1 || exit 1\n" : "",
                  ranks > 1 ? fmt::format("decomposePar -force > log.decomposePar 2>&1 || exit 1\n"
                                          "mpirun --allow-run-as-root -np {} {} -parallel > log.solver 2>&1 || exit 1\n"
                                          "reconstructPar -latestTime > log.reconstructPar 2>&1 || exit 1\n",
                                          ranks, s.unsteady ? "pimpleFoam" : "simpleFoam")
                            : fmt::format("{} > log.solver 2>&1\n", s.unsteady ? "pimpleFoam" : "simpleFoam")));
  // Allclean removes what Allrun and the solver wrote (meshes, time folders other than 0,
  // processor folders, logs, postProcessing); the files mmval wrote stay.
  put(dir / "Allclean",
      std::string("#!/bin/sh\n# Removes what ./Allrun wrote, back to the case as mmval wrote it.\ncd \"$(dirname \"$0\")\"\n") +
          (direct_cells >= 0 ? "rm -rf postProcessing processor[0-9]* log.*\n" : "rm -rf constant/polyMesh postProcessing processor[0-9]* log.*\n") +
      "for d in [0-9]*; do\n  [ -d \"$d\" ] && [ \"$d\" != 0 ] && rm -rf \"$d\"\ndone\nexit 0\n");
  put(dir / "case.foam", "");  // ParaView's OpenFOAM reader opens the case through this (empty) file
  for (const char* script : {"Allrun", "Allclean"})
    fs::permissions(dir / script, fs::perms::owner_exec | fs::perms::group_exec | fs::perms::others_exec, fs::perm_options::add);
  return direct_cells >= 0 ? direct_cells : mesh.cellCount();
}

std::string fatalMessage(const std::string& log) {
  const auto pos = log.find("FOAM FATAL");
  if (pos != std::string::npos) {
    std::string block = log.substr(pos, 1200);
    const auto end = block.find("\n\n\n");
    if (end != std::string::npos) block.resize(end);
    return block;
  }
  // Last few lines.
  std::vector<std::string> lines;
  std::istringstream in(log);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  std::string out;
  for (std::size_t i = lines.size() > 8 ? lines.size() - 8 : 0; i < lines.size(); ++i) out += lines[i] + "\n";
  return out;
}

SimpleConvergence simpleConvergence(const std::string& log, double target) {
  SimpleConvergence c;
  // "smoothSolver:  Solving for Ux, Initial residual = 0.0123, Final residual = 0.000456, No Iterations 2"
  static const std::regex solving_re("Solving for ([A-Za-z0-9_]+), Initial residual = ([-+0-9.eE]+|nan|-?inf)");
  std::map<std::string, double> current;
  std::istringstream in(log);
  for (std::string line; std::getline(in, line);) {
    if (line.rfind("Time = ", 0) == 0) {  // a new iteration; keep the last complete one's residuals
      if (!current.empty()) c.residuals = current;
      current.clear();
      ++c.iterations;
      continue;
    }
    if (line.find("SIMPLE solution converged") != std::string::npos) c.converged = true;
    std::smatch m;
    if (std::regex_search(line, m, solving_re) && !current.count(m[1])) {
      const std::string v = m[2];
      current[m[1]] = v == "nan" ? std::nan("") : v.find("inf") != std::string::npos ? std::numeric_limits<double>::infinity() : std::stod(v);
    }
  }
  if (!current.empty()) c.residuals = current;
  if (!c.converged && !c.residuals.empty()) {
    c.converged = true;
    for (const auto& [field, r] : c.residuals) c.converged = c.converged && r <= target;  // NaN: not converged
  }
  return c;
}

std::string residualText(const std::map<std::string, double>& residuals) {
  std::string out;
  for (const auto& [field, r] : residuals) out += fmt::format("{}{} {:.3g}", out.empty() ? "" : ", ", field, r);
  return out.empty() ? std::string("no residuals in the log") : out;
}

std::vector<Coefficients> readCoefficients(const fs::path& file) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error("OpenFOAM peer: no force coefficients at " + file.string());
  std::vector<Coefficients> out;
  // Columns named in the last comment line: "# Time Cd Cs Cl CmRoll CmPitch CmYaw Cd(f) Cd(r) ..."
  int col_cd = 1, col_cl = 3;
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    if (line[0] == '#') {
      std::istringstream h(line.substr(1));
      std::vector<std::string> names;
      for (std::string w; h >> w;) names.push_back(w);
      for (std::size_t i = 0; i < names.size(); ++i) {
        if (names[i] == "Cd") col_cd = static_cast<int>(i);
        if (names[i] == "Cl") col_cl = static_cast<int>(i);
      }
      continue;
    }
    std::istringstream row(line);
    std::vector<double> v;
    for (double x; row >> x;) v.push_back(x);
    if (static_cast<int>(v.size()) > std::max(col_cd, col_cl)) out.push_back({v[0], v[col_cd], v[col_cl]});
  }
  return out;
}

void addSheddingStatistics(const Scene& s, const std::vector<Coefficients>& history, Result& r) {
  // mmval's own statistics (simulate::ForceHistory::analyse): the last (up to 4) whole c_L periods
  // after statistics_from, time means by the trapezoidal rule (the adjustable time step spaces the
  // samples unevenly), St = f D / U_ref.
  simulate::ForceHistory forces;
  for (const auto& c : history) forces.add(c.time, c.cd, c.cl);
  const simulate::SheddingStats st = forces.analyse(s.statistics_from >= 0 ? s.statistics_from : 0.5 * s.end_time, 4);
  r.c_d_max = st.cd_max;
  r.c_d_mean = st.cd_mean;
  r.c_l_max = st.cl_max;
  r.shedding_periods = st.periods;
  r.strouhal.reset();
  if (st.periods > 0) r.strouhal = st.frequency_hz * s.diameter / s.u_ref;
}

namespace {

std::string readText(const fs::path& file) {
  std::ifstream in(file);
  std::stringstream b;
  b << in.rdbuf();
  return b.str();
}

std::string shellQuote(const std::string& s) {
  std::string out = "'";
  for (char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}

StepTiming runStep(const fs::path& dir, const std::string& command, const std::string& log) {
  const Installation inst = detect();
  const std::string env = fmt::format(
      "WM_PROJECT_DIR={} GLIBC_TUNABLES=glibc.malloc.mmap_threshold=4294967295:glibc.malloc.trim_threshold=4294967295",
      shellQuote(inst.project_dir.string()));
  const std::string line = fmt::format("cd {} && env {} {} > {} 2>&1", shellQuote(dir.string()), env, command, log);
  const auto t0 = std::chrono::steady_clock::now();
  const int status = std::system(line.c_str());
  StepTiming t;
  t.command = command;
  t.wall_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128;
  return t;
}

std::optional<double> lastPressureGradient(const std::string& log) {
  // meanVelocityForce reports "Pressure gradient source: uncorrected Ubar = U, pressure gradient = G".
  static const std::regex re("pressure gradient = ([-+0-9.eE]+)");
  std::optional<double> g;
  for (auto it = std::sregex_iterator(log.begin(), log.end(), re); it != std::sregex_iterator(); ++it) g = std::stod((*it)[1]);
  return g;
}

int lastIteration(const std::string& log) {
  static const std::regex re("\\nTime = ([0-9.eE+-]+)");
  int n = 0;
  for (auto it = std::sregex_iterator(log.begin(), log.end(), re); it != std::sregex_iterator(); ++it) ++n;
  return n;
}

/// Column `col` of every data row of a function object's .dat file.
std::vector<double> column(const fs::path& file, std::size_t col) {
  std::ifstream in(file);
  std::vector<double> out;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream row(line);
    std::vector<double> cur;
    for (double x; row >> x;) cur.push_back(x);
    if (cur.size() > col) out.push_back(cur[col]);
  }
  return out;
}

std::vector<double> lastRow(const fs::path& file) {
  std::ifstream in(file);
  std::vector<double> v;
  for (std::string line; std::getline(in, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream row(line);
    std::vector<double> cur;
    for (double x; row >> x;) cur.push_back(x);
    if (!cur.empty()) v = cur;
  }
  return v;
}

}  // namespace

std::optional<double> fluxChange(const std::vector<double>& history) {
  const std::size_t n = history.size();
  if (n < 2 || history.back() == 0.0) return std::nullopt;
  const double q = std::abs(history.back());
  if (n >= 3) {
    const double d = std::abs(history[n - 1] - history[n - 2]), d_before = std::abs(history[n - 2] - history[n - 3]);
    if (d == 0.0) return 0.0;
    const double r = d_before > 0 ? d / d_before : 1.0;
    if (r < 1) return d * r / (1 - r) / q;
  }
  const std::size_t back = std::min<std::size_t>(kFluxChangeIterations, n - 1);
  return std::abs(history.back() - history[n - 1 - back]) / q;
}

std::optional<double> executionTime(const std::string& solver_log) {
  static const std::string key = "\nExecutionTime = ";
  const std::size_t at = solver_log.rfind(key);
  if (at == std::string::npos) return std::nullopt;
  const char* begin = solver_log.c_str() + at + key.size();
  char* end = nullptr;
  const double v = std::strtod(begin, &end);
  if (end == begin) return std::nullopt;
  return v;
}

Result runCase(const Scene& s, const fs::path& dir, int ranks) {
  const Installation inst = detect();
  if (!inst.available) {
    Result r;
    r.failure = inst.reason;
    return r;
  }
  MesherReport mesher;
  writeCase(s, dir, ranks, &mesher);
  Result r = runWrittenCase(s, dir, ranks);
  if (mesher.direct) {
    r.mesher = mesher;
    r.mesh_seconds += mesher.seconds;
    r.steps.insert(r.steps.begin(), StepTiming{"mmval directImageMesh", mesher.seconds, 0});
  }
  return r;
}

Result runWrittenCase(const Scene& s, const fs::path& dir, int ranks) {
  Result r;
  r.ranks = std::max(1, ranks);
  const Installation inst = detect();
  if (!inst.available) {
    r.failure = inst.reason;
    return r;
  }
  const std::string solver = s.unsteady ? "pimpleFoam" : "simpleFoam";
  auto step = [&](const std::string& cmd, const std::string& log) {
    StepTiming t = runStep(dir, cmd, log);
    r.steps.push_back(t);
    if (t.exit_code != 0) r.failure = fmt::format("{} failed (exit {}): {}", cmd, t.exit_code, fatalMessage(readText(dir / log)));
    return t.exit_code == 0;
  };
  const bool direct = s.kind == Scene::Kind::image && s.direct_mesh;
  if (direct) {
    if (!fs::exists(dir / "constant" / "polyMesh" / "faces")) {
      r.failure = "no mesh in " + (dir / "constant" / "polyMesh").string() + " (the direct mesher writes it with the case: writeCase)";
      return r;
    }
  } else {
    if (!step("blockMesh", "log.blockMesh")) return r;
    r.mesh_seconds = r.steps.back().wall_seconds;
  }
  if (s.kind == Scene::Kind::image && !direct) {
    if (!step("snappyHexMesh -overwrite", "log.snappyHexMesh")) return r;
    r.snappy_seconds = r.steps.back().wall_seconds;
    r.mesh_seconds += r.snappy_seconds;
    if (s.surface_level > 0) {
      if (!step("extrudeMesh", "log.extrudeMesh")) return r;
      r.mesh_seconds += r.steps.back().wall_seconds;
    }
  }
  if (s.hele_shaw_depth > 0) {
    if (!step("topoSet", "log.topoSet")) return r;
    r.mesh_seconds += r.steps.back().wall_seconds;
  }
  if (!step("checkMesh", "log.checkMesh")) return r;
  const std::string check = readText(dir / "log.checkMesh");
  if (check.find("Failed") != std::string::npos && check.find("mesh checks") != std::string::npos) {
    r.failure = "checkMesh reports errors: " + fatalMessage(check.substr(check.find("Failed") > 600 ? check.find("Failed") - 600 : 0));
    return r;
  }
  r.mesh_seconds += r.steps.back().wall_seconds;
  if (perturbedStart(s) && !step("setExprFields", "log.setExprFields")) return r;
  {
    static const std::regex cells_re("cells: +([0-9]+)");
    std::smatch m;
    if (std::regex_search(check, m, cells_re)) r.cells = std::stoll(m[1]);
    static const std::regex ortho_re("non-orthogonality Max: ([-+0-9.eE]+)"), skew_re("Max skewness = ([-+0-9.eE]+)");
    r.max_non_orthogonality = std::regex_search(check, m, ortho_re) ? std::stod(m[1]) : std::nan("");
    r.max_skewness = std::regex_search(check, m, skew_re) ? std::stod(m[1]) : std::nan("");
  }
  if (r.ranks > 1) {
    if (!step("decomposePar -force", "log.decomposePar")) return r;
    const std::string root = geteuid() == 0 ? "--allow-run-as-root " : "";
    if (!step(fmt::format("mpirun {}-np {} {} -parallel", root, r.ranks, solver), "log.solver")) return r;
  } else if (!step(solver, "log.solver")) {
    return r;
  }
  r.solve_seconds = r.steps.back().wall_seconds;
  const std::string log = readText(dir / "log.solver");
  r.iterations = lastIteration(log);
  r.cpu_seconds = executionTime(log);
  if (!s.unsteady) {
    const SimpleConvergence conv = simpleConvergence(log, s.residual);
    r.converged = conv.converged;
    r.residuals = conv.residuals;
  }

  switch (s.kind) {
    case Scene::Kind::cylinder_channel: {
      const auto hist = readCoefficients(dir / "postProcessing" / "forceCoeffs1" / "0" / "coefficient.dat");
      if (hist.empty()) {
        r.failure = "no force coefficients written";
        return r;
      }
      r.c_d = hist.back().cd;
      r.c_l = hist.back().cl;
      if (s.unsteady) addSheddingStatistics(s, hist, r);
      if (s.pressure_probes.size() >= 2) {
        const auto row = lastRow(dir / "postProcessing" / "probes1" / "0" / "p");
        if (row.size() >= 3) r.dp = (row[1] - row[2]) * s.rho;
      }
      break;
    }
    case Scene::Kind::periodic_array: {
      const auto g = lastPressureGradient(log);
      if (!g) {
        r.failure = "meanVelocityForce reported no pressure gradient in log.solver";
        return r;
      }
      // The body force f stands for the mean pressure gradient G. Sangani & Acrivos' drag per
      // cylinder includes the force of the linear pressure part on the cylinder itself, so
      // F = G L^2 per unit length (not G times the fluid area, which is what a `forces`
      // function object on the periodic pressure would report). With the superficial
      // velocity U_d from the flux through the left face, F* = F / (mu U_d) = f L^2 / (nu U_d).
      const auto flux = lastRow(dir / "postProcessing" / "fluxLeft" / "0" / "surfaceFieldValue.dat");
      if (flux.size() < 2 || flux[1] == 0.0) {
        r.failure = "no flux through the periodic face was written";
        return r;
      }
      const double u_darcy = std::abs(flux[1]) / (s.cell * s.depth);
      r.f_star = *g * s.cell * s.cell / (s.nu * u_darcy);
      r.permeability = s.cell * s.cell / *r.f_star;
      r.drag_per_length = *r.f_star * s.rho * s.nu * u_darcy;
      break;
    }
    case Scene::Kind::channel: {
      const auto row = lastRow(dir / "postProcessing" / "flowRate" / "0" / "surfaceFieldValue.dat");
      if (row.size() >= 2) r.flow_rate = row[1] / s.depth;  // per unit depth
      if (!s.unsteady) r.flux_change = fluxChange(column(dir / "postProcessing" / "flowRate" / "0" / "surfaceFieldValue.dat", 1));
      break;
    }
    case Scene::Kind::image: {
      const MaskGeometry g = loadMask(s.mask, s.pixel, s.grain_dark);
      r.porosity_total = g.porosity_total;
      r.porosity_connected = g.porosity_connected;
      const auto row = lastRow(dir / "postProcessing" / "flowRate" / "0" / "surfaceFieldValue.dat");
      if (row.size() < 2) {
        r.failure = "no outlet flux written";
        return r;
      }
      const double cell = imageMeshThickness(s, g.fluid.cols, g.fluid.rows, g.width());
      static const std::regex vol_re("Total volume = ([-+0-9.eE]+)");
      std::smatch m;
      if (std::regex_search(check, m, vol_re)) r.porosity_mesh = std::stod(m[1]) / (g.width() * g.height() * cell);
      r.porosity_boundary = s.smooth_boundary ? smoothPoreFraction(g, s.smoothing_px) : g.porosity_connected;
      // Darcy: k = mu U_d L / dp with U_d = Q / (H * thickness) and kinematic p.
      const double u_darcy = std::abs(row[1]) / (g.height() * cell);
      r.flow_rate = std::abs(row[1]) / cell;
      r.flux_change = fluxChange(column(dir / "postProcessing" / "flowRate" / "0" / "surfaceFieldValue.dat", 1));
      r.permeability = s.nu * u_darcy * g.width() / s.pressure_drop;
      break;
    }
  }
  r.ok = true;
  return r;
}

}  // namespace mmval::openfoam
