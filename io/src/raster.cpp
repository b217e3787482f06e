#include <granflow/io/raster.hpp>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>

#include <granflow/io/input_error.hpp>

#ifdef GRANFLOW_WITH_GDAL
#include <cpl_conv.h>
#include <cpl_error.h>
#include <cpl_string.h>
#include <cpl_vsi.h>
#include <gdal.h>
#include <ogr_srs_api.h>
#endif

namespace granflow::io {
namespace {

const double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string lower(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(10);
  os << v;
  return os.str();
}

// Whitespace-separated words of a text with the line of each.
class Words {
 public:
  explicit Words(const std::string& text) : s_(text) {}
  bool next(std::string& word, long& line) {
    while (at_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[at_]))) {
      if (s_[at_] == '\n') ++line_;
      ++at_;
    }
    if (at_ >= s_.size()) return false;
    const size_t start = at_;
    while (at_ < s_.size() && !std::isspace(static_cast<unsigned char>(s_[at_]))) ++at_;
    word.assign(s_, start, at_ - start);
    line = line_;
    return true;
  }

 private:
  const std::string& s_;
  size_t at_ = 0;
  long line_ = 1;
};

bool parse_number(const std::string& w, double& v) {
  const char* b = w.data();
  const char* e = b + w.size();
  if (b != e && *b == '+') ++b;  // from_chars takes no '+'
  const auto r = std::from_chars(b, e, v);
  return r.ec == std::errc() && r.ptr == e && std::isfinite(v);
}

// Bilinear position along one axis of n centres: index i0 and fraction f of centre coordinate u.
void axis_weights(double u, long n, long& i0, double& f) {
  if (n == 1) {
    i0 = 0;
    f = 0;
    return;
  }
  u = std::clamp(u, 0.0, static_cast<double>(n - 1));
  i0 = std::min(static_cast<long>(std::floor(u)), n - 2);
  f = u - static_cast<double>(i0);
}

// Calls use(row, col, weight) for the (up to) four centres around (easting, northing).
template <class F>
void bilinear(const Raster& r, double easting, double northing, F&& use) {
  long c0, r0;
  double fc, fr;
  axis_weights((easting - r.west) / r.cellsize - 0.5, r.ncols, c0, fc);
  axis_weights((r.north() - northing) / r.cellsize - 0.5, r.nrows, r0, fr);
  for (int a = 0; a < 2; ++a)
    for (int b = 0; b < 2; ++b) {
      const double w = (a ? fr : 1 - fr) * (b ? fc : 1 - fc);
      if (w != 0) use(r0 + a, c0 + b, w);
    }
}

// Central difference along one axis at a cell centre (one-sided at the edges and beside
// NODATA): (value at +1 - value at -1) / distance. NaN when the cell itself is NODATA.
double centre_difference(const Raster& r, long row, long col, int drow, int dcol) {
  const double z = r.at(row, col);
  if (std::isnan(z)) return kNaN;
  auto value = [&](int s) {
    const long rr = row + s * drow, cc = col + s * dcol;
    if (rr < 0 || rr >= r.nrows || cc < 0 || cc >= r.ncols) return kNaN;
    return r.at(rr, cc);
  };
  const double up = value(1), down = value(-1);
  if (!std::isnan(up) && !std::isnan(down)) return (up - down) / (2 * r.cellsize);
  if (!std::isnan(up)) return (up - z) / r.cellsize;
  if (!std::isnan(down)) return (z - down) / r.cellsize;
  return 0.0;  // a single cell along this axis: level
}

#ifdef GRANFLOW_WITH_GDAL
// While alive: GDAL's drivers registered (once per process) and its errors kept off stderr, so
// that the caller can report CPLGetLastErrorMsg() in its own message.
struct GdalSession {
  GdalSession() {
    static std::once_flag registered;
    std::call_once(registered, [] { GDALAllRegister(); });
    CPLPushErrorHandler(CPLQuietErrorHandler);
    CPLErrorReset();
  }
  ~GdalSession() { CPLPopErrorHandler(); }
  GdalSession(const GdalSession&) = delete;
  GdalSession& operator=(const GdalSession&) = delete;
};

