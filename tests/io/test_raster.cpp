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

namespace {
// A projected system in US survey feet (NAD83 / California zone 3 (ftUS), as GDAL writes it).
const char* kFeetWkt =
    "PROJCS[\"NAD83 / California zone 3 (ftUS)\",GEOGCS[\"NAD83\",DATUM[\"North_American_Datum_1983\","
    "SPHEROID[\"GRS 1980\",6378137,298.257222101]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],"
    "PROJECTION[\"Lambert_Conformal_Conic_2SP\"],PARAMETER[\"standard_parallel_1\",38.4333333333333],"
    "PARAMETER[\"standard_parallel_2\",37.0666666666667],PARAMETER[\"latitude_of_origin\",36.5],"
    "PARAMETER[\"central_meridian\",-120.5],PARAMETER[\"false_easting\",6561666.667],"
    "PARAMETER[\"false_northing\",1640416.667],UNIT[\"US survey foot\",0.304800609601219]]";
const char* kUtmWkt =
    "PROJCS[\"WGS 84 / UTM zone 32N\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,"
    "298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],"
    "PARAMETER[\"latitude_of_origin\",0],PARAMETER[\"central_meridian\",9],PARAMETER[\"scale_factor\",0.9996],"
    "PARAMETER[\"false_easting\",500000],PARAMETER[\"false_northing\",0],UNIT[\"metre\",1]]";
const char* kEsriGeoWkt =
    "GEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\",SPHEROID[\"WGS_1984\",6378137.0,298.257223563]],"
    "PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\",0.0174532925199433]]";
const char* kEsriGeoText =
    "Projection    GEOGRAPHIC\nDatum         WGS84\nSpheroid      WGS84\nUnits         DD\nZunits        NO\n"
    "Parameters\n";
const char* kEsriFeetText = "Projection    UTM\nZone          10\nDatum         NAD83\nUnits         FEET\n"
                            "Spheroid      GRS80\nParameters\n";
const char* kWkt2Feet =
    "PROJCRS[\"local feet\",BASEGEOGCRS[\"WGS 84\",DATUM[\"World Geodetic System 1984\",ELLIPSOID[\"WGS 84\","
    "6378137,298.257223563]],ANGLEUNIT[\"degree\",0.0174532925199433]],CONVERSION[\"UTM zone 10N\","
    "METHOD[\"Transverse Mercator\"],PARAMETER[\"Latitude of natural origin\",0,ANGLEUNIT[\"degree\","
    "0.0174532925199433]],PARAMETER[\"Longitude of natural origin\",-123,ANGLEUNIT[\"degree\",0.0174532925199433]],"
    "PARAMETER[\"Scale factor at natural origin\",0.9996,SCALEUNIT[\"unity\",1]],PARAMETER[\"False easting\","
    "1640416.667,LENGTHUNIT[\"foot\",0.3048]],PARAMETER[\"False northing\",0,LENGTHUNIT[\"foot\",0.3048]]],"
    "CS[Cartesian,2],AXIS[\"easting\",east,ORDER[1],LENGTHUNIT[\"foot\",0.3048]],"
    "AXIS[\"northing\",north,ORDER[2],LENGTHUNIT[\"foot\",0.3048]]]";
const std::string kBom = "\xEF\xBB\xBF";
}  // namespace

// Every form of a .prj is read for its unit, with and without a BOM: geographic systems (OGC
// WKT 1 and 2, ESRI's WKT, ESRI's older Projection/Units lines) are refused, so are linear units
// other than the metre (named, with the .prj); a projected system in metres is taken, and its
// text reaches maps/*.prj without the BOM. crs_unit_from_text is what a build without GDAL uses.
TEST(Raster, PrjInEveryFormIsCheckedForMetres) {
  using K = io::CrsUnit;
  struct Form {
    const char* name;
    std::string text;
    K::Kind kind;
    const char* needle;  // in the error after the raster's path
  };
  const Form forms[] = {
      {"wkt1_geo", "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\",6378137,298.257223563]],"
                   "PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]]",
       K::Geographic, "the raster is in a geographic coordinate system (degrees, "},
      {"bom_geo", kBom + kEsriGeoWkt, K::Geographic, "the raster is in a geographic coordinate system (degrees, "},
      {"esri_geo", kEsriGeoWkt, K::Geographic, "the raster is in a geographic coordinate system (degrees, "},
      {"esri_text_geo", kEsriGeoText, K::Geographic, "the raster is in a geographic coordinate system (degrees, "},
      {"wkt2_geo", "GEOGCRS[\"WGS 84\",DATUM[\"World Geodetic System 1984\",ELLIPSOID[\"WGS 84\",6378137,"
                   "298.257223563]],CS[ellipsoidal,2],AXIS[\"latitude\",north],AXIS[\"longitude\",east],"
                   "ANGLEUNIT[\"degree\",0.0174532925199433]]",
       K::Geographic, "the raster is in a geographic coordinate system (degrees, "},
      {"feet", kFeetWkt, K::OtherUnit, "the coordinate system's unit is 'US survey foot' (0.3048006096 m, "},
      {"bom_feet", kBom + kFeetWkt, K::OtherUnit, "the coordinate system's unit is 'US survey foot'"},
      {"esri_text_feet", kEsriFeetText, K::OtherUnit, "the coordinate system's unit is '"},
      {"wkt2_feet", kWkt2Feet, K::OtherUnit, "the coordinate system's unit is '"},
      {"junk", "hello", K::Unknown, "cannot tell the coordinate system of "},
  };
  const TempDir t;
  for (const Form& f : forms) {
    EXPECT_EQ(io::crs_unit_from_text(f.text).kind, f.kind) << f.name;
    const std::string path = t.write(std::string(f.name) + ".asc", kGrid);
    const std::string prj = t.write(std::string(f.name) + ".prj", f.text);
    const std::string msg = error_of(path);
    EXPECT_EQ(msg.rfind(path + ": " + f.needle, 0), 0u) << f.name << ": " << msg;
    EXPECT_NE(msg.find(prj), std::string::npos) << f.name << ": " << msg;
  }
  const io::CrsUnit feet = io::crs_unit_from_text(kFeetWkt);
  EXPECT_EQ(feet.unit, "US survey foot");
  EXPECT_NEAR(feet.metres, 1200.0 / 3937.0, 1e-14);
  EXPECT_EQ(io::crs_unit_from_text(kEsriFeetText).unit, "FEET");
  EXPECT_DOUBLE_EQ(io::crs_unit_from_text(kWkt2Feet).metres, 0.3048);
  // metres: taken, the BOM dropped; an empty .prj is no coordinate system
  for (const std::string& text : {std::string(kUtmWkt), kBom + kUtmWkt, std::string("Projection UTM\nUnits METERS\n")}) {
    EXPECT_EQ(io::crs_unit_from_text(text).kind, K::Metres) << text;
    t.write("m.prj", text);
    const io::Raster r = io::read_raster(t.write("m.asc", kGrid));
    EXPECT_EQ(r.crs, text.rfind(kBom, 0) == 0 ? text.substr(3) : text);
  }
  t.write("e.prj", kBom + "\n");
  EXPECT_TRUE(io::read_raster(t.write("e.asc", kGrid)).crs.empty());
}

