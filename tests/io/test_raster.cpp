// Elevation rasters: the ESRI ASCII reader against a hand-written grid (values, NODATA, cell
// centre against corner, bilinear elevation and slope), its errors, and (where the build has
// GDAL) the same raster written as GeoTIFF through GDAL reads the same.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>

#include <granflow/io/input_error.hpp>
#include <granflow/io/raster.hpp>

#ifdef GRANFLOW_WITH_GDAL
#include <cpl_conv.h>
#include <gdal.h>
#include <ogr_srs_api.h>
#endif

using namespace granflow;

namespace {

// A folder of its own in the temporary folder (process id: parallel ctest runs), removed again.
struct TempDir {
  std::filesystem::path dir;
  TempDir() : dir(std::filesystem::temp_directory_path() / ("granflow_raster_" + std::to_string(::getpid()))) {
    std::filesystem::create_directories(dir);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(dir, ec);
  }
  std::string write(const std::string& name, const std::string& text) const {
    const std::string p = (dir / name).string();
    std::ofstream(p) << text;
    return p;
  }
};

// 4 columns x 3 rows, 10 m cells, lower-left corner at (1000, 2000); row 0 is the north row.
const char* kGrid =
    "ncols 4\n"
    "nrows 3\n"
    "xllcorner 1000\n"
    "yllcorner 2000\n"
    "cellsize 10\n"
    "NODATA_value -9999\n"
    "1 2 3 4\n"
    "5 6 7 -9999\n"
    "9 10 11 12\n";

std::string error_of(const std::string& path) {
  try {
    io::read_raster(path);
  } catch (const io::InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(Raster, ReadsEsriAsciiValuesNodataAndCorner) {
  const TempDir t;
  const io::Raster r = io::read_raster(t.write("dem.asc", kGrid));
  ASSERT_EQ(r.ncols, 4);
  ASSERT_EQ(r.nrows, 3);
  EXPECT_EQ(r.west, 1000.0);
  EXPECT_EQ(r.south, 2000.0);
  EXPECT_EQ(r.east(), 1040.0);
  EXPECT_EQ(r.north(), 2030.0);
  EXPECT_EQ(r.at(0, 0), 1.0);   // north-west
  EXPECT_EQ(r.at(2, 3), 12.0);  // south-east
  EXPECT_TRUE(std::isnan(r.at(1, 3)));
  EXPECT_TRUE(r.crs.empty());
  // centres: column 0 at easting 1005, row 0 (north) at northing 2025
  EXPECT_EQ(r.centre_east(0), 1005.0);
  EXPECT_EQ(r.centre_north(0), 2025.0);
  EXPECT_EQ(r.centre_north(2), 2005.0);
  EXPECT_EQ(r.elevation(1005, 2025), 1.0);
  EXPECT_EQ(r.elevation(1015, 2005), 10.0);
  // bilinear between centres: halfway between 1 and 2, and among 1, 2, 5, 6
  EXPECT_DOUBLE_EQ(r.elevation(1010, 2025), 1.5);
  EXPECT_DOUBLE_EQ(r.elevation(1010, 2020), 3.5);
  // outer half cell: the edge centres' value, constant outward
  EXPECT_EQ(r.elevation(1001, 2029), 1.0);
  EXPECT_DOUBLE_EQ(r.elevation(1010, 2029.9), 1.5);
  // NODATA wherever it has a weight; its neighbours' own centres still evaluate
  EXPECT_TRUE(std::isnan(r.elevation(1030, 2015)));
  EXPECT_TRUE(std::isnan(r.elevation(1036, 2016)));
  EXPECT_EQ(r.elevation(1035, 2005), 12.0);
  EXPECT_EQ(r.elevation(1025, 2015), 7.0);
  // slope: +0.1 per metre east, -0.4 per metre north (rows grow by 4 southward per 10 m)
  double de = 0, dn = 0;
  ASSERT_TRUE(r.slope(1012, 2012, de, dn));
  EXPECT_NEAR(de, 0.1, 1e-12);
  EXPECT_NEAR(dn, -0.4, 1e-12);
  EXPECT_FALSE(r.slope(1034, 2014, de, dn));
  // the cells the bilinear evaluation reads for a box
  long r0, r1, c0, c1;
  r.cells_read(1006, 1014, 2016, 2024, r0, r1, c0, c1);
  EXPECT_EQ(c0, 0);
  EXPECT_EQ(c1, 1);
  EXPECT_EQ(r0, 0);
  EXPECT_EQ(r1, 1);
}

TEST(Raster, CellCentreOriginIsHalfACellFromTheCorner) {
  const TempDir t;
  const std::string centre = "NCOLS 4\nNROWS 3\nXLLCENTER 1005\nYLLCENTER 2005\nCELLSIZE 10\nNODATA_VALUE -9999\n"
                             "1 2 3 4 5 6 7 -9999\n9 10 11 12\n";  // values may wrap anywhere
  const io::Raster a = io::read_raster(t.write("corner.asc", kGrid));
  const io::Raster b = io::read_raster(t.write("centre.asc", centre));
  EXPECT_EQ(b.west, a.west);
  EXPECT_EQ(b.south, a.south);
  for (double e : {1000.0, 1007.5, 1013.0, 1029.0})
    for (double n : {2001.0, 2012.5, 2024.0}) {
      const double za = a.elevation(e, n), zb = b.elevation(e, n);
      if (std::isnan(za)) EXPECT_TRUE(std::isnan(zb)) << e << ", " << n;  // beside the NODATA cell
      else EXPECT_EQ(za, zb) << e << ", " << n;
    }
}

// What the maps are written with: esri_ascii_text gives the raster back through the reader (NaN
// as NODATA, corner and cell size exact); with GDAL, geotiff_bytes as well.
TEST(Raster, WrittenGridsReadBack) {
  const TempDir t;
  io::Raster a = io::read_raster(t.write("dem.asc", kGrid));
  a.values[0] = 0.123456789;
  a.west = 500000.025;  // UTM-sized
  const io::Raster b = io::read_esri_ascii(t.write("back.asc", io::esri_ascii_text(a)));
  EXPECT_EQ(b.ncols, a.ncols);
  EXPECT_EQ(b.nrows, a.nrows);
  EXPECT_EQ(b.west, a.west);
  EXPECT_EQ(b.south, a.south);
  EXPECT_EQ(b.cellsize, a.cellsize);
  for (size_t i = 0; i < a.values.size(); ++i)
    if (std::isnan(a.values[i])) EXPECT_TRUE(std::isnan(b.values[i])) << i; else EXPECT_EQ(b.values[i], a.values[i]) << i;
  if (!io::raster_gdal_available()) {
    EXPECT_THROW(io::geotiff_bytes(a), std::runtime_error);
    return;
  }
  const std::string tif = (t.dir / "back.tif").string();
  const std::string bytes = io::geotiff_bytes(a);
  std::ofstream(tif, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  const io::Raster c = io::read_raster(tif);
  EXPECT_EQ(c.west, a.west);
  EXPECT_EQ(c.south, a.south);
  EXPECT_EQ(c.cellsize, a.cellsize);
  for (size_t i = 0; i < a.values.size(); ++i)
    if (std::isnan(a.values[i])) EXPECT_TRUE(std::isnan(c.values[i])) << i; else EXPECT_EQ(c.values[i], a.values[i]) << i;
}

TEST(Raster, MalformedGridsNameFileAndLine) {
  const TempDir t;
  struct Case {
    const char* name;
    std::string text, needle;
  };
  const Case cases[] = {
      {"nocell.asc", "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\n1 2\n", ":5: the header has no 'cellsize'"},
      {"few.asc", "ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n3\n",
       ":7: 3 values, but ncols x nrows = 2 x 2 = 4"},
      {"many.asc", "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n3\n", ":7: more values than"},
      {"word.asc", "ncols 2\nnrows 2\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n3 x4\n", ":7: 'x4' is not a number"},
      {"key.asc", "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ndx 1\n1 2\n", ":5: unknown header key 'dx'"},
      {"cols.asc", "ncols 2.5\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n", ":1: 'ncols' must be a whole"},
      {"nan.asc", "ncols 2\nnrows 1\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 nan\n", ":6: 'nan' is not a number"},
  };
  for (const Case& c : cases) {
    const std::string path = t.write(c.name, c.text);
    const std::string msg = error_of(path);
    EXPECT_NE(msg.find(path + c.needle), std::string::npos) << c.name << ": " << msg;
  }
  EXPECT_NE(error_of((t.dir / "missing.asc").string()).find("no such raster file"), std::string::npos);
}

TEST(Raster, GeographicCoordinateSystemIsRefused) {
  const TempDir t;
  const std::string path = t.write("geo.asc", kGrid);
  t.write("geo.prj", "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
                     "PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]]");
  EXPECT_NE(error_of(path).find("geographic coordinate system (degrees"), std::string::npos) << error_of(path);
  t.write("utm.asc", kGrid);
  t.write("utm.prj", "PROJCS[\"WGS 84 / UTM zone 32N\",GEOGCS[\"WGS 84\"],UNIT[\"metre\",1]]");
  EXPECT_EQ(io::read_raster((t.dir / "utm.asc").string()).crs.substr(0, 6), "PROJCS");
  EXPECT_TRUE(io::wkt_is_geographic("  GEOGCRS[\"WGS 84\"]"));
  EXPECT_FALSE(io::wkt_is_geographic("PROJCRS[\"x\", BASEGEOGCRS[\"WGS 84\"]]"));
}

#ifdef GRANFLOW_WITH_GDAL
namespace {
// The hand-written grid as a GeoTIFF (and in CRS `epsg`, 0: none), through GDAL.
std::string write_geotiff(const std::filesystem::path& path, int epsg) {
  GDALAllRegister();
  GDALDriverH drv = GDALGetDriverByName("GTiff");
  GDALDatasetH ds = GDALCreate(drv, path.c_str(), 4, 3, 1, GDT_Float32, nullptr);
  double gt[6] = {1000, 10, 0, 2030, 0, -10};
  GDALSetGeoTransform(ds, gt);
  if (epsg) {
    OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
    OSRImportFromEPSG(srs, epsg);
    char* wkt = nullptr;
    OSRExportToWkt(srs, &wkt);
    GDALSetProjection(ds, wkt);
    CPLFree(wkt);
    OSRDestroySpatialReference(srs);
  }
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  GDALSetRasterNoDataValue(band, -9999);
  float v[12] = {1, 2, 3, 4, 5, 6, 7, -9999, 9, 10, 11, 12};
  EXPECT_EQ(GDALRasterIO(band, GF_Write, 0, 0, 4, 3, v, 4, 3, GDT_Float32, 0, 0), CE_None);
  GDALClose(ds);
  return path.string();
}
}  // namespace

TEST(Raster, GeoTiffThroughGdalGivesTheSameElevations) {
  ASSERT_TRUE(io::raster_gdal_available());
  const TempDir t;
  const io::Raster a = io::read_raster(t.write("dem.asc", kGrid));
  const io::Raster b = io::read_raster(write_geotiff(t.dir / "dem.tif", 32632));  // UTM 32N, metres
  EXPECT_NE(b.crs.find("UTM"), std::string::npos);
  ASSERT_EQ(b.ncols, a.ncols);
  ASSERT_EQ(b.nrows, a.nrows);
  EXPECT_EQ(b.west, a.west);
  EXPECT_EQ(b.south, a.south);
  EXPECT_EQ(b.cellsize, a.cellsize);
  for (size_t i = 0; i < a.values.size(); ++i) {
    if (std::isnan(a.values[i])) EXPECT_TRUE(std::isnan(b.values[i])) << i;
    else EXPECT_EQ(a.values[i], b.values[i]) << i;
  }
  for (double e : {1001.0, 1010.0, 1017.5, 1039.0})
    for (double n : {2002.0, 2015.0, 2029.0}) {
      const double za = a.elevation(e, n), zb = b.elevation(e, n);
      if (std::isnan(za)) EXPECT_TRUE(std::isnan(zb)); else EXPECT_EQ(za, zb) << e << ", " << n;
    }
  // without a coordinate system: metres; in degrees (WGS 84): refused
  EXPECT_TRUE(io::read_raster(write_geotiff(t.dir / "plain.tif", 0)).crs.empty());
  const std::string geo = write_geotiff(t.dir / "geo.tif", 4326);
  EXPECT_NE(error_of(geo).find(geo + ": the raster is in a geographic coordinate system"), std::string::npos)
      << error_of(geo);
  EXPECT_NE(error_of(t.write("junk.tif", "not a tiff")).find("not a raster GDAL can read"), std::string::npos);
}
#else
TEST(Raster, WithoutGdalOnlyAsciiGridsAreRead) {
  const TempDir t;
  EXPECT_FALSE(io::raster_gdal_available());
  EXPECT_NE(error_of(t.write("dem.tif", "x")).find("reads only ESRI ASCII grids"), std::string::npos);
}
#endif