std::string gdal_message(const std::string& fallback) {
  const char* m = CPLGetLastErrorMsg();
  return m && *m ? std::string(m) : fallback;
}

#endif

[[noreturn]] void refuse_geographic(const std::string& path, const std::string& source) {
  throw InputError(where(path) + "the raster is in a geographic coordinate system (degrees" + source +
                   "); granflow needs a projected one in metres (e.g. UTM): reproject it, e.g. gdalwarp -t_srs "
                   "EPSG:326xx");
}

std::string upper(std::string s) {
  for (char& c : s) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return s;
}

std::string skip_bom(const std::string& s) { return s.rfind("\xEF\xBB\xBF", 0) == 0 ? s.substr(3) : s; }

// A WKT node NAME[arg, ...]: quoted strings and bare words in `atoms`, nodes in `kids`.
struct WktNode {
  std::string name;  // upper case
  std::vector<std::string> atoms;
  std::vector<WktNode> kids;
};

class WktParser {
 public:
  explicit WktParser(const std::string& s) : s_(s) {}
  bool parse(WktNode& n) {
    if (!node(n, 0)) return false;
    skip();
    return at_ == s_.size();
  }

 private:
  bool more() const { return at_ < s_.size(); }
  void skip() {
    while (more() && std::isspace(static_cast<unsigned char>(s_[at_]))) ++at_;
  }
  bool word(std::string& w) {
    skip();
    const size_t b = at_;
    auto in_word = [](char c) {
      return std::isalnum(static_cast<unsigned char>(c)) || c == '_' || c == '.' || c == '+' || c == '-';
    };
    while (more() && in_word(s_[at_])) ++at_;
    w.assign(s_, b, at_ - b);
    return !w.empty();
  }
  bool opens() const { return more() && (s_[at_] == '[' || s_[at_] == '('); }
  bool node(WktNode& n, int depth) {
    if (depth > 32 || !word(n.name)) return false;  // depth: no stack overflow on hostile input
    n.name = upper(n.name);
    skip();
    if (!opens()) return false;
    ++at_;
    for (;;) {
      skip();
      if (!more()) return false;
      if (s_[at_] == '"') {  // "" is a quote inside
        std::string q;
        for (++at_;; ++at_) {
          if (!more()) return false;
          if (s_[at_] == '"') {
            if (at_ + 1 < s_.size() && s_[at_ + 1] == '"') { q += '"'; ++at_; continue; }
            ++at_;
            break;
          }
          q += s_[at_];
        }
        n.atoms.push_back(q);
      } else {
        const size_t save = at_;
        std::string w;
        if (!word(w)) return false;
        skip();
        if (opens()) {
          at_ = save;
          n.kids.emplace_back();
          if (!node(n.kids.back(), depth + 1)) return false;
        } else {
          n.atoms.push_back(w);
        }
      }
      skip();
      if (more() && s_[at_] == ',') { ++at_; continue; }
      if (more() && (s_[at_] == ']' || s_[at_] == ')')) { ++at_; return true; }
      return false;
    }
  }
  const std::string& s_;
  size_t at_ = 0;
};

CrsUnit unit_of_wkt(const WktNode& n) {
  const std::string& k = n.name;
  if (k == "GEOGCS" || k == "GEOGCRS" || k == "GEOGRAPHICCRS" || k == "GEODCRS" || k == "GEODETICCRS")
    return {CrsUnit::Geographic, "", 0};
  if ((k == "COMPD_CS" || k == "COMPOUNDCRS") && !n.kids.empty()) return unit_of_wkt(n.kids.front());
  if (k == "BOUNDCRS")
    for (const WktNode& c : n.kids)
      if (c.name == "SOURCECRS" && !c.kids.empty()) return unit_of_wkt(c.kids.front());
  if (k != "PROJCS" && k != "PROJCRS" && k != "PROJECTEDCRS" && k != "LOCAL_CS" && k != "ENGCRS" &&
      k != "ENGINEERINGCRS")
    return {};
  auto is_unit = [](const WktNode& c) { return c.name == "UNIT" || c.name == "LENGTHUNIT"; };
  const WktNode* unit = nullptr;
  for (const WktNode& c : n.kids)  // WKT 1: UNIT of the PROJCS itself (the GEOGCS inside has degrees)
    if (!unit && is_unit(c)) unit = &c;
  for (const WktNode& c : n.kids)  // WKT 2: a LENGTHUNIT in the AXIS nodes
    if (c.name == "AXIS")
      for (const WktNode& a : c.kids)
        if (!unit && is_unit(a)) unit = &a;
  double m = 0;
  if (!unit || unit->atoms.size() < 2 || !parse_number(unit->atoms[1], m) || !(m > 0)) return {};
  if (std::fabs(m - 1.0) <= 1e-9) return {CrsUnit::Metres, unit->atoms[0], 1.0};
  return {CrsUnit::OtherUnit, unit->atoms[0], m};
}

