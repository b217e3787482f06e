// Maps and deposit measures of 3D terrain runs (issue 33, part 3; docs/mpm_terrain.md, "Maps").
// CPU twin, CI-sized scenes on a flat raster georeferenced at UTM-sized coordinates.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <granflow/io/raster.hpp>
#include <granflow/mpm/checkpoint.hpp>
#include <granflow/mpm/driver.hpp>
#include <granflow/mpm/kernels.hpp>
#include <granflow/mpm/maps.hpp>
#include <granflow/mpm/scene_file.hpp>

#include "tiny_column.hpp"

using namespace granflow;
using namespace granflow::mpm;
namespace fs = std::filesystem;

namespace {

constexpr double kE0 = 500000.0, kN0 = 4000000.0, kZ0 = 100.0;  // terrain.origin
const std::string kCrs = "PROJCS[\"granflow test, metres\",UNIT[\"metre\",1]]";

struct Scratch {
  fs::path dir;
  explicit Scratch(const std::string& name)
      : dir(fs::temp_directory_path() / ("granflow_maps_" + name + "_" + std::to_string(::getpid()))) {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  ~Scratch() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

std::string read_text(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// A level raster at elevation kZ0 (scene y = 0): 8 x 8 cells of 4 cm from 4 cm west and south of
// the grid's corner, so the 20 cm footprint covers columns and rows 1 to 5 (counted from the
// west and from the south).
std::shared_ptr<const io::Raster> flat_raster() {
  auto r = std::make_shared<io::Raster>();
  r->file = "flat.asc";
  r->ncols = r->nrows = 8;
  r->west = kE0 - 0.04;
  r->south = kN0 - 0.04;
  r->cellsize = 0.04;
  r->values.assign(64, kZ0);
  r->crs = kCrs;
  return r;
}

// A frictional box [x0, x1] x [0, height] x [z0, z1] on the raster, one stage.
Scene block_scene(double x0, double x1, double z0, double z1, double height, double duration, double damping) {
  Scene sc = test::tiny_column(ModelKind::Frictional);
  sc.material = flume_scene(0.04, 1e-4, ModelKind::Frictional, ShapeKind::Linear, 0.1).material;
  sc.dim = 3;
  sc.origin = {0.0, -0.04, 0.0};  // the ground (y = 0) on a node row
  sc.size = {0.2, 0.24, 0.2};
  sc.h = 0.02;
  sc.gravity = {0.0, -9.81, 0.0};
  test::one_open_stage(sc, "run", duration, damping);
  sc.output.series_dt = 0.01;
  Body b;
  b.box_min = {x0, 0.0, z0};
  b.box_max = {x1, height, z1};
  sc.bodies = {b};
  Terrain t;
  t.raster = flat_raster();
  t.file = t.raster->file;
  t.origin = {kE0, kN0, kZ0};
  sc.terrain = t;
  return sc;
}

RunSummary run_to(const SceneSetup& su, const fs::path& out, double stop_after = -1, const Checkpoint* resume = nullptr) {
  auto r = make_cpu_runner(su);
  RunOptions opt;
  opt.out_dir = out.string();
  opt.progress = false;
  opt.checkpoint_dt = 0.02;
  opt.stop_after = stop_after;
  opt.resume = resume;
  return run(su, *r, opt);
}

// deposit.csv's rows (t, t_flow, area, volume, extent, points_below_ground, max_depth_below_ground)
// after its header.
std::vector<std::vector<double>> deposit_rows(const fs::path& out) {
  std::istringstream in(read_text(out / "deposit.csv"));
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "t,t_flow,area,volume,extent,points_below_ground,max_depth_below_ground");
  std::vector<std::vector<double>> rows;
  while (std::getline(in, line)) {
    std::vector<double> row;
    std::istringstream ls(line);
    for (std::string cell; std::getline(ls, cell, ',');) row.push_back(std::stod(cell));
    EXPECT_EQ(row.size(), 7u) << line;
    rows.push_back(row);
  }
  return rows;
}

}  // namespace

// A block at rest on the flat raster, its sides on cell edges (columns and rows 2 and 3 from the
// west and south): the thickness map holds its height on the four cells it covers and 0 on the
// rest of the footprint; the map holds the footprint's cells only (columns and rows 1 to 5 of the
// raster: its corner is the grid's) and reads back through the raster reader with the terrain's
// cell size and coordinate system; deposit.csv gives the block's volume, area and
// extent along x (within 5 % of a spacing: its free edges bulge by 0.3 mm under the K0 stress).
TEST(TerrainMaps, BlockAtRestGivesItsHeightAndVolume) {
  const double H = 0.06;
  Scene sc = block_scene(0.04, 0.12, 0.04, 0.12, H, 0.02, 0.5);
  sc.initial.geostatic = true;
  const SceneSetup su = make_setup(sc);
  ASSERT_DOUBLE_EQ(su.spacing, 0.01);
  Scratch s("rest");
  const RunSummary res = run_to(su, s.dir);
  ASSERT_TRUE(res.ok) << res.message;

  const io::Raster m = io::read_esri_ascii((s.dir / "maps" / "deposit_thickness.asc").string());
  const io::Raster& ground = *sc.terrain->raster;
  EXPECT_EQ(m.ncols, 5);
  EXPECT_EQ(m.nrows, 5);
  EXPECT_NEAR(m.west, kE0 + sc.origin[0], 1e-9);  // the grid's corner, a raster cell edge
  EXPECT_NEAR(m.south, kN0 + sc.origin[2], 1e-9);
  EXPECT_DOUBLE_EQ(m.cellsize, ground.cellsize);
  EXPECT_NE(m.crs.find(kCrs), std::string::npos) << m.crs;  // the .prj beside it
  for (long row = 0; row < m.nrows; ++row)
    for (long col = 0; col < m.ncols; ++col) {
      const long k = m.nrows - 1 - row;  // from the south
      const bool covered = (col == 1 || col == 2) && (k == 1 || k == 2);
      const double v = m.at(row, col);
      if (covered)
        EXPECT_NEAR(v, H, 1e-9) << "row " << row << ", col " << col;
      else
        EXPECT_EQ(v, 0.0) << "row " << row << ", col " << col;
    }
  const io::Raster terrain = io::read_esri_ascii((s.dir / "maps" / "terrain.asc").string());
  ASSERT_EQ(terrain.values.size(), 25u);
  for (double z : terrain.values) EXPECT_EQ(z, kZ0);
  if (io::raster_gdal_available()) {  // the GeoTIFF holds the same cells
    const io::Raster tif = io::read_raster((s.dir / "maps" / "deposit_thickness.tif").string());
    EXPECT_DOUBLE_EQ(tif.west, m.west);
    EXPECT_DOUBLE_EQ(tif.south, m.south);
    for (size_t i = 0; i < m.values.size(); ++i)
      if (std::isnan(m.values[i])) EXPECT_TRUE(std::isnan(tif.values[i])); else EXPECT_NEAR(tif.values[i], m.values[i], 1e-8);
  }

  const auto rows = deposit_rows(s.dir);
  ASSERT_EQ(rows.size(), res.series.size());  // one row per sample
  for (const auto& r : rows) {
    EXPECT_NEAR(r[3], 0.08 * H * 0.08, 1e-10) << "t = " << r[0];  // volume
    EXPECT_NEAR(r[2], 4 * 0.04 * 0.04, 1e-12);                    // area: the four cells
    EXPECT_NEAR(r[4], 0.08, 0.05 * su.spacing);                   // extent along x (its edges bulge)
    EXPECT_EQ(r[5], 0.0);                                         // no point below the ground
  }
  std::printf("block at rest: thickness %.6f m on its cells (height %.3f), volume %.6e m^3, extent %.5f m\n",
              m.at(m.nrows - 1 - 1, 1), H, rows.back()[3], rows.back()[4]);
}

// A column collapsing on the flat raster: the maxima are not below the final values, cell by
// cell (max_depth >= deposit_thickness, the final sample being one of them), the column's cells
// saw its initial height, and a run stopped at a checkpoint and resumed writes the same maps and
// deposit.csv, byte for byte, as the run straight through (the checkpoint carries the maxima).
TEST(TerrainMaps, MaximaAreNotBelowTheFinalValuesAndSurviveARestart) {
  const double H = 0.12;
  const SceneSetup su = make_setup(block_scene(0.08, 0.12, 0.08, 0.12, H, 0.1, 0.0));
  Scratch a("straight"), b("resumed");
  const RunSummary straight = run_to(su, a.dir);
  ASSERT_TRUE(straight.ok);
  const io::Raster dep = io::read_esri_ascii((a.dir / "maps" / "deposit_thickness.asc").string());
  const io::Raster depth = io::read_esri_ascii((a.dir / "maps" / "max_depth.asc").string());
  const io::Raster speed = io::read_esri_ascii((a.dir / "maps" / "max_speed.asc").string());
  double fastest = 0, spread = 0;
  for (size_t i = 0; i < dep.values.size(); ++i) {
    ASSERT_EQ(std::isnan(dep.values[i]), std::isnan(depth.values[i]));
    if (std::isnan(dep.values[i])) continue;
    EXPECT_GE(depth.values[i], dep.values[i]) << "cell " << i;
    if (dep.values[i] > 0) spread += 1;
    fastest = std::max(fastest, speed.values[i]);
  }
  const long row = dep.nrows - 1 - 2, col = 2;  // the column's cell (raster column and row 3; the map starts at 1)
  EXPECT_NEAR(depth.at(row, col), H, 1e-9);
  EXPECT_LT(dep.at(row, col), H - 0.01);  // it collapsed
  EXPECT_GT(spread, 1);
  EXPECT_GT(fastest, 0.1);
  // the fastest cell is the fastest point of any sample (runout.csv's max_speed, from measure())
  double fastest_sample = 0;
  for (const SeriesRow& r : straight.series) fastest_sample = std::max(fastest_sample, r.m.max_speed);
  EXPECT_NEAR(fastest, fastest_sample, 1e-6 * fastest_sample);
  std::printf("collapse: column cell max depth %.4f m, final %.4f m; %g cells covered; fastest %.3f m/s\n",
              depth.at(row, col), dep.at(row, col), spread, fastest);

  ASSERT_TRUE(run_to(su, b.dir, 0.05).ok);
  const Checkpoint c = read_checkpoint((b.dir / kCheckpointFile).string());
  ASSERT_FALSE(c.loop.maps.max_depth.empty());
  fs::remove_all(b.dir / "maps");  // what --restart removes (written after the checkpoint)
  const RunSummary r = run_to(su, b.dir, -1, &c);
  ASSERT_TRUE(r.ok) << r.message;
  for (const char* f : {"maps/deposit_thickness.asc", "maps/max_speed.asc", "maps/max_depth.asc", "deposit.csv"})
    EXPECT_EQ(read_text(b.dir / f), read_text(a.dir / f)) << f;
}

// A raster finer than the point spacing (4 mm cells, 1 cm spacing) stripes the thickness map: a
// cell holds a column of points or none. output.map_cell = 2 cm joins 5 x 5 raster cells per
// map cell: the block's cells read its height, the map's cells are those of the raster's blocks
// over the footprint, and both maps hold the block's whole volume.
TEST(TerrainMaps, MapCellJoinsRasterCellsAndEndsTheStripes) {
  const double H = 0.04;
  auto fine = std::make_shared<io::Raster>(*flat_raster());
  fine->ncols = fine->nrows = 80;
  fine->cellsize = 0.004;
  fine->values.assign(80 * 80, kZ0);
  Scene sc = block_scene(0.04, 0.12, 0.04, 0.12, H, 0.01, 0.5);
  sc.initial.geostatic = true;
  sc.terrain->raster = fine;
  Scene joined = sc;
  joined.output.map_cell = 0.02;
  const SceneSetup su = make_setup(sc), sj = make_setup(joined);
  ASSERT_DOUBLE_EQ(su.spacing, 0.01);
  Scratch a("fine"), b("joined");
  ASSERT_TRUE(run_to(su, a.dir).ok);
  ASSERT_TRUE(run_to(sj, b.dir).ok);
  const io::Raster mf = io::read_esri_ascii((a.dir / "maps" / "deposit_thickness.asc").string());
  const io::Raster mj = io::read_esri_ascii((b.dir / "maps" / "deposit_thickness.asc").string());
  EXPECT_EQ(mf.ncols, 50);  // raster columns 10 to 59 (of 80) under the 20 cm footprint
  EXPECT_EQ(mj.ncols, 10);  // blocks 2 to 11 (of 16)
  EXPECT_EQ(mj.nrows, 10);
  EXPECT_DOUBLE_EQ(mj.cellsize, 0.02);
  EXPECT_NEAR(mj.west, fine->west + 2 * 0.02, 1e-9);
  EXPECT_NEAR(mj.south, fine->south + 2 * 0.02, 1e-9);
  EXPECT_NEAR(mf.west, fine->west + 10 * 0.004, 1e-9);
  auto volume = [](const io::Raster& m) {
    double v = 0;
    for (double t : m.values)
      if (!std::isnan(t)) v += t * m.cellsize * m.cellsize;
    return v;
  };
  EXPECT_NEAR(volume(mf), 0.08 * 0.08 * H, 1e-10);
  EXPECT_NEAR(volume(mj), 0.08 * 0.08 * H, 1e-10);
  // under the block (x, z in [0.04, 0.12] m: raster columns 20 to 39 from the west, 4 mm each; map 10 to 29)
  double lo = 1e9, hi = 0;
  for (long k = 11; k < 29; ++k)
    for (long col = 11; col < 29; ++col) {
      lo = std::min(lo, mf.at(mf.nrows - 1 - k, col));
      hi = std::max(hi, mf.at(mf.nrows - 1 - k, col));
    }
  EXPECT_EQ(lo, 0.0);
  EXPECT_GT(hi, 3 * H);
  for (long k = 2; k < 6; ++k)  // map cells of 2 cm: the block covers blocks 4 to 7 whole (map 2 to 5)
    for (long col = 2; col < 6; ++col) EXPECT_NEAR(mj.at(mj.nrows - 1 - k, col), H, 1e-9) << k << ", " << col;
  const io::Raster terrain = io::read_esri_ascii((b.dir / "maps" / "terrain.asc").string());
  EXPECT_EQ(terrain.cellsize, 0.02);
  EXPECT_EQ(terrain.at(terrain.nrows - 1 - 3, 3), kZ0);
  std::printf("map cells of 4 mm: thickness %.3f to %.3f m under a %.2f m block; of 2 cm: %.6f m\n", lo, hi, H,
              mj.at(mj.nrows - 1 - 3, 3));
}

// A 2D scene over a base gets the maps as a profile along x (deposit_profile.csv, bins of h or
// output.map_cell): the CI-sized column collapsing on a level base. The bins hold the column's
// whole area (thickness times bin width), the column's bins saw its height, max_depth is not
// below the final thickness anywhere, and deposit.csv is per unit width (length, area).
TEST(TerrainMaps, TwoDimensionalRunOverABaseWritesProfiles) {
  for (double bin : {0.0, 0.04}) {
    Scene sc = test::tiny_column(ModelKind::Frictional);
    sc.stages[1].duration = 0.15;
    sc.output.times = {0.15};
    BaseLine b;
    b.x = {sc.origin[0], sc.origin[0] + sc.size[0]};
    b.y = {sc.origin[1], sc.origin[1]};
    sc.base = b;
    sc.output.map_cell = bin;
    const SceneSetup su = make_setup(sc);
    Scratch s(bin > 0 ? "profile_joined" : "profile");
    const RunSummary res = run_to(su, s.dir);
    ASSERT_TRUE(res.ok) << res.message;
    std::istringstream in(read_text(s.dir / "deposit_profile.csv"));
    std::string line;
    std::getline(in, line);
    EXPECT_EQ(line, "x,base_y,deposit_thickness,max_speed,max_depth");
    const double w = bin > 0 ? bin : sc.h;
    double area = 0, column_depth = 0, fastest = 0;
    long rows = 0;
    while (std::getline(in, line)) {
      std::vector<double> r;
      std::istringstream ls(line);
      for (std::string cell; std::getline(ls, cell, ',');) r.push_back(std::stod(cell));
      ASSERT_EQ(r.size(), 5u) << line;
      EXPECT_NEAR(r[0], sc.origin[0] + (rows + 0.5) * w, 1e-12);
      EXPECT_NEAR(r[1], sc.origin[1], 1e-12);
      EXPECT_GE(r[4], r[2]) << line;
      area += r[2] * w;
      if (r[0] < 0.1) column_depth = std::max(column_depth, r[4]);
      fastest = std::max(fastest, r[3]);
      ++rows;
    }
    EXPECT_EQ(rows, std::lround(sc.size[0] / w));
    EXPECT_NEAR(area, 0.2 * 0.1, 1e-12);  // the column's seeded area
    EXPECT_NEAR(column_depth, 0.1, 1e-9);
    EXPECT_GT(fastest, 0.3);
    std::istringstream dep(read_text(s.dir / "deposit.csv"));
    std::getline(dep, line);
    EXPECT_EQ(line, "t,t_flow,length,area,extent");
    std::string last;
    while (std::getline(dep, line)) last = line;
    std::vector<double> r;
    std::istringstream ls(last);
    for (std::string cell; std::getline(ls, cell, ',');) r.push_back(std::stod(cell));
    ASSERT_EQ(r.size(), 5u);
    EXPECT_LE(r[3], 0.02 + 1e-12);  // area per unit width: the bins at least one spacing thick
    EXPECT_GT(r[3], 0.015);
    EXPECT_GT(r[4], 0.22);  // it spread beyond the column's 0.2 m
    std::printf("2D profile, bins %.2f m: final deposit length %.3f m, area %.5f m^2/m, extent %.3f m\n", w, r[2], r[3],
                r[4]);
  }
}

// A DEM far larger than the grid (40 x 30 cells of 3 cm, NODATA but for the cells around the
// footprint, whose edges fall inside cells): the maps hold the 7 x 7 cells that overlap the 20 cm
// footprint (raster columns and rows 10 to 16: (0.305 m + [0, 0.2 m]) / 0.03 m), on the raster's
// own cells, with no NODATA (the terrain map's cells are the raster's cells with values) and the
// block's volume.
TEST(TerrainMaps, MapsAreCroppedToTheFootprintOnTheRastersCells) {
  auto dem = std::make_shared<io::Raster>(*flat_raster());
  dem->ncols = 40;
  dem->nrows = 30;
  dem->cellsize = 0.03;
  dem->west = kE0 - 0.305;
  dem->south = kN0 - 0.305;
  dem->values.assign(40 * 30, std::numeric_limits<double>::quiet_NaN());
  for (long k = 9; k <= 17; ++k)  // from the south; the interpolation reads one cell beyond the footprint's
    for (long c = 9; c <= 17; ++c) dem->values[static_cast<size_t>((29 - k) * 40 + c)] = kZ0;
  const double H = 0.04;
  Scene sc = block_scene(0.04, 0.12, 0.04, 0.12, H, 0.01, 0.5);
  sc.initial.geostatic = true;
  sc.terrain->raster = dem;
  Scratch s("cropped");
  ASSERT_TRUE(run_to(make_setup(sc), s.dir).ok);
  const io::Raster m = io::read_esri_ascii((s.dir / "maps" / "deposit_thickness.asc").string());
  const io::Raster t = io::read_esri_ascii((s.dir / "maps" / "terrain.asc").string());
  for (const io::Raster* r : {&m, &t}) {
    EXPECT_EQ(r->ncols, 7);
    EXPECT_EQ(r->nrows, 7);
    EXPECT_NEAR(r->west, kE0 - 0.305 + 10 * 0.03, 1e-9);
    EXPECT_NEAR(r->south, kN0 - 0.305 + 10 * 0.03, 1e-9);
    EXPECT_EQ(r->cellsize, 0.03);
  }
  double volume = 0;
  for (long row = 0; row < 7; ++row)
    for (long col = 0; col < 7; ++col) {
      ASSERT_FALSE(std::isnan(m.at(row, col)));
      volume += m.at(row, col) * 0.03 * 0.03;
      EXPECT_EQ(t.at(row, col), kZ0) << row << ", " << col;  // no NODATA cell of the raster
    }
  EXPECT_NEAR(volume, 0.08 * 0.08 * H, 1e-10);
}

// Map cells are counted before anything is allocated and must be resolvable in the positions'
// precision: a 2D profile with output.map_cell = 1e-9 m (2e8 bins over the 0.2 m grid) is
// refused naming the key; a 3D terrain with terrain.origin at 0 leaves scene coordinates of
// 4e6 m, where fp32 positions resolve 0.5 m: its 4 cm cells are refused in fp32 (limit 1e-4 x
// 4e6 m = 400 m) naming terrain.file, and taken in fp64 (limit 4e-4 m).
TEST(TerrainMaps, MapCellsAreCountedAndResolvedBeforeTheRun) {
  auto refusal = [](const Scene& sc, std::string& key) {
    try {
      make_setup(sc);
    } catch (const SceneError& e) {
      key = e.key();
      return std::string(e.what());
    }
    return std::string();
  };
  Scene flat = test::tiny_column(ModelKind::Frictional);
  BaseLine b;
  b.x = {flat.origin[0], flat.origin[0] + flat.size[0]};
  b.y = {flat.origin[1], flat.origin[1]};
  flat.base = b;
  flat.output.map_cell = 1e-9;
  std::string key;
  std::string msg = refusal(flat, key);
  EXPECT_EQ(key, "output.map_cell");
  EXPECT_NE(msg.find("map cells of 1e-09 m give " + [&] {
              std::ostringstream os;
              os << std::ceil(flat.size[0] / 1e-9);
              return os.str();
            }() + " cells"), std::string::npos) << msg;
  EXPECT_NE(msg.find("at most 10000000 are allowed"), std::string::npos) << msg;

  Scene far = block_scene(0.04, 0.12, 0.04, 0.12, 0.04, 0.01, 0.5);
  far.terrain->origin = {0.0, 0.0, kZ0};  // scene x, z = easting, northing
  far.origin[0] += kE0;
  far.origin[2] += kN0;
  far.bodies[0].box_min[0] += kE0;
  far.bodies[0].box_max[0] += kE0;
  far.bodies[0].box_min[2] += kN0;
  far.bodies[0].box_max[2] += kN0;
  far.precision = Precision::FP32;
  msg = refusal(far, key);
  EXPECT_EQ(key, "terrain.file");
  EXPECT_NE(msg.find("map cells of 0.04 m (terrain.file; output.map_cell sets them) at scene coordinates up to "
                     "4e+06 m: fp32 positions resolve 0.48 m there"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find("at least 0.0001 x the largest |x| or |z| of the grid (400 m"), std::string::npos) << msg;
  far.precision = Precision::FP64;
  EXPECT_EQ(refusal(far, key), "");
}

// Without terrain nothing is measured or written; a checkpoint's maps must fit the footprint.
TEST(TerrainMaps, OnlyTerrainRunsHaveMaps) {
  const SceneSetup plain = make_setup(test::tiny_column(ModelKind::Frictional));
  EXPECT_FALSE(TerrainMaps(plain).active());
  const SceneSetup su = make_setup(block_scene(0.04, 0.12, 0.04, 0.12, 0.04, 0.01, 0.5));
  TerrainMaps m(su);
  ASSERT_TRUE(m.active());
  EXPECT_EQ(m.state().max_depth.size(), 25u);  // 5 x 5 cells
  MapsState wrong;
  wrong.max_speed.assign(3, 0.0);
  wrong.max_depth.assign(3, 0.0);
  EXPECT_THROW(m.restore(wrong), std::runtime_error);
}

// output.fields: a frame carries position and the listed arrays only; none listed, all of them.
TEST(MpmOutputFields, FramesCarryTheListedArraysOnly) {
  Frame f;
  f.n = 2;
  f.dim = 2;
  f.x = {0, 1, 0, 1};
  f.v = {0, 0, 0, 0};
  for (auto* a : {&f.T, &f.p, &f.q, &f.eps_pd, &f.eta_c, &f.K_col, &f.e, &f.sxx, &f.syy, &f.sxy}) a->assign(2, 1.0);
  f.material = {0, 1};
  f.body = {0, 1};
  Scratch s("fields");
  fs::create_directories(s.dir);
  const fs::path all = s.dir / "all.vtu", some = s.dir / "some.vtu";
  for (const FrameFormat format : {FrameFormat::Raw, FrameFormat::Base64, FrameFormat::Ascii}) {
    SCOPED_TRACE(static_cast<int>(format));
    write_vtu(all.string(), f, format);
    write_vtu(some.string(), f, format, {"p", "e"});
    const std::string a = read_text(all), b = read_text(some);
    for (const std::string& name : frame_field_names()) {
      EXPECT_NE(a.find("Name=\"" + name + "\""), std::string::npos) << name;
      EXPECT_EQ(b.find("Name=\"" + name + "\"") != std::string::npos, name == "p" || name == "e") << name;
    }
    EXPECT_NE(b.find("Name=\"position\""), std::string::npos);
  }
}

// The deposit's edge about a centre on a synthetic map (issue 53): a thickness T0 (1 - r / R) on a
// lattice of cells crosses one spacing s at R (1 - s / T0) exactly, wherever the centre lies
// against the cells (on a corner, inside a cell, a quarter map from its corner); 0 when the map
// is thin at the centre, NaN when it never thins within the map.
TEST(TerrainMaps, DepositEdgeOfAConeIsWhereItsThicknessCrossesOneSpacing) {
  const double w = 0.01, T0 = 0.1, R = 0.3, s = 0.025;
  const double expected = R * (1 - s / T0);
  struct Case {
    double x0, z0, lo;  // centre, and the map's lower corner in both directions
  };
  for (const Case c : {Case{0.5, 0.5, 0.0}, Case{0.503, 0.4971, 0.0}, Case{0.0, 0.0, 0.0}, Case{0.013, -0.002, 0.0}}) {
    std::vector<double> cx, cz, th, thin, thick;
    for (int i = 0; i < 100; ++i)
      for (int j = 0; j < 100; ++j) {
        cx.push_back(c.lo + (i + 0.5) * w);
        cz.push_back(c.lo + (j + 0.5) * w);
        const double r = std::hypot(cx.back() - c.x0, cz.back() - c.z0);
        th.push_back(std::max(0.0, T0 * (1 - r / R)));
        thin.push_back(0.5 * s);
        thick.push_back(2 * s);
      }
    const DepositEdges e = deposit_edges(cx, cz, th, c.x0, c.z0, w, s);
    for (double edge : {e.all, e.axes, e.diagonals}) EXPECT_NEAR(edge, expected, 1e-12) << c.x0 << " " << c.z0;
    EXPECT_EQ(deposit_edges(cx, cz, thin, c.x0, c.z0, w, s).all, 0.0);
    EXPECT_TRUE(std::isnan(deposit_edges(cx, cz, thick, c.x0, c.z0, w, s).all));
  }
}

// The sectors read the grid's anisotropy: a cone whose radius is R along the axes and 0.8 R along
// the diagonals (R cos^2 2phi + 0.8 R sin^2 2phi, the angle phi about the centre) gives the two
// apart, with the all-direction edge between them.
TEST(TerrainMaps, DepositEdgeSectorsSeparateTheAxesFromTheDiagonals) {
  const double w = 0.005, T0 = 0.1, R = 0.3, s = 0.01;
  std::vector<double> cx, cz, th;
  for (int i = 0; i < 100; ++i)
    for (int j = 0; j < 100; ++j) {
      cx.push_back((i + 0.5) * w);
      cz.push_back((j + 0.5) * w);
      const double phi = std::atan2(cz.back(), cx.back()), c2 = std::cos(2 * phi);
      const double reach = R * (c2 * c2 + 0.8 * (1 - c2 * c2));
      th.push_back(std::max(0.0, T0 * (1 - std::hypot(cx.back(), cz.back()) / reach)));
    }
  const DepositEdges e = deposit_edges(cx, cz, th, 0, 0, w, s);
  const double axes = e.axes, diag = e.diagonals, all = e.all;
  EXPECT_GT(axes, 0.96 * 0.9 * R);  // within 15 deg of an axis the reach is at least 0.95 R
  EXPECT_LT(diag, 0.86 * 0.9 * R);  // within 15 deg of a diagonal at most 0.85 R
  EXPECT_LT(diag, all);
  EXPECT_LT(all, axes);
}

// The CI-sized axisymmetric collapse (mpm/scenes/cylinder_collapse_ci.toml, issue 53): a quarter
// cylinder R0 = H0 = 0.1 m at R0/h = 5 spreads alike along the grid's axes and its diagonals (the
// deposit's edge in the two sectors within 5 %), beyond R0, and the edge over all directions
// lies between the sectors' within a point spacing.
TEST(TerrainMaps, CylinderCollapseCiSpreadsAlikeAlongTheAxesAndTheDiagonals) {
  const Scratch s("cylinder");
  const SceneSetup su = make_setup_for_file(load_scene(GRANFLOW_SOURCE_DIR "/mpm/scenes/cylinder_collapse_ci.toml"));
  const RunSummary r = run_to(su, s.dir);
  ASSERT_TRUE(r.ok) << r.message;
  std::istringstream in(read_text(s.dir / "deposit.csv"));
  std::string line, last;
  std::getline(in, line);
  ASSERT_EQ(line, "t,t_flow,area,volume,extent,points_below_ground,max_depth_below_ground,edge_radius,"
                  "edge_radius_axes,edge_radius_diagonals");
  while (std::getline(in, line)) last = line;
  std::vector<double> row;
  std::istringstream ls(last);
  for (std::string cell; std::getline(ls, cell, ',');) row.push_back(std::stod(cell));
  ASSERT_EQ(row.size(), 10u) << last;
  const double all = row[7], axes = row[8], diag = row[9];
  std::printf("edge at t = %g s: %.4f m (axes %.4f, diagonals %.4f: %+.1f %%)\n", row[0], all, axes, diag,
              100 * (diag / axes - 1));
  EXPECT_GT(all, 1.5 * 0.1);
  EXPECT_NEAR(diag, axes, 0.05 * axes);
  EXPECT_GT(all, std::min(axes, diag) - su.spacing);
  EXPECT_LT(all, std::max(axes, diag) + su.spacing);

  // The edge is read at the scene's output.edge_thickness (0.04 R0), not at one point spacing:
  // the final map (the last sample's time) gives it back, and the spacing's reading lies inward.
  const double thr = su.scene.output.edge_thickness;
  ASSERT_DOUBLE_EQ(thr, 0.004);
  const io::Raster m = io::read_esri_ascii((s.dir / "maps" / "deposit_thickness.asc").string());
  std::vector<double> cx, cz, th;
  for (long row = 0; row < m.nrows; ++row)
    for (long col = 0; col < m.ncols; ++col) {
      cx.push_back(m.centre_east(col) - m.west);  // the grid's plan corner is the raster's
      cz.push_back(m.centre_north(row) - m.south);
      th.push_back(std::max(0.0, m.at(row, col)));
    }
  EXPECT_NEAR(deposit_edges(cx, cz, th, 0, 0, m.cellsize, thr).all, all, 1e-7);
  EXPECT_LT(deposit_edges(cx, cz, th, 0, 0, m.cellsize, su.spacing).all, all - 0.2 * su.spacing);

  // runout.csv's height is above the ground (the scene's [runout] line at y = 0), not above the
  // grid's bottom 2 h below it: at t = 0 the column's top, H0 (the highest points half a
  // spacing below it, plus the measure's half spacing); at the end it has collapsed.
  std::istringstream ro(read_text(s.dir / "runout.csv"));
  std::getline(ro, line);
  ASSERT_EQ(line.rfind("t,t_flow,stage,runout,height,", 0), 0u) << line;
  std::vector<std::vector<double>> rows;
  while (std::getline(ro, line)) {
    std::vector<double> v;
    std::istringstream cs(line);
    for (std::string cell; std::getline(cs, cell, ',');) v.push_back(std::stod(cell));
    rows.push_back(v);
  }
  ASSERT_GE(rows.size(), 2u);
  EXPECT_NEAR(rows.front()[4], 0.1, 1e-9);
  EXPECT_LT(rows.back()[4], 0.8 * 0.1);
  EXPECT_GT(rows.back()[4], 0.3 * 0.1);
}

namespace {

// The CI collapse with a cylindrical gate (stage.gate.radius) of radius R0 about its axis,
// holding the radial component (radial) or all, in its stage; lifted at lift_speed (0: held
// throughout).
Scene gated_cylinder_ci(bool radial, double lift_speed) {
  Scene sc = load_scene(GRANFLOW_SOURCE_DIR "/mpm/scenes/cylinder_collapse_ci.toml");
  Gate g;
  g.point = {0.0, 0.0, 0.0};
  g.radius = 0.1;
  g.normal_only = radial;
  g.lift_speed = lift_speed;
  sc.stages[0].gate = g;
  return sc;
}

}  // namespace

// The cylindrical gate in the grid update: a node at or outside radius R0 of the axis loses its
// radial velocity (hold "normal") or all of it ("all"), keeps the tangential and vertical parts,
// and a node inside is free; lifted, the gate holds only at and above its lower edge
// (y = lift_speed t). Nodes on the ground (y <= 0) are held by the terrain throughout.
TEST(TerrainMaps, CylindricalGateHoldsTheRadialVelocityOutsideItsRadius) {
  using FR = FrictionalModel<double>;
  using G = GridLayout<3>;
  for (const auto& [radial, speed] : {std::pair{true, 0.0}, std::pair{false, 0.0}, std::pair{true, 0.5}}) {
    const SceneSetup su = make_setup_for_file(gated_cylinder_ci(radial, speed));
    ASSERT_TRUE(stage_has_contacts(su, 0));
    StepParams<3, double, FR> sp{};
    sp.grid = test::grid_of<3>(su);
    sp.dt = 1e-4;
    sp.t = 0.12;
    const double edge = speed * sp.t;
    const long nn = su.n_nodes;
    std::vector<double> grid(static_cast<size_t>(G::N) * nn, 0.0);
    const GridView<double> gv{grid.data(), nn, su.stage_masks[0].data()};
    int checked = 0;
    for (long k = 0; k < nn; ++k) {
      int I[3];
      sp.grid.multi(k, I);
      double x[3];
      for (int d = 0; d < 3; ++d) x[d] = su.origin[d] + I[d] * su.scene.h;
      if (x[1] <= 1e-12 || x[0] < 1e-12 || x[2] < 1e-12) continue;  // ground and symmetry walls hold their own
      const double r = std::hypot(x[0], x[2]), cs = x[0] / r, sn = x[2] / r;
      // 1 m/s outward, 0.5 m/s about the axis, 0.25 m/s up
      const double v[3] = {cs - 0.5 * sn, 0.25, sn + 0.5 * cs};
      gv.f(G::M, k) = 1.0;
      for (int d = 0; d < 3; ++d) gv.f(G::P + d, k) = v[d];
      grid_update_node<3, double, FR, true, true>(gv, k, sp);
      const bool held = r >= 0.1 - 1e-12 && x[1] >= edge - 1e-12;
      const double vr = gv.f(G::VNEW, k) * cs + gv.f(G::VNEW + 2, k) * sn;
      const double vt = -gv.f(G::VNEW, k) * sn + gv.f(G::VNEW + 2, k) * cs;
      const double vy = gv.f(G::VNEW + 1, k);
      const double keep = held && !radial ? 0.0 : 1.0;
      EXPECT_NEAR(vr, held ? 0.0 : 1.0, 1e-12) << x[0] << " " << x[1] << " " << x[2];
      EXPECT_NEAR(vt, 0.5 * keep, 1e-12) << x[0] << " " << x[1] << " " << x[2];
      EXPECT_NEAR(vy, 0.25 * keep, 1e-12) << x[0] << " " << x[1] << " " << x[2];
      checked += held;
    }
    EXPECT_GT(checked, 100);
  }
}

// The CI column behind a cylindrical gate of its own radius: held whole it stands (no point
// passes the gate, the top stays at H0, it comes to rest); lifted at 1 m/s it flows out beneath
// the gate and spreads beyond 1.5 R0, as the column released at once does
// (CylinderCollapseCiSpreadsAlike...), but less far by the time of the release.
TEST(TerrainMaps, CylindricalGateHoldsTheColumnAndReleasesItWhenLifted) {
  struct Run {
    double front_max = 0, height_end = 0, speed_end = 0, edge_end = 0;
  };
  auto run = [](double lift_speed, const std::string& name) {
    Scene sc = gated_cylinder_ci(true, lift_speed);
    sc.stages[0].duration = 0.25;
    sc.output.times = {0.25};
    const Scratch s(name);
    const RunSummary r = run_to(make_setup_for_file(sc), s.dir);
    EXPECT_TRUE(r.ok) << r.message;
    Run out;
    std::istringstream ro(read_text(s.dir / "runout.csv")), dep(read_text(s.dir / "deposit.csv"));
    std::string line;
    std::getline(ro, line);
    std::vector<double> v;
    while (std::getline(ro, line)) {
      v.clear();
      std::istringstream cs(line);
      for (std::string cell; std::getline(cs, cell, ',');) v.push_back(std::stod(cell));
      out.front_max = std::max(out.front_max, v[3]);
    }
    out.height_end = v[4];
    out.speed_end = v[5];
    std::getline(dep, line);
    while (std::getline(dep, line)) {
      v.clear();
      std::istringstream cs(line);
      for (std::string cell; std::getline(cs, cell, ',');) v.push_back(std::stod(cell));
    }
    out.edge_end = v[7];
    return out;
  };
  const Run held = run(0.0, "gate_held"), lifted = run(1.0, "gate_lifted");
  std::printf("held: front at most %.4f m, height %.4f m, speed %.2e m/s; lifted at 1 m/s: edge %.4f m, height %.4f m\n",
              held.front_max, held.height_end, held.speed_end, lifted.edge_end, lifted.height_end);
  const double spacing = 0.01;  // 20 mm cells, 2 points per axis
  EXPECT_LE(held.front_max, 0.1 + 0.5 * spacing + 1e-6);  // the outermost points stay inside R0
  EXPECT_NEAR(held.height_end, 0.1, 0.1 * spacing);
  EXPECT_LT(held.speed_end, 0.01);
  EXPECT_GT(lifted.edge_end, 1.5 * 0.1);
  EXPECT_LT(lifted.height_end, 0.8 * 0.1);
}