// Cells finer than the coordinates resolve in double precision are refused from the header:
// the rule is cellsize >= 1e-10 x the largest |easting| or |northing| of the raster's corners.
TEST(Raster, CellsBelowTheCoordinatesResolutionAreRefused) {
  const TempDir t;
  auto grid = [](const char* x, const char* cell) {
    return std::string("ncols 2\nnrows 2\nxllcorner ") + x + "\nyllcorner 0\ncellsize " + cell + "\n1 2\n3 4\n";
  };
  const std::string far = t.write("far.asc", grid("1e17", "0.04"));  // the case: 16 m between doubles
  const std::string msg = error_of(far);
  EXPECT_EQ(msg.rfind(far + ":6: cells of 0.04 m at coordinates up to 1e+17 m", 0), 0u) << msg;
  EXPECT_NE(msg.find("at least 1e-10 x the largest |easting| or |northing| (10000000 m here)"), std::string::npos)
      << msg;
  // at 1e8 m the limit is 1e-2 m (the east edge lies 2 cells further: 1.0000000002e-2)
  EXPECT_NE(error_of(t.write("below.asc", grid("1e8", "0.0099"))).find("cells of 0.0099 m"), std::string::npos);
  EXPECT_EQ(io::read_raster(t.write("above.asc", grid("1e8", "0.0101"))).cellsize, 0.0101);
  // a UTM northing of 4e6 m keeps cells of 1 mm (limit 0.4 mm)
  EXPECT_EQ(io::read_raster(t.write("utm.asc", grid("4e6", "0.001"))).cellsize, 0.001);
}

// Sizes are checked before anything is allocated or read: a header of 1e10 cells, a raster or
// .prj that is a link to /dev/zero (a file that never ends), a folder.
TEST(Raster, OversizedAndEndlessFilesAreRefusedBeforeReading) {
  const TempDir t;
  const std::string huge =
      t.write("huge.asc", "ncols 100000\nnrows 100000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n");
  const std::string msg = error_of(huge);
  EXPECT_EQ(msg.rfind(huge + ":6: ncols x nrows = 100000 x 100000 = 10000000000 cells would need 80 GB", 0), 0u)
      << msg;
  EXPECT_NE(msg.find("at most 250000000 cells"), std::string::npos) << msg;
  // under the limit but far more than the file holds: counted, not reserved
  const std::string few = t.write("few.asc", "ncols 10000\nnrows 10000\nxllcorner 0\nyllcorner 0\ncellsize 1\n1 2\n");
  EXPECT_NE(error_of(few).find(":6: 2 values, but ncols x nrows = 10000 x 10000 = 100000000"), std::string::npos);
  for (const char* name : {"zero.asc", "zero.tif"}) {
    const std::string link = (t.dir / name).string();
    std::filesystem::create_symlink("/dev/zero", link);
    const std::string m = error_of(link);
    EXPECT_EQ(m.rfind(link + ": not a regular file (a device, FIFO or folder, linked to /dev/zero)", 0), 0u) << m;
  }
  const std::string asc = t.write("dem.asc", kGrid);
  std::filesystem::create_symlink("/dev/zero", t.dir / "dem.prj");
  const std::string m = error_of(asc);
  EXPECT_EQ(m.rfind((t.dir / "dem.prj").string() + ": not a regular file", 0), 0u) << m;
  std::filesystem::create_directory(t.dir / "folder.asc");
  EXPECT_NE(error_of((t.dir / "folder.asc").string()).find("folder.asc: not a regular file"), std::string::npos);
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
  // a GeoTIFF in US survey feet: refused as its .asc twin is, naming the unit
  const std::string feet = write_geotiff(t.dir / "feet.tif", 2227);
  EXPECT_EQ(error_of(feet).rfind(feet + ": the coordinate system's unit is 'US survey foot' (0.3048006096 m)", 0), 0u)
      << error_of(feet);
}
#else
TEST(Raster, WithoutGdalOnlyAsciiGridsAreRead) {
  const TempDir t;
  EXPECT_FALSE(io::raster_gdal_available());
  EXPECT_NE(error_of(t.write("dem.tif", "x")).find("reads only ESRI ASCII grids"), std::string::npos);
}
#endif