// ESRI's older text: lines of "Keyword value" (Projection, Datum, Units, Zunits, Parameters, ...).
bool unit_of_esri_text(const std::string& text, CrsUnit& u) {
  std::istringstream in(text);
  std::string line, projection, units;
  bool first = true;
  while (std::getline(in, line)) {
    std::istringstream ws(line);
    std::string key, value;
    if (!(ws >> key)) continue;
    ws >> value;
    key = lower(key);
    if (first && key != "projection") return false;
    first = false;
    if (key == "projection") projection = upper(value);
    else if (key == "units") units = upper(value);
  }
  if (first) return false;
  if (projection == "GEOGRAPHIC") u = {CrsUnit::Geographic, "", 0};
  else if (units.empty() || units == "METERS" || units == "METRES" || units == "METER" || units == "METRE" || units == "M")
    u = {CrsUnit::Metres, units, 1.0};
  else if (units == "FEET" || units == "FT") u = {CrsUnit::OtherUnit, units, 0.3048};
  else u = {CrsUnit::OtherUnit, units, 0};
  return true;
}

#ifdef GRANFLOW_WITH_GDAL
// OGR's reading of a coordinate system (WKT of any version or dialect, ESRI's older text); false
// where OGR cannot parse it or it is neither geographic nor projected.
bool unit_of_ogr(const std::string& text, CrsUnit& u) {
  OGRSpatialReferenceH srs = OSRNewSpatialReference(nullptr);
  std::string copy = text;
  char* p = copy.data();
  bool ok = OSRImportFromWkt(srs, &p) == OGRERR_NONE;
  if (!ok) {
    char** lines = CSLTokenizeString2(text.c_str(), "\r\n", 0);
    ok = lines && OSRImportFromESRI(srs, lines) == OGRERR_NONE;
    CSLDestroy(lines);
  }
  if (ok && OSRIsGeographic(srs)) {
    u = {CrsUnit::Geographic, "", 0};
  } else if (ok && (OSRIsProjected(srs) || OSRIsLocal(srs))) {
    char* name = nullptr;
    const double m = OSRGetLinearUnits(srs, &name);
    u = {std::fabs(m - 1.0) <= 1e-9 ? CrsUnit::Metres : CrsUnit::OtherUnit, name ? name : "", m};
  } else {
    ok = false;
  }
  OSRDestroySpatialReference(srs);
  return ok;
}
#endif

// Refuses a coordinate system that is not projected in metres; `from`: where it was read (a .prj).
void check_crs(const std::string& path, const std::string& from, const std::string& text) {
  CrsUnit u;
#ifdef GRANFLOW_WITH_GDAL
  const GdalSession gdal;
  if (!unit_of_ogr(text, u)) u = crs_unit_from_text(text);
#else
  u = crs_unit_from_text(text);
#endif
  const std::string src = from.empty() ? std::string() : ", " + from;
  if (u.kind == CrsUnit::Geographic) refuse_geographic(path, src);
  if (u.kind == CrsUnit::OtherUnit)
    throw InputError(where(path) + "the coordinate system's unit is '" + u.unit + "'" +
                     (u.metres > 0 ? " (" + fmt(u.metres) + " m" : std::string(" (not a length")) + src +
                     "); granflow needs metres: reproject the raster, e.g. gdalwarp -t_srs EPSG:326xx");
  if (u.kind == CrsUnit::Unknown)
    throw InputError(where(path) + "cannot tell the coordinate system" + (from.empty() ? "" : " of " + from) +
                     " (neither WKT nor ESRI's Projection/Units lines); granflow needs a projected one in "
                     "metres: correct the .prj, or remove it to take the raster as metres");
}

