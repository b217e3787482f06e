// Elevation rasters (digital elevation models): ESRI ASCII grids (.asc) in every build, GeoTIFF
// and the other GDAL formats where the build found GDAL (raster_gdal_available). Georeferenced in
// metres: a raster in a geographic (degrees) coordinate system or in another linear unit is
// refused (every .prj form: WKT, ESRI's WKT and text, a BOM), one without a coordinate system is
// taken as metres; sizes and cell resolution are checked from the header before allocating.
// Errors are InputErrors naming the file (and line).
#pragma once

#include <string>
#include <vector>

namespace granflow::io {

struct Raster {
  std::string file;
  long ncols = 0, nrows = 0;
  double west = 0, south = 0;  // easting and northing of the lower-left corner of the lower-left cell
  double cellsize = 0;
  std::vector<double> values;  // nrows rows of ncols, row 0 the northern row (file order); NaN: NODATA
  std::string crs;             // coordinate system as given (WKT of a .prj or of GDAL), empty: none

  double at(long row, long col) const { return values[static_cast<size_t>(row * ncols + col)]; }
  double east() const { return west + static_cast<double>(ncols) * cellsize; }
  double north() const { return south + static_cast<double>(nrows) * cellsize; }
  double centre_east(long col) const { return west + (static_cast<double>(col) + 0.5) * cellsize; }
  double centre_north(long row) const { return south + (static_cast<double>(nrows - row) - 0.5) * cellsize; }
  // The column and row of the cell holding (easting, northing), clamped to the raster.
  long col_of(double easting) const;
  long row_of(double northing) const;
  bool covers(double easting, double northing) const {
    return easting >= west && easting <= east() && northing >= south && northing <= north();
  }

  // Bilinear between cell centres; in the outer half cell the edge centres' values are kept
  // (constant outward), beyond the raster those of its nearest point. NaN where a cell with a
  // non-zero weight is NODATA.
  double elevation(double easting, double northing) const;
  // Slope (d elevation / d easting, d elevation / d northing): central differences at the cell
  // centres (one-sided at the edges and beside NODATA), bilinear between centres as elevation.
  // False (slopes NaN) where a cell with a non-zero weight is NODATA.
  bool slope(double easting, double northing, double& d_east, double& d_north) const;
  // Cells [row0, row1] x [col0, col1] that elevation and slope may read for points in the
  // box [e0, e1] x [n0, n1] (the footprint's NODATA check).
  void cells_read(double e0, double e1, double n0, double n1, long& row0, long& row1, long& col0, long& col1) const;
};

// ESRI ASCII grid: header ncols, nrows, xllcorner | xllcenter, yllcorner | yllcenter, cellsize,
// optional NODATA_value (keys in any order, any case), then nrows x ncols values, the northern
// row first. A .prj beside it (same stem) gives the coordinate system.
Raster read_esri_ascii(const std::string& path);

// Any raster: .asc through read_esri_ascii, everything else through GDAL (band 1, north-up,
// square cells, scale and offset applied). Without GDAL only .asc is read.
Raster read_raster(const std::string& path);

// The text of an ESRI ASCII grid of r (xllcorner, yllcorner; NaN cells as NODATA_value -9999;
// 9 significant digits): read_esri_ascii gives r back.
std::string esri_ascii_text(const Raster& r);
// The bytes of a GeoTIFF of r (one Float64 band, NODATA -9999, r.crs as its coordinate system),
// made in GDAL's memory files so that the caller writes them through its checked path. Throws
// std::runtime_error in a build without GDAL (raster_gdal_available()) or when GDAL fails.
std::string geotiff_bytes(const Raster& r);

// True when this build reads rasters through GDAL (CMake found it: GRANFLOW_WITH_GDAL).
bool raster_gdal_available();

// A coordinate system given as WKT is geographic (degrees): GEOGCS / GEOGCRS / GEODCRS at its top.
bool wkt_is_geographic(const std::string& wkt);

// What a coordinate system's text says about its horizontal unit.
struct CrsUnit {
  enum Kind { Metres, Geographic, OtherUnit, Unknown } kind = Unknown;
  std::string unit;   // OtherUnit: its name as written ("US survey foot", "FEET")
  double metres = 0;  // OtherUnit: metres per unit (0: not stated)
};
// The coordinate system of a .prj read from its text alone, as a build without GDAL does (builds
// with GDAL ask OGR first and use this where OGR cannot parse it): WKT 1 and 2, ESRI's WKT, and
// ESRI's older lines ("Projection GEOGRAPHIC", "Units FEET"). A leading UTF-8 BOM is skipped.
CrsUnit crs_unit_from_text(const std::string& text);

// Limits checked before anything is allocated (InputErrors name the file and the size needed).
constexpr double kMaxRasterCells = 250e6;      // ncols x nrows (2 GB of doubles)
constexpr double kMaxAsciiBytes = 4e9;         // an .asc is read whole
constexpr double kMaxPrjBytes = 1e6;           // a .prj
// Cells must be at least this times the largest |easting| or |northing| of the raster's corners:
// double precision resolves 2.2e-16 times it, so a cell spans over 450,000 distinct values.
constexpr double kMinCellOverCoordinate = 1e-10;

}  // namespace granflow::io