// Size and precision, from the header alone: refused before anything is allocated.
void check_extent(const Raster& r, const std::string& path, long line = 0) {
  const double cells = static_cast<double>(r.ncols) * static_cast<double>(r.nrows);
  if (cells > kMaxRasterCells)
    throw InputError(where(path, line) + "ncols x nrows = " + std::to_string(r.ncols) + " x " + std::to_string(r.nrows) +
                     " = " + std::to_string(r.ncols * r.nrows) + " cells would need " + fmt(cells * 8 / 1e9) +
                     " GB as doubles; granflow reads at most " + fmt(kMaxRasterCells) +
                     " cells (2 GB): crop or coarsen the raster (gdal_translate -projwin, -tr)");
  const double big = std::max({std::fabs(r.west), std::fabs(r.east()), std::fabs(r.south), std::fabs(r.north())});
  if (!(r.cellsize >= kMinCellOverCoordinate * big))
    throw InputError(where(path, line) + "cells of " + fmt(r.cellsize) + " m at coordinates up to " + fmt(big) +
                     " m: double precision resolves only " + fmt(big * std::numeric_limits<double>::epsilon()) +
                     " m there; granflow needs cells of at least 1e-10 x the largest |easting| or |northing| (" +
                     fmt(kMinCellOverCoordinate * big) +
                     " m here): shift the raster's coordinates (xllcorner, yllcorner) and terrain.origin by "
                     "the same amount");
}

// A regular file (a link is followed) of at most `limit` bytes: no device, FIFO or folder.
void check_regular(const std::string& path, double limit, const std::string& what) {
  std::error_code ec;
  const auto st = std::filesystem::status(path, ec);
  if (!std::filesystem::exists(st)) return;  // the caller names a missing file
  if (!std::filesystem::is_regular_file(st))
    throw InputError(where(path) + "not a regular file (a device, FIFO or folder" +
                     (std::filesystem::is_symlink(std::filesystem::symlink_status(path, ec))
                          ? ", linked to " + std::filesystem::read_symlink(path, ec).string()
                          : std::string()) +
                     "); granflow reads " + what + " from regular files");
  const double size = static_cast<double>(std::filesystem::file_size(path, ec));
  if (size > limit)
    throw InputError(where(path) + fmt(size) + " bytes; granflow reads " + what + " of at most " + fmt(limit) +
                     " bytes");
}

#ifdef GRANFLOW_WITH_GDAL
Raster read_gdal(const std::string& path) {
  const GdalSession gdal;
  GDALDatasetH ds = GDALOpen(path.c_str(), GA_ReadOnly);
  if (!ds) throw InputError(where(path) + "not a raster GDAL can read (" + gdal_message("unknown format") + ")");
  struct Close {
    GDALDatasetH d;
    ~Close() { GDALClose(d); }
  } close{ds};
  Raster r;
  r.file = path;
  r.ncols = GDALGetRasterXSize(ds);
  r.nrows = GDALGetRasterYSize(ds);
  if (GDALGetRasterCount(ds) < 1 || r.ncols < 1 || r.nrows < 1) throw InputError(where(path) + "the raster has no band");
  double gt[6];
  if (GDALGetGeoTransform(ds, gt) != CE_None)
    throw InputError(where(path) + "the raster has no georeferencing (geotransform)");
  if (gt[2] != 0 || gt[4] != 0) throw InputError(where(path) + "the raster is rotated; granflow needs north-up rasters");
  if (!(gt[1] > 0) || std::fabs(gt[1] + gt[5]) > 1e-9 * gt[1])
    throw InputError(where(path) + "cells of " + fmt(gt[1]) + " x " + fmt(-gt[5]) +
                     ": granflow needs square cells in north-up rows (gdalwarp -tr)");
  r.cellsize = gt[1];
  r.west = gt[0];
  r.south = gt[3] - static_cast<double>(r.nrows) * r.cellsize;
  if (const char* wkt = GDALGetProjectionRef(ds); wkt && *wkt) {
    r.crs = wkt;
    check_crs(path, "", r.crs);  // as a .prj beside an .asc
  }
  check_extent(r, path);
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  int has_nodata = 0;
  const double nodata = GDALGetRasterNoDataValue(band, &has_nodata);
  const double scale = GDALGetRasterScale(band, nullptr), offset = GDALGetRasterOffset(band, nullptr);
  r.values.resize(static_cast<size_t>(r.ncols * r.nrows));
  if (GDALRasterIO(band, GF_Read, 0, 0, static_cast<int>(r.ncols), static_cast<int>(r.nrows), r.values.data(),
                   static_cast<int>(r.ncols), static_cast<int>(r.nrows), GDT_Float64, 0, 0) != CE_None)
    throw InputError(where(path) + "reading band 1 failed (" + gdal_message("GDALRasterIO") + ")");
  for (double& v : r.values) {
    if (has_nodata && (v == nodata || (std::isnan(nodata) && std::isnan(v)))) {
      v = kNaN;
      continue;
    }
    if (!std::isfinite(v)) throw InputError(where(path) + "a non-finite elevation that is not the NODATA value");
    v = v * scale + offset;
  }
  return r;
}
#endif

}  // namespace

long Raster::col_of(double easting) const {
  return std::clamp(static_cast<long>(std::floor((easting - west) / cellsize)), 0L, ncols - 1);
}
long Raster::row_of(double northing) const {
  return std::clamp(static_cast<long>(std::floor((north() - northing) / cellsize)), 0L, nrows - 1);
}

double Raster::elevation(double easting, double northing) const {
  double z = 0;
  bilinear(*this, easting, northing, [&](long row, long col, double w) { z += w * at(row, col); });
  return z;  // NaN propagates
}

bool Raster::slope(double easting, double northing, double& d_east, double& d_north) const {
  d_east = d_north = 0;
  bilinear(*this, easting, northing, [&](long row, long col, double w) {
    d_east += w * centre_difference(*this, row, col, 0, 1);
    d_north += w * centre_difference(*this, row, col, -1, 0);  // row - 1 lies north
  });
  return !std::isnan(d_east) && !std::isnan(d_north);
}

void Raster::cells_read(double e0, double e1, double n0, double n1, long& row0, long& row1, long& col0,
                        long& col1) const {
  // positions in units of cells from the first centre: the centres around u are floor(u), ceil(u)
  auto clamp_to = [](double u, long n) { return std::clamp(static_cast<long>(u), 0L, n - 1); };
  col0 = clamp_to(std::floor((e0 - west) / cellsize - 0.5), ncols);
  col1 = clamp_to(std::ceil((e1 - west) / cellsize - 0.5), ncols);
  row0 = clamp_to(std::floor((north() - n1) / cellsize - 0.5), nrows);
  row1 = clamp_to(std::ceil((north() - n0) / cellsize - 0.5), nrows);
}

CrsUnit crs_unit_from_text(const std::string& text) {
  const std::string t = skip_bom(text);
  CrsUnit u;
  WktNode root;
  if (WktParser(t).parse(root)) return unit_of_wkt(root);
  if (unit_of_esri_text(t, u)) return u;
  return {};
}

bool wkt_is_geographic(const std::string& wkt) {
  const auto a = wkt.find_first_not_of(" \t\r\n");
  if (a == std::string::npos) return false;
  const std::string head = lower(wkt.substr(a, 8));
  return head.rfind("geogcs", 0) == 0 || head.rfind("geogcrs", 0) == 0 || head.rfind("geodcrs", 0) == 0;
}

Raster read_esri_ascii(const std::string& path) {
  check_regular(path, kMaxAsciiBytes, "ESRI ASCII grids");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(where(path) + (std::filesystem::exists(path) ? "cannot be read" : "no such raster file"));
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string text = ss.str();
  Words words(text);
  Raster r;
  r.file = path;
  double nodata = kNaN;
  bool has[6] = {};  // ncols nrows x y cellsize nodata
  bool x_centre = false, y_centre = false;
  double x = 0, y = 0;
  std::string w, value;
  long line = 0;
  // header: "key value" pairs up to the first word that is a number
  for (;;) {
    if (!words.next(w, line)) throw InputError(where(path) + "no values after the header");
    double probe;
    if (parse_number(w, probe)) break;
    const std::string key = lower(w);
    long vline = 0;
    if (!words.next(value, vline) || vline != line)
      throw InputError(where(path, line) + "header key '" + w + "' has no value on its line");
    double v;
    if (!parse_number(value, v)) throw InputError(where(path, line) + "header '" + w + "': '" + value + "' is not a number");
    auto once = [&](int k) {
      if (has[k]) throw InputError(where(path, line) + "header '" + w + "' given twice");
      has[k] = true;
    };
    auto count = [&]() {
      if (v < 1 || v != std::floor(v) || v > 1e8) throw InputError(where(path, line) + "'" + w + "' must be a whole number >= 1, got " + value);
      return static_cast<long>(v);
    };
    if (key == "ncols") { once(0); r.ncols = count(); }
    else if (key == "nrows") { once(1); r.nrows = count(); }
    else if (key == "xllcorner" || key == "xllcenter" || key == "xllcentre") { once(2); x = v; x_centre = key != "xllcorner"; }
    else if (key == "yllcorner" || key == "yllcenter" || key == "yllcentre") { once(3); y = v; y_centre = key != "yllcorner"; }
    else if (key == "cellsize") {
      once(4);
      if (!(v > 0)) throw InputError(where(path, line) + "'cellsize' must be positive, got " + value);
      r.cellsize = v;
    } else if (key == "nodata_value") { once(5); nodata = v; }
    else
      throw InputError(where(path, line) + "unknown header key '" + w +
                       "' (an ESRI ASCII grid has ncols, nrows, xllcorner or xllcenter, yllcorner or yllcenter, "
                       "cellsize and NODATA_value; dx/dy cells are not supported)");
  }
  const char* names[5] = {"ncols", "nrows", "xllcorner (or xllcenter)", "yllcorner (or yllcenter)", "cellsize"};
  for (int k = 0; k < 5; ++k)
    if (!has[k]) throw InputError(where(path, line) + "the header has no '" + names[k] + "'");
  r.west = x_centre ? x - 0.5 * r.cellsize : x;
  r.south = y_centre ? y - 0.5 * r.cellsize : y;
  check_extent(r, path, line);
  const size_t n = static_cast<size_t>(r.ncols * r.nrows);
  r.values.reserve(std::min(n, text.size() / 2 + 1));  // a value takes at least 2 bytes
  const double tol = 1e-6 * std::fabs(nodata);  // NODATA written in float precision (-3.4e38)
  for (bool first = true;; first = false) {
    if (!first && !words.next(w, line)) break;
    double v;
    if (!parse_number(w, v))
      throw InputError(where(path, line) + "'" + w + "' is not a number (value " + std::to_string(r.values.size() + 1) +
                       " of " + std::to_string(n) + ")");
    if (r.values.size() == n)
      throw InputError(where(path, line) + "more values than ncols x nrows = " + std::to_string(r.ncols) + " x " +
                       std::to_string(r.nrows));
    r.values.push_back(has[5] && std::fabs(v - nodata) <= tol ? kNaN : v);
  }
  if (r.values.size() != n)
    throw InputError(where(path, line) + std::to_string(r.values.size()) + " values, but ncols x nrows = " +
                     std::to_string(r.ncols) + " x " + std::to_string(r.nrows) + " = " + std::to_string(n));
  std::filesystem::path prj(path);
  prj.replace_extension(".prj");
  if (std::filesystem::exists(prj)) {
    check_regular(prj.string(), kMaxPrjBytes, "coordinate systems (.prj)");
    std::ifstream p(prj, std::ios::binary);
    std::ostringstream wkt;
    wkt << p.rdbuf();
    r.crs = skip_bom(wkt.str());  // maps/*.prj get it without the BOM
    if (r.crs.find_first_not_of(" \t\r\n") == std::string::npos) r.crs.clear();  // empty: none
    else check_crs(path, prj.string(), r.crs);
  }
  return r;
}

std::string esri_ascii_text(const Raster& r) {
  std::ostringstream os;
  os.precision(15);
  os << "ncols " << r.ncols << "\nnrows " << r.nrows << "\nxllcorner " << r.west << "\nyllcorner " << r.south
     << "\ncellsize " << r.cellsize << "\nNODATA_value -9999\n";
  os.precision(9);
  for (long row = 0; row < r.nrows; ++row) {
    for (long col = 0; col < r.ncols; ++col) {
      const double v = r.at(row, col);
      if (col > 0) os << ' ';
      if (std::isnan(v)) os << "-9999"; else os << v;
    }
    os << '\n';
  }
  return os.str();
}

std::string geotiff_bytes(const Raster& r) {
#ifdef GRANFLOW_WITH_GDAL
  const GdalSession gdal;
  static std::atomic<long> serial{0};
  const std::string name = "/vsimem/granflow_map_" + std::to_string(serial++) + ".tif";
  GDALDriverH drv = GDALGetDriverByName("GTiff");
  if (!drv) throw std::runtime_error("GDAL has no GTiff driver");
  GDALDatasetH ds = GDALCreate(drv, name.c_str(), static_cast<int>(r.ncols), static_cast<int>(r.nrows), 1,
                               GDT_Float64, nullptr);
  if (!ds) throw std::runtime_error("GDAL could not create a GeoTIFF (" + gdal_message("GDALCreate") + ")");
  double gt[6] = {r.west, r.cellsize, 0.0, r.north(), 0.0, -r.cellsize};
  GDALSetGeoTransform(ds, gt);
  if (!r.crs.empty()) GDALSetProjection(ds, r.crs.c_str());  // an ESRI .prj GDAL cannot parse is left out
  GDALRasterBandH band = GDALGetRasterBand(ds, 1);
  GDALSetRasterNoDataValue(band, -9999.0);
  std::vector<double> v(r.values);
  for (double& x : v)
    if (std::isnan(x)) x = -9999.0;
  const CPLErr err = GDALRasterIO(band, GF_Write, 0, 0, static_cast<int>(r.ncols), static_cast<int>(r.nrows),
                                  v.data(), static_cast<int>(r.ncols), static_cast<int>(r.nrows), GDT_Float64, 0, 0);
  GDALClose(ds);
  vsi_l_offset len = 0;
  GByte* buf = VSIGetMemFileBuffer(name.c_str(), &len, TRUE);  // takes the buffer and removes the file
  std::string out(reinterpret_cast<const char*>(buf), buf ? static_cast<size_t>(len) : 0);
  CPLFree(buf);
  if (err != CE_None || out.empty())
    throw std::runtime_error("GDAL could not write a GeoTIFF (" + gdal_message("GDALRasterIO") + ")");
  return out;
#else
  (void)r;
  throw std::runtime_error("this build has no GDAL: GeoTIFF maps are not written");
#endif
}

bool raster_gdal_available() {
#ifdef GRANFLOW_WITH_GDAL
  return true;
#else
  return false;
#endif
}

Raster read_raster(const std::string& path) {
  if (lower(std::filesystem::path(path).extension().string()) == ".asc") return read_esri_ascii(path);
  if (!std::filesystem::exists(path)) throw InputError(where(path) + "no such raster file");
  check_regular(path, std::numeric_limits<double>::infinity(), "rasters");  // GDAL reads what it needs
#ifdef GRANFLOW_WITH_GDAL
  return read_gdal(path);
#else
  throw InputError(where(path) + "this build reads only ESRI ASCII grids (.asc): GDAL was not found when it was "
                                 "built (install libgdal-dev and rebuild), or convert the raster with "
                                 "gdal_translate -of AAIGrid");
#endif
}

}  // namespace granflow::io
