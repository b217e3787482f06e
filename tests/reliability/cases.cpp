// The bad inputs, one line each. Every case starts from default_files() (a good parameter set
// p.toml, a good element test t.toml, a good rate table and lab CSV) and changes one thing.
// To add a case for a new command: one line {name, {files}, {argv}, exit code, {substrings}};
// e.g. {"calib_unknown_key", {{"job.toml", "..."}}, {"calibrate", "job.toml"}, 2, {"job.toml:3", "..."}}.
#include "harness.hpp"

#include <granflow/mpm/checkpoint.hpp>
#include <granflow/mpm/mesh.hpp>

namespace reliability {

namespace {

// Line numbers below refer to these texts.
const std::string kParams =
    "name = \"reliability base set\"\n"  // 1
    "[collisional]\n"                    // 2
    "rho_p = 1050\n"                     // 3
    "d = 1.0e-3\n"                       // 4
    "e_sd = 0.92\n"                      // 5
    "V_m = 0.4\n"                        // 6
    "eps_n = 0.7\n"                      // 7
    "mu_p = 0.1\n"                       // 8
    "[frictional]\n"                     // 9
    "K0 = 120\n"                         // 10
    "nu = 0.235\n"                       // 11
    "n = 0.5\n"                          // 12
    "phi_c_deg = 23\n"                   // 13
    "e_ref = 0.910\n"                    // 14
    "lambda_c = 0.122\n"                 // 15
    "xi = 0.71\n"                        // 16
    "A_d = 0.5\n"                        // 17
    "k_p = 0.001\n"                      // 18
    "n_p = 1\n"                          // 19
    "n_d = 1\n"                          // 20
    "p_at = 101.3e3\n"                   // 21
    "[initial]\n"                        // 22
    "e0 = [0.99, 1.02]\n"                // 23
    "T0 = 1.0e-15\n";                    // 24

const std::string kTest =
    "params = \"p.toml\"\n"                   // 1
    "[test]\n"                                // 2
    "path = \"undrained_simple_shear\"\n"     // 3
    "programme = \"constant\"\n"              // 4
    "rate = 10.0\n"                           // 5
    "duration = 0.01\n"                       // 6
    "e0 = 0.99\n"                             // 7
    "sigma_v0 = 500.0\n"                      // 8
    "outputs = 3\n";                          // 9

const std::string kTableTest =
    "params = \"p.toml\"\n"          // 1
    "[test]\n"                       // 2
    "programme = \"table\"\n"        // 3
    "rate_file = \"rates.csv\"\n"    // 4
    "outputs = 3\n";                 // 5

const std::string kRates = "time,rate\n0,10\n0.005,20\n0.01,20\n";
const std::string kLab = "# triaxial test\nstrain,q\n0,0\n0.01,120\n0.02,180\n";

const std::string kScene =
    "name = \"reliability scene\"\n"       // 1
    "[grid]\n"                              // 2
    "origin = [0.0, 0.0]\n"                 // 3
    "size = [0.2, 0.1]\n"                   // 4
    "h = 0.02\n"                            // 5
    "[particles]\n"                         // 6
    "per_cell = 4\n"                        // 7
    "[time]\n"                              // 8
    "dt = 1e-4\n"                           // 9
    "[material]\n"                          // 10
    "parameters = \"column_collapse\"\n"    // 11
    "model = \"frictional\"\n"              // 12
    "[[body]]\n"                            // 13
    "min = [0.0, 0.0]\n"                    // 14
    "max = [0.1, 0.06]\n"                   // 15
    "[[wall]]\n"                            // 16
    "side = \"y-\"\n"                       // 17
    "[[stage]]\n"                           // 18
    "duration = 0.002\n"                    // 19
    "[output]\n"                            // 20
    "series_dt = 0.001\n";                  // 21

// A 3D scene on a terrain raster (dem.asc: 6 x 6 cells of 25 mm, ground at y = 0.02 m).
const std::string kTerrainScene =
    "name = \"reliability terrain\"\n"          // 1
    "[grid]\n"                                  // 2
    "dim = 3\n"                                 // 3
    "origin = [0.0, 0.0, 0.0]\n"                // 4
    "size = [0.1, 0.1, 0.1]\n"                  // 5
    "h = 0.02\n"                                // 6
    "[particles]\n"                             // 7
    "per_cell = 8\n"                            // 8
    "[time]\n"                                  // 9
    "dt = 1e-4\n"                               // 10
    "[material]\n"                              // 11
    "parameters = \"column_collapse\"\n"        // 12
    "model = \"frictional\"\n"                  // 13
    "[terrain]\n"                               // 14
    "file = \"dem.asc\"\n"                      // 15
    "origin = [500000.0, 4000000.0, 100.0]\n"   // 16
    "mu = 0.3\n"                                // 17
    "[[body]]\n"                                // 18
    "min = [0.02, 0.04, 0.02]\n"                // 19
    "max = [0.06, 0.08, 0.06]\n"                // 20
    "[[stage]]\n"                               // 21
    "duration = 0.002\n"                        // 22
    "[output]\n"                                // 23
    "series_dt = 0.001\n";                      // 24

// A 3D scene of a body inside a mesh (m.stl: mesh_cube(), a 4 cm cube at 2 to 6 cm).
const std::string kMeshScene =
    "name = \"reliability mesh\"\n"       // 1
    "[grid]\n"                              // 2
    "dim = 3\n"                             // 3
    "origin = [0.0, 0.0, 0.0]\n"            // 4
    "size = [0.1, 0.1, 0.1]\n"              // 5
    "h = 0.02\n"                            // 6
    "[particles]\n"                         // 7
    "per_cell = 8\n"                        // 8
    "[time]\n"                              // 9
    "dt = 1e-4\n"                           // 10
    "[material]\n"                          // 11
    "parameters = \"column_collapse\"\n"    // 12
    "model = \"frictional\"\n"              // 13
    "[[wall]]\n"                            // 14
    "side = \"y-\"\n"                       // 15
    "[[body]]\n"                            // 16
    "mesh = \"m.stl\"\n"                    // 17
    "[[stage]]\n"                           // 18
    "duration = 0.002\n"                    // 19
    "[output]\n"                            // 20
    "series_dt = 0.001\n";                  // 21

// An ASCII STL of the box [lo, hi]^3 (lo, hi per axis equal), triangles `drop` left out and
// `flip` turned, a second box `shift` along the diagonal when nonzero; `nan_vertex` replaces the
// first vertex line.
std::string mesh_cube(double lo = 0.02, double hi = 0.06, int drop = -1, int flip = -1, double shift = 0,
                      const std::string& nan_vertex = "") {
  const int q[6][4][3] = {{{0, 0, 0}, {0, 0, 1}, {0, 1, 1}, {0, 1, 0}}, {{1, 0, 0}, {1, 1, 0}, {1, 1, 1}, {1, 0, 1}},
                          {{0, 0, 0}, {1, 0, 0}, {1, 0, 1}, {0, 0, 1}}, {{0, 1, 0}, {0, 1, 1}, {1, 1, 1}, {1, 1, 0}},
                          {{0, 0, 0}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}}, {{0, 0, 1}, {1, 0, 1}, {1, 1, 1}, {0, 1, 1}}};
  std::string s = "solid cube\n";
  int t = 0;
  for (double off : shift != 0 ? std::vector<double>{0, shift} : std::vector<double>{0})
    for (const auto& f : q)
      for (int half = 0; half < 2; ++half, ++t) {
        if (t == drop) continue;
        int c[3] = {0, half ? 2 : 1, half ? 3 : 2};
        if (t == flip) std::swap(c[1], c[2]);
        s += "facet normal 0 0 0\nouter loop\n";
        for (int k : c) {
          std::string v = "vertex";
          for (int d = 0; d < 3; ++d) v += " " + std::to_string((f[k][d] ? hi : lo) + off);
          s += (t == 0 && k == 0 && !nan_vertex.empty() ? nan_vertex : v) + "\n";
        }
        s += "endloop\nendfacet\n";
      }
  return s + "endsolid cube\n";
}
std::string MS(const std::string& from, const std::string& to) { return edit(kMeshScene, from, to); }

// The terrain raster: cell centres at scene x, z = -0.0125 to 0.1125 (row 0 the northern, z =
// 0.1125), NODATA at (row, col) where asked; the header is 6 lines, row r is line 7 + r.
std::string dem(int nodata_row = -1, int nodata_col = -1) {
  std::string s = "ncols 6\nnrows 6\nxllcorner 499999.975\nyllcorner 3999999.975\ncellsize 0.025\nNODATA_value -9999\n";
  for (int r = 0; r < 6; ++r)
    for (int c = 0; c < 6; ++c) s += (r == nodata_row && c == nodata_col ? "-9999" : "100.02") + std::string(c == 5 ? "\n" : " ");
  return s;
}

const std::string kJob =
    "params = \"collisional_element\"\n"    // 1
    "[[free]]\n"                            // 2
    "key = \"collisional.V_m\"\n"           // 3
    "lower = 0.2\n"                         // 4
    "upper = 0.5\n"                         // 5
    "[algorithm]\n"                         // 6
    "global = \"none\"\n"                   // 7
    "local_evaluations = 20\n"              // 8
    "[[experiments]]\n"                     // 9
    "name = \"dem\"\n"                      // 10
    "kind = \"steady_shear\"\n"             // 11
    "data = \"dem.csv\"\n"                  // 12
    "abscissa = \"nu\"\n"                   // 13
    "quantity = \"solid_fraction\"\n"       // 14
    "targets = { p = \"p\", s = \"tau\" }\n" // 15
    "[experiments.steady_shear]\n"          // 16
    "restitution_column = \"e_r\"\n";       // 17

const std::string kDem =
    "# steady shear, d = rho_p = gammadot = 1\n"  // 1
    "nu,p,s,T,e_r\n"                              // 2
    "0.30,0.38,0.16,0.43,0.7\n"                   // 3
    "0.40,0.70,0.31,0.33,0.7\n"                   // 4
    "0.50,1.84,0.81,0.25,0.7\n";                  // 5

// An mpm_scene calibration of scene.toml (one stage of 0.002 s) against front.csv.
const std::string kSceneJob =
    "params = \"column_collapse\"\n"                                                   // 1
    "[[free]]\nkey = \"frictional.phi_c_deg\"\nlower = 15.0\nupper = 25.0\n"           // 2-5
    "[algorithm]\nglobal = \"none\"\nlocal_evaluations = 2\n"                         // 6-8
    "[[experiments]]\nkind = \"mpm_scene\"\nname = \"column\"\nscene = \"scene.toml\"\n"  // 9-12
    "backend = \"cpu\"\nprogress = false\n"                                            // 13-14
    "[experiments.front]\ndata = \"front.csv\"\n";                                     // 15-16

// kScene with two materials (lines 10-17) and two bodies (18-25), the wall from line 26 on.
const std::string kTwoMaterials = edit(edit(kScene,
    "[material]\nparameters = \"column_collapse\"\nmodel = \"frictional\"\n",
    "[[material]]\nname = \"strong\"\nparameters = \"column_collapse\"\nmodel = \"frictional\"\n"    // 10-13
    "[[material]]\nname = \"weak\"\nparameters = \"column_collapse\"\nmodel = \"frictional\"\n"),    // 14-17
    "[[body]]\nmin = [0.0, 0.0]\nmax = [0.1, 0.06]\n",
    "[[body]]\nmin = [0.0, 0.0]\nmax = [0.1, 0.03]\nmaterial = \"weak\"\n"                                // 18-21
    "[[body]]\nmin = [0.0, 0.03]\nmax = [0.1, 0.06]\nmaterial = \"strong\"\n");                          // 22-25

// Shorthands.
std::string P(const std::string& from, const std::string& to) { return edit(kParams, from, to); }
std::string T(const std::string& from, const std::string& to) { return edit(kTest, from, to); }
const std::vector<std::string> kEl = {"element", "t.toml", "--out", "out.csv"};
const std::vector<std::string> kTab = {"element", "table.toml", "--out", "out.csv"};
std::vector<std::string> el_set(const std::string& a) { return {"element", "t.toml", "--set", a, "--out", "out.csv"}; }
const std::vector<std::string> kLabArgs = {"@csv", "lab.csv", "strain,q", "strain"};
std::string S(const std::string& from, const std::string& to) { return edit(kScene, from, to); }
std::string J(const std::string& from, const std::string& to) { return edit(kJob, from, to); }
const std::vector<std::string> kMpm = {"mpm", "scene.toml", "--out", "o", "--no-png", "--quiet"};
const std::vector<std::string> kT3 = {"mpm", "t3.toml", "--out", "o", "--no-png", "--quiet"};
const std::vector<std::string> kRestart = {"mpm", "scene.toml", "--out", "o", "--no-png", "--quiet", "--restart"};
const std::vector<std::string> kCal = {"calibrate", "job.toml", "--out", "fit", "--no-plot", "--quiet"};
std::vector<std::string> mpm_with(std::vector<std::string> extra) {
  std::vector<std::string> a = kMpm;
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}
std::string M2(const std::string& from, const std::string& to) { return edit(kTwoMaterials, from, to); }
const std::vector<std::string> kCalForce = {"calibrate", "job.toml", "--out", "fit", "--no-plot", "--quiet", "--force"};
const std::vector<std::string> kMpmForce = {"mpm", "scene.toml", "--out", "o", "--no-png", "--quiet", "--force"};

// A valid checkpoint, but of another scene (its hash is not kScene's).
std::string foreign_checkpoint() {
  granflow::mpm::Checkpoint c;
  c.scene_hash = 0x5ca1ab1e;
  c.loop.dt = 1e-4;
  c.loop.series.push_back({});
  return granflow::mpm::encode_checkpoint(c);
}
std::string flip_byte(std::string s, size_t at) {
  s[at] = static_cast<char>(s[at] ^ 0x40);
  return s;
}
constexpr int kInput = 2;  // granflow's exit code for input errors

// A design file of 4 Halton members varying one key ([[vary]] at line 4, the range at line 6).
std::string design(const std::string& key, const std::string& range_line) {
  return "[design]\nmethod = \"halton\"\nmembers = 4\n[[vary]]\nkey = \"" + key + "\"\n" + range_line + "\n";
}
const std::vector<std::string> kEns = {"ensemble", "scene.toml", "d.toml", "--out", "o", "--no-png", "--quiet"};
std::vector<std::string> ens_with(std::vector<std::string> extra) {
  std::vector<std::string> a = kEns;
  a.insert(a.end(), extra.begin(), extra.end());
  return a;
}

}  // namespace

Files default_files() {
  return {{"p.toml", kParams}, {"t.toml", kTest},     {"table.toml", kTableTest}, {"rates.csv", kRates},
          {"lab.csv", kLab},   {"scene.toml", kScene}, {"job.toml", kJob},         {"dem.csv", kDem},
          {"t3.toml", kTerrainScene}, {"dem.asc", dem()}};
}

// Bodies and obstacles from meshes (docs/mpm_meshes.md); only where the build reads meshes.
std::vector<Case> mesh_cases() {
  const std::vector<std::string> m3 = {"mpm", "m3.toml", "--out", "o", "--no-png", "--quiet"};
  const std::string plate = "[[obstacle]]\nkind = \"mesh\"\nname = \"plate\"\nmesh = \"p.stl\"\n";  // lines 22-25
  return {
      {"mesh_open", {{"m3.toml", kMeshScene}, {"m.stl", mesh_cube(0.02, 0.06, 3)}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "m.stl: is not closed: 3 bad edges", "belongs to one triangle only", "from (0.06, 0.02, 0.02)"}},
      {"mesh_flipped_face", {{"m3.toml", kMeshScene}, {"m.stl", mesh_cube(0.02, 0.06, -1, 3)}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "m.stl: is not consistently oriented: 3 bad edges", "a flipped face"}},
      {"mesh_self_intersecting", {{"m3.toml", kMeshScene}, {"m.stl", mesh_cube(0.02, 0.06, -1, -1, 0.02)}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "m.stl: is self-intersecting: 18 pairs of triangles cross or overlap", "at (0.06, 0.04, 0.04)"}},
      {"mesh_empty", {{"m3.toml", kMeshScene}, {"m.stl", ""}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "m.stl: is empty (0 bytes): an empty mesh"}},
      {"mesh_no_triangle", {{"m3.toml", kMeshScene}, {"m.stl", "solid empty\nendsolid empty\n"}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "m.stl: "}},
      {"mesh_folder", {{"m3.toml", MS("\"m.stl\"", "\".\"")}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", ".: is a folder, not a mesh file"}},
      {"mesh_missing_file", {{"m3.toml", kMeshScene}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "m.stl: no such file"}},
      {"mesh_nan_vertex", {{"m3.toml", kMeshScene}, {"m.stl", mesh_cube(0.02, 0.06, -1, -1, 0, "vertex nan 0.02 0.02")}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "m.stl: vertex 0", "is not a finite number (NaN or infinite)"}},
      {"mesh_all_degenerate", {{"m3.toml", kMeshScene}, {"m.stl", "solid s\nfacet normal 0 0 0\nouter loop\nvertex 0.02 0.02 0.02\nvertex 0.04 0.02 0.02\nvertex 0.06 0.02 0.02\nendloop\nendfacet\nendsolid s\n"}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "m.stl: all 1 triangles are degenerate (no area)"}},
      {"mesh_out_of_grid", {{"m3.toml", MS("mesh = \"m.stl\"\n", "mesh = \"m.stl\"\noffset = [0.08, 0.0, 0.0]\n")}, {"m.stl", mesh_cube()}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "the placed mesh (x [0.1, 0.14], y [0.02, 0.06], z [0.02, 0.06]) lies outside the grid", "move it (offset)"}},
      {"mesh_in_millimetres", {{"m3.toml", kMeshScene}, {"m.stl", mesh_cube(20, 60)}}, m3, kInput, {"m3.toml:17", "'body[0].mesh'", "lies outside the grid", "400 times the grid's size", "scale = 0.001"}},
      {"mesh_bad_scale", {{"m3.toml", MS("mesh = \"m.stl\"\n", "mesh = \"m.stl\"\nscale = -1\n")}, {"m.stl", mesh_cube()}}, m3, kInput, {"m3.toml:18", "'body[0].scale'", "> 0"}},
      {"mesh_in_2d_scene", {{"scene.toml", S("min = [0.0, 0.0]\nmax = [0.1, 0.06]\n", "mesh = \"m.stl\"\n")}, {"m.stl", mesh_cube()}}, kMpm, kInput, {"scene.toml:14", "'body[0].mesh'", "meshes need grid.dim = 3"}},
      {"mesh_obstacle_in_2d_scene", {{"scene.toml", kScene + plate}, {"p.stl", mesh_cube()}}, kMpm, kInput, {"'obstacle[0].kind'", "\"mesh\" needs grid.dim = 3"}},
      {"mesh_obstacle_thin", {{"m3.toml", kMeshScene + plate}, {"m.stl", mesh_cube()}, {"p.stl", mesh_cube(0.065, 0.095)}}, m3, kInput, {"m3.toml:25", "'obstacle[0].mesh'", "obstacle 'plate' is 0.03 m thick along x at (", "less than two grid cells (2 h = 0.04 m)"}},
      {"mesh_in_ensemble", {{"m3.toml", kMeshScene}, {"m.stl", mesh_cube()}, {"d.toml", design("frictional.phi_c_deg", "range = [18.0, 22.0]")}}, {"ensemble", "m3.toml", "d.toml", "--out", "o", "--no-png", "--quiet"}, kInput, {"m3.toml:17: 'body[0].mesh': ensembles take no meshes; a scene with a mesh runs alone"}},
  };
}

std::vector<Case> all_cases() {
  std::vector<Case> mesh = granflow::mpm::mesh_reader_available() ? mesh_cases() : std::vector<Case>{};
  std::vector<Case> cases = {
      // ---- parameter-set TOML ------------------------------------------------------------
      {"param_typo_missing_key", {{"p.toml", P("phi_c_deg", "phi_c_dg")}}, kEl, kInput, {"p.toml", "'frictional.phi_c_deg'", "required key is missing", "frictional.phi_c_dg", "a typo?"}},
      {"param_unknown_key", {{"p.toml", P("mu_p = 0.1\n", "mu_p = 0.1\ncolour = 1\n")}}, kEl, kInput, {"p.toml:9", "unknown key 'collisional.colour'", "allowed here"}},
      {"param_unknown_table", {{"p.toml", P("[initial]", "[inital]")}}, kEl, kInput, {"p.toml:22", "unknown key 'inital'"}},
      {"param_missing_K0", {{"p.toml", drop_line(kParams, "K0 =")}}, kEl, kInput, {"p.toml", "'frictional.K0'", "required key is missing", "> 0"}},
      {"param_string_for_number", {{"p.toml", P("rho_p = 1050", "rho_p = \"1050\"")}}, kEl, kInput, {"p.toml:3", "'collisional.rho_p'", "expected a number, got a string"}},
      {"param_array_for_number", {{"p.toml", P("d = 1.0e-3", "d = [1.0e-3]")}}, kEl, kInput, {"p.toml:4", "'collisional.d'", "expected a number, got an array"}},
      {"param_nan", {{"p.toml", P("K0 = 120", "K0 = nan")}}, kEl, kInput, {"p.toml:10", "'frictional.K0'", "finite"}},
      {"param_inf", {{"p.toml", P("rho_p = 1050", "rho_p = inf")}}, kEl, kInput, {"p.toml:3", "'collisional.rho_p'", "finite"}},
      {"param_negative_density", {{"p.toml", P("rho_p = 1050", "rho_p = -1050")}}, kEl, kInput, {"p.toml:3", "'collisional.rho_p'", "must be > 0", "-1050"}},
      {"param_negative_diameter", {{"p.toml", P("d = 1.0e-3", "d = -1.0e-3")}}, kEl, kInput, {"p.toml:4", "'collisional.d'", "must be > 0"}},
      {"param_zero_diameter", {{"p.toml", P("d = 1.0e-3", "d = 0")}}, kEl, kInput, {"p.toml:4", "'collisional.d'", "must be > 0"}},
      {"param_restitution_above_1", {{"p.toml", P("eps_n = 0.7", "eps_n = 1.2")}}, kEl, kInput, {"p.toml:7", "'collisional.eps_n'", "in [0, 1]"}},
      {"param_restitution_negative", {{"p.toml", P("eps_n = 0.7", "eps_n = -0.1")}}, kEl, kInput, {"p.toml:7", "'collisional.eps_n'", "in [0, 1]"}},
      {"param_e0_above_range", {{"p.toml", P("e0 = [0.99, 1.02]", "e0 = [0.99, 3.0]")}}, kEl, kInput, {"p.toml:23", "'initial.e0'", "in (0, 2.97)"}},
      {"param_e0_zero", {{"p.toml", P("e0 = [0.99, 1.02]", "e0 = 0")}}, kEl, kInput, {"p.toml:23", "'initial.e0'", "in (0, 2.97)"}},
      {"param_Vs_above_Vsd", {{"p.toml", P("e0 = [0.99, 1.02]", "e0 = [0.99, 0.5]")}}, kEl, kInput, {"p.toml", "initial.e0", "at or above V_sd", "must exceed e_sd"}},
      {"param_esd_rounds_Vsd_to_1", {{"p.toml", P("e_sd = 0.92", "e_sd = 5e-324")}}, kEl, kInput, {"p.toml:5", "'collisional.e_sd'", "V_sd = 1/(1 + e_sd) = 1", "below 1"}},
      {"param_Vsd_not_below_1", {{"p.toml", P("e_sd = 0.92", "V_sd = 1.0")}}, kEl, kInput, {"p.toml:5", "'collisional.V_sd'", "in (0, 1)"}},
      {"param_Vm_above_Vsd", {{"p.toml", P("V_m = 0.4", "V_m = 0.6")}}, kEl, kInput, {"p.toml:6", "'collisional.V_m'", "below V_sd"}},
      {"param_both_esd_and_Vsd", {{"p.toml", P("e_sd = 0.92", "e_sd = 0.92\nV_sd = 0.52")}}, kEl, kInput, {"p.toml", "exactly one of e_sd or V_sd"}},
      {"param_friction_angle_90", {{"p.toml", P("phi_c_deg = 23", "phi_c_deg = 90")}}, kEl, kInput, {"p.toml:13", "'frictional.phi_c_deg'", "in (0, 90)"}},
      {"param_friction_angle_negative", {{"p.toml", P("phi_c_deg = 23", "phi_c_deg = -5")}}, kEl, kInput, {"p.toml:13", "'frictional.phi_c_deg'", "in (0, 90)"}},
      {"param_poisson_ratio_half", {{"p.toml", P("nu = 0.235", "nu = 0.5")}}, kEl, kInput, {"p.toml:11", "'frictional.nu'", "in (-1, 0.5)"}},
      {"param_integer_as_float", {{"p.toml", kParams + "[numerics]\nmax_substeps = 1.5\n"}}, kEl, kInput, {"p.toml:26", "'numerics.max_substeps'", "expected an integer"}},
      {"param_table_is_value", {{"p.toml", "initial = 5\n" + kParams.substr(0, kParams.find("[initial]"))}}, kEl, kInput, {"p.toml:1", "'initial'", "expected a table, got an integer"}},
      {"param_truncated", {{"p.toml", kParams.substr(0, kParams.find("xi = ") + 4)}}, kEl, kInput, {"p.toml:16", "TOML syntax error"}},
      {"param_duplicate_key", {{"p.toml", P("K0 = 120", "K0 = 120\nK0 = 130")}}, kEl, kInput, {"p.toml:11", "TOML syntax error", "K0"}},
      {"param_empty_file", {{"p.toml", ""}}, kEl, kInput, {"p.toml", "needs a [frictional] or a [collisional] table"}},
      {"param_binary_garbage", {{"p.toml", std::string("\x7f" "ELF\x02\x01\x01\0\0\0", 10)}}, kEl, kInput, {"p.toml:1", "TOML syntax error"}},
      {"param_no_such_set", {}, {"element", "t.toml", "--params", "elemnt_test", "--out", "out.csv"}, kInput, {"elemnt_test", "no such file", "shipped sets:", "element_test"}},
      {"param_name_too_long", {}, {"element", "t.toml", "--params", std::string(300, 'p'), "--out", "out.csv"}, kInput, {"pppp: no such file, and no parameter set of that name"}},
      {"param_is_directory", {{"sub/x", ""}}, {"element", "t.toml", "--params", "sub", "--out", "out.csv"}, kInput, {"sub", "not a regular file"}},
      {"param_lambda_negative", {{"p.toml", P("lambda_c = 0.122", "lambda_c = -0.1")}}, kEl, kInput, {"p.toml:15", "'frictional.lambda_c'", ">= 0"}},

      // ---- element-test TOML -----------------------------------------------------------------
      {"test_unknown_key", {{"t.toml", T("sigma_v0", "sigma_v")}}, kEl, kInput, {"t.toml:8", "unknown key 'test.sigma_v'", "allowed here", "sigma_v0"}},
      {"test_unknown_top_level_key", {{"t.toml", edit(kTest, "params =", "parms =")}}, kEl, kInput, {"t.toml:1", "unknown key 'parms'", "allowed at top level"}},
      {"test_bad_path_choice", {{"t.toml", T("undrained_simple_shear", "triaxial")}}, kEl, kInput, {"t.toml:3", "'test.path'", "must be one of", "'drained_triaxial'"}},
      {"test_rtol_above_1", {{"t.toml", kTest + "rtol = 2\n"}}, kEl, kInput, {"t.toml:10", "'test.rtol'", "in (0, 1)"}},
      {"test_missing_test_table", {{"t.toml", "params = \"p.toml\"\n"}}, kEl, kInput, {"t.toml", "'test'", "required table [test] is missing"}},
      {"test_acceleration_missing", {{"t.toml", T("\"constant\"", "\"acceleration\"")}}, kEl, kInput, {"t.toml", "'test.acceleration'", "required key is missing"}},
      {"test_dt_with_cvode", {{"t.toml", kTest + "dt = 1e-3\n"}}, kEl, kInput, {"t.toml:10", "'test.dt'", "only with solver = \"incremental\""}},
      {"test_rate_negative", {{"t.toml", T("rate = 10.0", "rate = -1")}}, kEl, kInput, {"t.toml:5", "'test.rate'", ">= 0"}},
      {"test_rate_zero_constant", {{"t.toml", T("rate = 10.0", "rate = 0")}}, kEl, kInput, {"t.toml:5", "'test.rate'", "must be > 0"}},
      {"test_duration_inf", {{"t.toml", T("duration = 0.01", "duration = inf")}}, kEl, kInput, {"t.toml:6", "'test.duration'", "finite"}},
      {"test_e0_out_of_range", {{"t.toml", T("e0 = 0.99", "e0 = 3.5")}}, kEl, kInput, {"t.toml:7", "'test.e0'", "in (0, 2.97)"}},
      {"test_e0_Vs_above_Vsd", {{"t.toml", T("e0 = 0.99", "e0 = 0.6")}}, kEl, kInput, {"t.toml: 'test.e0' (V_sd from p.toml)", "e0 = 0.6", "at or above V_sd", "must exceed e_sd"}},
      {"test_outputs_too_few", {{"t.toml", T("outputs = 3", "outputs = 1")}}, kEl, kInput, {"t.toml:9", "'test.outputs'", "in [2, "}},
      {"test_outputs_not_integer", {{"t.toml", T("outputs = 3", "outputs = \"many\"")}}, kEl, kInput, {"t.toml:9", "'test.outputs'", "expected an integer"}},
      {"test_overrides_not_array", {{"t.toml", edit(kTest, "[test]", "overrides = \"frictional.K0=1\"\n[test]")}}, kEl, kInput, {"t.toml:2", "'overrides'", "array of strings"}},
      {"test_hold_after_duration", {{"t.toml", T("\"constant\"", "\"acceleration\"\nacceleration = 5\nhold = 1")}}, kEl, kInput, {"t.toml", "'test.hold'", "shorter than duration"}},
      {"test_stress_outside_yield", {{"t.toml", kTest + "k0 = 5\n"}}, kEl, kInput, {"t.toml", "outside the yield surface"}},
      {"test_sweep_min_above_max", {{"t.toml", edit(edit(kTest, "programme = \"constant\"", "programme = \"sweep\"\nrate_min = 10\nrate_max = 1"), "duration = 0.01\n", "")}}, kEl, kInput, {"t.toml", "'test.rate_max'", "must exceed rate_min"}},
      {"test_sweep_too_many_rates", {{"t.toml", edit(edit(kTest, "programme = \"constant\"", "programme = \"sweep\"\nrate_min = 5e-324\nrate_max = 1000\nrates_per_decade = 1000"), "duration = 0.01\n", "")}}, kEl, kInput, {"t.toml", "'test.rate_max'", "would need more than 100000 rates"}},
      {"test_file_missing", {}, {"element", "nope.toml", "--out", "out.csv"}, kInput, {"nope.toml", "cannot open file"}},
      {"test_file_is_directory", {{"sub/x", ""}}, {"element", "sub", "--out", "out.csv"}, kInput, {"sub", "not a regular file"}},
      {"test_rate_file_name_too_long", {{"table.toml", edit(kTableTest, "rates.csv", std::string(300, 'r') + ".csv")}}, kTab, kInput, {"rrrr.csv: cannot open file (File name too long)"}},
      {"test_truncated", {{"t.toml", kTest.substr(0, kTest.find("rate = 10") + 6)}}, kEl, kInput, {"t.toml:5", "TOML syntax error"}},
      {"test_step_budget", {{"t.toml", kTest + "max_steps = 3\n"}}, kEl, 1, {"CV_TOO_MUCH_WORK", "at t = ", "test.max_steps = 3"}},
      {"test_step_budget_incremental", {{"t.toml", kTest + "solver = \"incremental\"\ndt = 1e-4\nmax_steps = 3\n"}}, kEl, 1, {"incremental update", "test.max_steps = 3", "at t = "}},

      {"run_voids_vanish", {{"t.toml", "params = \"p.toml\"\n[test]\npath = \"isotropic\"\nmodel = \"frictional\"\nrate = 1.0\nduration = 1.0\ne0 = 0.99\n"}}, kEl, 1, {"CVODE failed", "at t = 0.2293", "allowed: 0 < e < 2.97"}},  // ln(1.99)/3

      // ---- --set overrides ---------------------------------------------------------------------
      {"set_unknown_key", {}, el_set("frictional.phi_c=31"), kInput, {"--set 'frictional.phi_c=31': unknown key 'frictional.phi_c'", "allowed here", "phi_c_deg"}},
      {"set_no_section", {}, el_set("phi_c_deg=31"), kInput, {"--set 'phi_c_deg=31'", "expected section.key=value"}},
      {"set_not_a_number", {}, el_set("frictional.phi_c_deg=abc"), kInput, {"--set 'frictional.phi_c_deg=abc'"}},
      {"set_out_of_range", {}, el_set("frictional.phi_c_deg=95"), kInput, {"--set 'frictional.phi_c_deg=95': 'frictional.phi_c_deg': must be in (0, 90), got 95"}},
      {"set_negative_density", {}, el_set("collisional.rho_p=-5"), kInput, {"'collisional.rho_p'", "must be > 0"}},
      {"set_unknown_section", {}, el_set("mpm.ppc=4"), kInput, {"--set 'mpm.ppc=4'", "no [mpm] table"}},
      {"set_nan", {}, el_set("frictional.K0=nan"), kInput, {"'frictional.K0'", "finite"}},
      {"set_string_value", {}, el_set("collisional.eps_n=\"0.5\""), kInput, {"'collisional.eps_n'", "expected a number, got a string"}},
      {"set_empty_value", {}, el_set("frictional.K0="), kInput, {"--set 'frictional.K0='"}},
      {"set_bare_word_is_a_string", {}, el_set("frictional.K0=high"), kInput, {"--set 'frictional.K0=high': 'frictional.K0': expected a number, got a string"}},
      {"set_in_test_file", {{"t.toml", edit(kTest, "[test]", "overrides = [\"frictional.xi=-1\"]\n[test]")}}, kEl, kInput, {"t.toml: overrides 'frictional.xi=-1': 'frictional.xi': must be > 0, got -1"}},

      // ---- CLI arguments and output files ---------------------------------------------------
      {"cli_unknown_command", {}, {"elemnt", "t.toml"}, 106, {"A subcommand is required", "command line: elemnt t.toml"}},  // CLI11's message; see docs/reliability.md
      {"cli_unknown_option", {}, {"element", "t.toml", "--forse"}, 109, {"--forse"}},
      {"cli_out_without_value", {}, {"element", "t.toml", "--out"}, 114, {"--out"}},
      {"cli_no_command", {}, {}, 106, {"subcommand"}},
      {"out_exists_without_force", {{"out.csv", "previous result\n"}}, kEl, kInput, {"out.csv", "file exists", "--force"}},
      {"out_directory_missing", {}, {"element", "t.toml", "--out", "no/such/dir/out.csv"}, kInput, {"no/such/dir", "does not exist"}},
      {"out_failed_run_keeps_old_result", {{"out.csv", "previous result\n"}, {"t.toml", kTest + "max_steps = 3\n"}}, {"element", "t.toml", "--out", "out.csv", "--force"}, 1, {"CV_TOO_MUCH_WORK"}},
      {"out_is_directory", {{"res/x", ""}}, {"element", "t.toml", "--out", "res", "--force"}, kInput, {"res", "is a directory"}},

      // ---- rate-programme CSV (programme = "table") ------------------------------------------
      {"rates_unsorted", {{"rates.csv", "time,rate\n0,10\n0.006,20\n0.004,20\n0.01,1\n"}}, kTab, kInput, {"rates.csv:4", "'time' must not decrease"}},
      {"rates_non_numeric", {{"rates.csv", "time,rate\n0,10\n0.005,fast\n0.01,20\n"}}, kTab, kInput, {"rates.csv:3", "column 'rate'", "'fast' is not a number"}},
      {"rates_nan", {{"rates.csv", "time,rate\n0,10\n0.005,nan\n0.01,20\n"}}, kTab, kInput, {"rates.csv:3", "column 'rate'", "not a finite number"}},
      {"rates_overflow", {{"rates.csv", "time,rate\n0,10\n0.005,1e999\n0.01,20\n"}}, kTab, kInput, {"rates.csv:3", "column 'rate'", "not a finite number"}},
      {"rates_empty_file", {{"rates.csv", ""}}, kTab, kInput, {"rates.csv: the file is empty", "(time,rate)"}},
      {"rates_is_directory", {{"rates.csv", kAbsent}, {"rates.csv/x", ""}}, kTab, kInput, {"rates.csv", "not a regular file"}},
      {"rates_header_only", {{"rates.csv", "time,rate\n"}}, kTab, kInput, {"rates.csv", "no data rows"}},
      {"rates_semicolons", {{"rates.csv", "time;rate\n0;10\n0.01;20\n"}}, kTab, kInput, {"rates.csv", "delimiter must be a comma"}},
      {"rates_missing_column", {{"rates.csv", "time,rat\n0,10\n0.01,20\n"}}, kTab, kInput, {"rates.csv", "rate", "Header found: 'time,rat'"}},
      {"rates_negative", {{"rates.csv", "time,rate\n0,10\n0.01,-2\n"}}, kTab, kInput, {"rates.csv:3", "'rate' must be >= 0"}},
      {"rates_not_from_zero", {{"rates.csv", "time,rate\n0.001,10\n0.01,20\n"}}, kTab, kInput, {"rates.csv:2", "must start at time 0"}},
      {"rates_single_row", {{"rates.csv", "time,rate\n0,10\n"}}, kTab, kInput, {"rates.csv", "at least 2 rows"}},
      {"rates_short_row", {{"rates.csv", "time,rate\n0,10\n0.01\n"}}, kTab, kInput, {"rates.csv:3"}},
      {"rates_long_row", {{"rates.csv", "time,rate\n0,10\n0.01,20,30\n"}}, kTab, kInput, {"rates.csv:3"}},
      {"rates_unterminated_quote", {{"rates.csv", "time,rate\n0,10\n\"0.01,20\n"}}, kTab, kInput, {"rates.csv:3"}},
      {"rates_file_missing", {{"rates.csv", kAbsent}}, kTab, kInput, {"rates.csv", "cannot open file"}},
      {"rates_duration_past_table", {{"table.toml", kTableTest + "duration = 1\n"}}, kTab, kInput, {"table.toml:6", "'test.duration'", "past the last time"}},

      // ---- lab CSV (the reader calibration uses; run through granflow_csv_probe) --------------
      {"lab_duplicated_abscissa", {{"lab.csv", "strain,q\n0,0\n0.01,120\n0.01,130\n"}}, kLabArgs, kInput, {"lab.csv:4", "column 'strain' must increase strictly"}},
      {"lab_unsorted_abscissa", {{"lab.csv", "strain,q\n0,0\n0.02,120\n0.01,130\n"}}, kLabArgs, kInput, {"lab.csv:4", "must increase strictly"}},
      {"lab_non_numeric", {{"lab.csv", "strain,q\n0,0\n0.01,12O\n"}}, kLabArgs, kInput, {"lab.csv:3", "column 'q'", "'12O' is not a number"}},
      {"lab_empty_cell", {{"lab.csv", "strain,q\n0,0\n0.01,\n"}}, kLabArgs, kInput, {"lab.csv:3", "column 'q'", "empty cell"}},
      {"lab_tab_delimited", {{"lab.csv", "strain\tq\n0\t0\n0.01\t120\n"}}, kLabArgs, kInput, {"lab.csv", "delimiter must be a comma"}},
      {"lab_empty_file", {{"lab.csv", ""}}, kLabArgs, kInput, {"lab.csv: the file is empty", "(strain,q)"}},
      {"lab_only_comments", {{"lab.csv", "# nothing measured\n"}}, kLabArgs, kInput, {"lab.csv: the file is empty"}},
      {"lab_inf", {{"lab.csv", "strain,q\n0,0\n0.01,inf\n"}}, kLabArgs, kInput, {"lab.csv:3", "not a finite number"}},
      {"lab_truncated_row", {{"lab.csv", "strain,q\n0,0\n0.01"}}, kLabArgs, kInput, {"lab.csv:3"}},
      {"lab_stray_strain_in_data_programme", {{"t.toml", "params = \"p.toml\"\n[test]\npath = \"drained_triaxial\"\nprogramme = \"data\"\ndata_file = \"lab.csv\"\ncontrol_column = \"strain\"\nrate = 1.0\ne0 = 0.99\nsigma_v0 = 500.0\n"}, {"lab.csv", "strain,q\n0,0\n0.01,120\n1e300,130\n"}}, kEl, kInput, {"lab.csv:4", "column 'strain': 1e+300 is not a strain"}},
      {"lab_file_missing", {{"lab.csv", kAbsent}}, kLabArgs, kInput, {"lab.csv", "cannot open file"}},

      // ---- calibration job (granflow calibrate) ----------------------------------------------
      {"calib_unknown_key", {{"job.toml", "colour = 1\n" + kJob}}, kCal, kInput, {"job.toml:1", "unknown key 'colour'", "allowed here", "params"}},
      {"calib_unknown_experiment_key", {{"job.toml", J("abscissa = ", "absissa = ")}}, kCal, kInput, {"job.toml:9", "'experiments[0].abscissa'", "required key is missing", "experiments[0].absissa", "a typo?"}},
      {"calib_missing_data_file", {{"dem.csv", kAbsent}}, kCal, kInput, {"job.toml:12", "'experiments[0].data'", "no such file", "dem.csv"}},
      {"calib_bounds_reversed", {{"job.toml", J("lower = 0.2\nupper = 0.5", "lower = 0.5\nupper = 0.2")}}, kCal, kInput, {"job.toml:5", "'free[0].upper'", "must exceed lower = 0.5"}},
      {"calib_start_outside_bounds", {{"job.toml", J("upper = 0.5\n", "upper = 0.5\nstart = 0.7\n")}}, kCal, kInput, {"job.toml:6", "'free[0].start'", "0.7", "outside [lower, upper] = [0.2"}},
      {"calib_unknown_parameter", {{"job.toml", J("collisional.V_m", "collisional.V_x")}}, kCal, kInput, {"job.toml:3", "'free[0].key'", "collisional.V_x"}},
      {"calib_no_free_parameter", {{"job.toml", J("[[free]]\nkey = \"collisional.V_m\"\nlower = 0.2\nupper = 0.5\n", "")}}, kCal, kInput, {"job.toml", "'free'", "at least one [[free]]"}},
      {"calib_unknown_algorithm", {{"job.toml", J("global = \"none\"", "global = \"none\"\nlocal = \"LN_FOO\"")}}, kCal, kInput, {"job.toml:8", "'algorithm.local'", "must be one of", "'LN_BOBYQA'", "LN_FOO"}},
      {"calib_kind_missing", {{"job.toml", J("kind = \"steady_shear\"\n", "")}}, kCal, kInput, {"job.toml", "'experiments[0].kind'", "required key is missing", "'steady_shear'"}},
      {"calib_data_non_numeric", {{"dem.csv", edit(kDem, "0.31", "abc")}}, kCal, kInput, {"dem.csv:4", "column 's'", "'abc' is not a number"}},
      {"calib_data_unsorted_abscissa", {{"dem.csv", edit(kDem, "0.50,", "0.35,")}}, kCal, kInput, {"dem.csv:5", "must increase strictly", "0.35 follows 0.4"}},
      {"calib_data_missing_column", {{"job.toml", J("s = \"tau\"", "shear = \"tau\"")}}, kCal, kInput, {"dem.csv", "needs column 'shear'", "header 'nu,p,s,T,e_r'"}},
      {"calib_job_missing", {}, {"calibrate", "nojob.toml", "--no-plot", "--quiet"}, kInput, {"nojob.toml", "cannot open file"}},
      {"calib_out_exists", {{"fit/old.txt", "previous fit\n"}}, kCal, kInput, {"fit", "output directory exists", "--force"}},
      {"calib_force_foreign_folder", {{"fit/old.txt", "not granflow's\n"}}, kCalForce, kInput, {"fit: not a granflow run folder (it has no granflow.manifest)", "--force replaces only folders granflow wrote"}},
      {"calib_out_is_a_file", {{"fit", "a file\n"}}, kCalForce, kInput, {"fit: is a file, not a folder"}},

      // ---- MPM scene (granflow mpm) ----------------------------------------------------------
      {"mpm_material_outside_grid", {{"scene.toml", S("max = [0.1, 0.06]", "max = [0.1, 0.5]")}}, kMpm, kInput, {"scene.toml:15", "'body[0].max'", "lies outside the grid [0, 0.1]", "grid.size"}},
      {"mpm_material_beyond_wall", {{"scene.toml", S("side = \"y-\"", "side = \"y-\"\nposition = 0.03")}}, kMpm, kInput, {"scene.toml:17", "'wall[0].side'", "lies beyond this wall (y <= 0.03 is held)"}},
      {"mpm_two_walls_one_side", {{"scene.toml", kScene + "[[wall]]\nside = \"y-\"\n"}}, kMpm, kInput, {"scene.toml:23", "'wall[1].side'", "second wall on side y-", "contradicts"}},
      {"mpm_wall_outside_grid", {{"scene.toml", S("side = \"y-\"", "side = \"y-\"\nposition = -1")}}, kMpm, kInput, {"scene.toml:18", "'wall[0].position'", "y = -1.000000 lies outside the grid [0.000000, 0.100000]"}},
      {"mpm_dt_above_stability_limit", {{"scene.toml", S("dt = 1e-4", "dt = 1e-2")}}, kMpm, kInput, {"scene.toml:9", "'time.dt'", "above the stability limit h / c_p"}},
      {"mpm_stop_at_rest_out_of_range", {{"scene.toml", S("dt = 1e-4", "dt = 1e-4\nstop_at_rest = 1.5")}}, kMpm, kInput, {"scene.toml:10", "'time.stop_at_rest'", "must be in (0, 1), got 1.5"}},
      {"mpm_rest_hold_without_stop_at_rest", {{"scene.toml", S("dt = 1e-4", "dt = 1e-4\nrest_hold = 0.1")}}, kMpm, kInput, {"scene.toml:10", "'time.rest_hold'", "only with time.stop_at_rest"}},
      {"mpm_grid_too_large", {{"scene.toml", S("h = 0.02", "h = 1e-6")}}, kMpm, kInput, {"scene.toml:5", "'grid.h'", "at most 400000000 nodes", "larger grid.h"}},
      {"mpm_unknown_shape", {{"scene.toml", S("h = 0.02", "h = 0.02\nshape = \"cubic\"")}}, kMpm, kInput, {"scene.toml:6", "'grid.shape'", "must be one of 'linear', 'quadratic', got 'cubic'"}},
      {"mpm_stage_negative_duration", {{"scene.toml", S("duration = 0.002", "duration = -0.1")}}, kMpm, kInput, {"scene.toml:19", "'stage[0].duration'", "must be > 0", "-0.1"}},
      {"mpm_unknown_key", {{"scene.toml", S("per_cell = 4", "per_cel = 4")}}, kMpm, kInput, {"scene.toml", "'particles.per_cell'", "required key is missing", "a typo?"}},
      {"mpm_per_cell_not_square", {{"scene.toml", S("per_cell = 4", "per_cell = 3")}}, kMpm, kInput, {"scene.toml:7", "'particles.per_cell'", "must be n^2"}},
      {"mpm_unknown_model", {{"scene.toml", S("\"frictional\"", "\"viscous\"")}}, kMpm, kInput, {"scene.toml:12", "'material.model'", "'phase_transition', 'frictional'"}},
      {"mpm_no_such_parameter_set", {{"scene.toml", S("\"column_collapse\"", "\"column_colapse\"")}}, kMpm, kInput, {"scene.toml:11", "'material.parameters'", "column_colapse: no such file, and no parameter set of that name", "column_collapse"}},
      {"mpm_frame_after_end", {{"scene.toml", kScene + "times = [1.0]\n"}}, kMpm, kInput, {"scene.toml:22", "'output.times'", "after the end of the last stage"}},
      {"mpm_checkpoint_dt_negative", {{"scene.toml", kScene + "checkpoint_dt = -1\n"}}, kMpm, kInput, {"scene.toml:22", "'output.checkpoint_dt'", "must be > 0"}},
      {"mpm_checkpoint_every_zero", {}, {"mpm", "scene.toml", "--out", "o", "--checkpoint-every", "0"}, 105, {"--checkpoint-every", "must be a number of seconds > 0, got '0'", "command line: mpm scene.toml"}},
      {"mpm_out_not_empty", {{"o/old.vtu", "previous run\n"}}, kMpm, kInput, {"output directory 'o' exists and is not empty", "--force"}},
      {"mpm_force_foreign_folder", {{"o/notes.txt", "not granflow's\n"}}, kMpmForce, kInput, {"output directory 'o' is not a granflow run folder", "--force replaces only folders granflow wrote"}},
      {"mpm_out_is_a_file", {{"o", "a file\n"}}, kMpm, kInput, {"o: is a file, not a folder"}},
      {"mpm_force_out_is_a_file", {{"o", "a file\n"}}, kMpmForce, kInput, {"o: is a file, not a folder"}},
      {"mpm_locked_on_another_host", {{"o/granflow.lock", "granflow lock\npid 1\nhost elsewhere.example\n"}, {"o/frame_0000.vtu", "x"}}, kMpmForce, kInput, {"output folder 'o' is locked by pid 1 on host elsewhere.example", "remove that file"}},
      {"mpm_restart_without_checkpoint", {{"o/frame_0000.vtu", "previous run\n"}}, kRestart, kInput, {"o/checkpoint.bin", "no checkpoint to restart from", "--checkpoint-every"}},
      {"mpm_restart_without_output", {}, kRestart, kInput, {"--restart", "'o' does not exist", "nothing to continue"}},
      {"mpm_restart_with_force", {{"o/checkpoint.bin", foreign_checkpoint()}}, {"mpm", "scene.toml", "--out", "o", "--restart", "--force"}, kInput, {"--restart", "--force", "give one of them"}},
      {"mpm_restart_other_scene", {{"o/checkpoint.bin", foreign_checkpoint()}}, kRestart, kInput, {"o/checkpoint.bin", "written for a different scene or parameter set", "5ca1ab1e"}},
      {"mpm_restart_truncated_checkpoint", {{"o/checkpoint.bin", foreign_checkpoint().substr(0, 100)}}, kRestart, kInput, {"o/checkpoint.bin", "truncated checkpoint: 100 bytes"}},
      {"mpm_restart_corrupt_checkpoint", {{"o/checkpoint.bin", flip_byte(foreign_checkpoint(), 60)}}, kRestart, kInput, {"o/checkpoint.bin", "checksum mismatch"}},
      {"mpm_restart_not_a_checkpoint", {{"o/checkpoint.bin", "t,runout\n0,0.2\n"}}, kRestart, kInput, {"o/checkpoint.bin", "not a granflow MPM checkpoint"}},
      // ---- terrain rasters and base profiles (granflow mpm; docs/mpm_terrain.md) ------------------
      {"terrain_nodata_under_material", {{"t3.toml", kTerrainScene}, {"dem.asc", dem(3, 2)}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "a NODATA cell under material", "dem.asc"}},
      {"terrain_nodata_in_footprint", {{"t3.toml", kTerrainScene}, {"dem.asc", dem(0, 5)}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "a NODATA cell inside the grid's footprint: row 0, column 5 of dem.asc"}},
      {"terrain_raster_misses_footprint", {{"t3.toml", edit(kTerrainScene, "[500000.0,", "[500000.05,")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "dem.asc covers easting [499999.975, 500000.125]", "not easting [500000.05, 500000.15]", "the grid's footprint"}},
      {"output_fields_unknown", {{"t3.toml", edit(kTerrainScene, "series_dt = 0.001\n", "series_dt = 0.001\nfields = [\"p\", \"speed\"]\n")}}, kT3, kInput, {"t3.toml:25", "'output.fields'", "unknown point array 'speed'", "velocity, p, q, eps_pd, T, eta_c, K_col, e, sigma_xx, sigma_yy, sigma_xy"}},
      {"output_deposit_direction_zero", {{"t3.toml", edit(kTerrainScene, "series_dt = 0.001\n", "series_dt = 0.001\ndeposit_direction = [0.0, 0.0]\n")}}, kT3, kInput, {"t3.toml:25", "'output.deposit_direction'", "[dx, dz]", "not both zero"}},
      {"output_deposit_centre_outside", {{"t3.toml", edit(kTerrainScene, "series_dt = 0.001\n", "series_dt = 0.001\ndeposit_centre = [0.7, 0.05]\n")}}, kT3, kInput, {"t3.toml:25", "'output.deposit_centre'", "[0.7, 0.05] lies outside the grid's plan [0, 0.1] x [0, 0.1] m"}},
      {"output_deposit_centre_one_number", {{"t3.toml", edit(kTerrainScene, "series_dt = 0.001\n", "series_dt = 0.001\ndeposit_centre = [0.05]\n")}}, kT3, kInput, {"t3.toml:25", "'output.deposit_centre'", "[x, z] of two finite numbers"}},
      {"output_edge_thickness_without_centre", {{"t3.toml", edit(kTerrainScene, "series_dt = 0.001\n", "series_dt = 0.001\nedge_thickness = 0.004\n")}}, kT3, kInput, {"t3.toml:25", "'output.edge_thickness'", "reads the edge about output.deposit_centre, which is not given"}},
      {"output_edge_thickness_zero", {{"t3.toml", edit(kTerrainScene, "series_dt = 0.001\n", "series_dt = 0.001\ndeposit_centre = [0.05, 0.05]\nedge_thickness = 0.0\n")}}, kT3, kInput, {"t3.toml:26", "'output.edge_thickness'"}},
      {"output_map_cell_not_a_multiple", {{"t3.toml", edit(kTerrainScene, "series_dt = 0.001\n", "series_dt = 0.001\nmap_cell = 0.06\n")}}, kT3, kInput, {"t3.toml:25", "'output.map_cell'", "whole multiple of the terrain raster's cell size 0.025 m (dem.asc)", "e.g. 0.05"}},
      {"terrain_malformed_asc", {{"t3.toml", kTerrainScene}, {"dem.asc", edit(dem(), "100.02 100.02\n", "100.02 1OO.02\n")}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "dem.asc:7: '1OO.02' is not a number"}},
      {"terrain_asc_value_count", {{"t3.toml", kTerrainScene}, {"dem.asc", edit(dem(), "ncols 6", "ncols 7")}}, kT3, kInput, {"'terrain.file'", "dem.asc:12: 36 values, but ncols x nrows = 7 x 6 = 42"}},
      {"terrain_geographic", {{"t3.toml", kTerrainScene}, {"dem.asc", dem()}, {"dem.prj", "GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\"],UNIT[\"degree\",0.0174532925199433]]"}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "geographic coordinate system (degrees", "gdalwarp"}},
      {"terrain_prj_bom_geographic", {{"t3.toml", kTerrainScene}, {"dem.asc", dem()}, {"dem.prj", "\xEF\xBB\xBFGEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\",SPHEROID[\"WGS_1984\",6378137.0,298.257223563]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\",0.0174532925199433]]"}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "geographic coordinate system (degrees", "dem.prj"}},
      {"terrain_prj_esri_text_geographic", {{"t3.toml", kTerrainScene}, {"dem.asc", dem()}, {"dem.prj", "Projection    GEOGRAPHIC\nDatum         WGS84\nUnits         DD\nParameters\n"}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "geographic coordinate system (degrees", "dem.prj"}},
      {"terrain_prj_us_survey_feet", {{"t3.toml", kTerrainScene}, {"dem.asc", dem()}, {"dem.prj", "PROJCS[\"NAD83 / California zone 3 (ftUS)\",GEOGCS[\"NAD83\",DATUM[\"North_American_Datum_1983\",SPHEROID[\"GRS 1980\",6378137,298.257222101]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],PROJECTION[\"Lambert_Conformal_Conic_2SP\"],PARAMETER[\"standard_parallel_1\",38.4333333333333],PARAMETER[\"standard_parallel_2\",37.0666666666667],PARAMETER[\"latitude_of_origin\",36.5],PARAMETER[\"central_meridian\",-120.5],PARAMETER[\"false_easting\",6561666.667],PARAMETER[\"false_northing\",1640416.667],UNIT[\"US survey foot\",0.304800609601219]]"}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "the coordinate system's unit is 'US survey foot' (0.3048006096 m", "dem.prj", "granflow needs metres"}},
      {"terrain_coordinates_beyond_precision", {{"t3.toml", edit(kTerrainScene, "[500000.0, 4000000.0,", "[1e17, 4000000.0,")}, {"dem.asc", edit(dem(), "xllcorner 499999.975", "xllcorner 1e17")}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "dem.asc:7: cells of 0.025 m at coordinates up to 1e+17 m", "at least 1e-10 x the largest |easting| or |northing|"}},
      {"terrain_asc_huge_header", {{"t3.toml", kTerrainScene}, {"dem.asc", edit(dem(), "ncols 6\nnrows 6", "ncols 100000\nnrows 100000")}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "dem.asc:7: ncols x nrows = 100000 x 100000 = 10000000000 cells would need 80 GB", "at most 250000000 cells"}},
      {"terrain_file_is_a_device", {{"t3.toml", edit(kTerrainScene, "file = \"dem.asc\"", "file = \"/dev/zero\"")}}, kT3, kInput, {"t3.toml:15", "'terrain.file'", "/dev/zero: not a regular file"}},
      {"output_map_cell_too_many_bins", {{"scene.toml", kScene + "map_cell = 1e-9\n[base]\nx = [0.0, 0.2]\ny = [0.0, 0.0]\n"}}, kMpm, kInput, {"scene.toml:22", "'output.map_cell'", "map cells of 1e-09 m give 2e+08 cells", "at most 10000000 are allowed"}},
      {"terrain_material_below_ground", {{"t3.toml", edit(kTerrainScene, "min = [0.02, 0.04, 0.02]", "min = [0.02, 0.0, 0.02]")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:14", "'terrain'", "lies on or below the terrain (ground at y = 0.02"}},
      {"terrain_mu_nan", {{"t3.toml", edit(kTerrainScene, "mu = 0.3\n", "mu = nan\n")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:17", "'terrain.mu'"}},
      {"terrain_mu_infinite", {{"t3.toml", edit(kTerrainScene, "mu = 0.3\n", "mu = inf\n")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:17", "'terrain.mu'"}},
      {"terrain_gravity_parallel_to_ground", {{"t3.toml", edit(kTerrainScene, "[material]\n", "[solver]\ngravity = [9.81, 0.0, 0.0]\n[material]\n")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:12", "'solver.gravity'", "parallel to the terrain"}},
      {"terrain_contact_unknown", {{"t3.toml", edit(kTerrainScene, "mu = 0.3\n", "mu = 0.3\ncontact = \"points\"\n")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:18", "'terrain.contact'", "support"}},
      {"terrain_in_2d_scene", {{"scene.toml", kScene + "[terrain]\nfile = \"dem.asc\"\norigin = [0.0, 0.0, 0.0]\n"}, {"dem.asc", dem()}}, kMpm, kInput, {"scene.toml:23", "'terrain.file'", "terrain needs grid.dim = 3", "[base]"}},
      // ---- obstacles ([[obstacle]], docs/mpm_obstacles.md) ------------------------------------------
      {"obstacle_thinner_than_two_cells", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"box\"\nmin = [0.14, 0.0]\nmax = [0.16, 0.06]\n"}}, kMpm, kInput, {"scene.toml:25", "'obstacle[0].max'", "0.02 m thick at its narrowest, less than two grid cells (2 h = 0.04 m)"}},
      {"obstacle_over_material", {{"scene.toml", kScene + "[[obstacle]]\nname = \"pier\"\nkind = \"box\"\nmin = [0.06, 0.0]\nmax = [0.16, 0.06]\n"}}, kMpm, kInput, {"scene.toml:22", "'obstacle[0]'", "of body[0] lies inside obstacle 'pier'"}},
      {"obstacle_outside_grid", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"box\"\nmin = [0.5, 0.5]\nmax = [0.6, 0.6]\n"}}, kMpm, kInput, {"scene.toml:22", "'obstacle[0]'", "holds no grid node: it lies outside the grid"}},
      {"obstacle_cylinder_in_2d", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"cylinder\"\n"}}, kMpm, kInput, {"scene.toml:23", "'obstacle[0].kind'", "\"cylinder\" needs grid.dim = 3", "box, segment or polygon"}},
      {"obstacle_polygon_two_vertices", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"polygon\"\nx = [0.15, 0.19]\ny = [0.0, 0.05]\n"}}, kMpm, kInput, {"scene.toml:24", "'obstacle[0].x'", "at least three vertices"}},
      {"mpm_gate_radius_in_2d", {{"scene.toml", edit(kScene, "duration = 0.002\n", "duration = 0.002\n[stage.gate]\npoint = [0.1, 0.0]\nradius = 0.05\n")}}, kMpm, kInput, {"scene.toml:22", "'stage[0].gate.radius'", "a cylindrical gate needs a 3D scene"}},
      {"mpm_gate_radius_with_normal", {{"t3.toml", edit(kTerrainScene, "duration = 0.002\n", "duration = 0.002\n[stage.gate]\npoint = [0.0, 0.0, 0.0]\nradius = 0.05\nnormal = [1.0, 0.0, 0.0]\n")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:26", "'stage[0].gate.normal'", "a cylindrical gate (radius) has no normal"}},
      {"mpm_gate_radius_below_h", {{"t3.toml", edit(kTerrainScene, "duration = 0.002\n", "duration = 0.002\n[stage.gate]\npoint = [0.0, 0.0, 0.0]\nradius = 0.01\n")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:25", "'stage[0].gate.radius'", "must be at least the grid spacing h = 0.02 m", "0.01"}},
      {"mpm_stage_name_with_slash", {{"scene.toml", edit(kScene, "[[stage]]\nduration", "[[stage]]\nname = \"a/b\"\nduration")}}, kMpm, kInput, {"scene.toml:19", "'stage[0].name'", "may not hold '/'"}},
      {"mpm_series_dt_below_dt", {{"scene.toml", edit(kScene, "series_dt = 0.001", "series_dt = 1e-6")}}, kMpm, kInput, {"scene.toml:21", "'output.series_dt'", "below time.dt = 0.0001 s", "series_dt >= time.dt"}},
      {"mpm_set_initial_e0_under_a_material_e0", {{"scene.toml", edit(kScene, "model = \"frictional\"\n", "model = \"frictional\"\ne0 = 0.9\n")}}, {"mpm", "scene.toml", "--out", "o", "--no-png", "--quiet", "--set", "initial.e0=0.8"}, kInput, {"--set 'initial.e0=0.8' changes nothing", "scene.toml:13", "'material.e0' takes precedence", "set material.e0 instead"}},
      {"obstacle_bow_tie", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"polygon\"\nx = [0.12, 0.18, 0.12, 0.18]\ny = [0.0, 0.06, 0.06, 0.0]\n"}}, kMpm, kInput, {"scene.toml:24", "'obstacle[0].x'", "not a simple polygon: edge 0 (vertices 0-1) and edge 2 (vertices 2-3) cross or touch"}},
      {"obstacle_polygon_on_a_line", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"polygon\"\nx = [0.12, 0.15, 0.18]\ny = [0.0, 0.03, 0.06]\n"}}, kMpm, kInput, {"scene.toml:24", "'obstacle[0].x'", "edge 0 (vertices 0-1) and edge 2 (vertices 2-0) fold back onto each other"}},
      {"obstacle_polygon_folds_back", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"polygon\"\nx = [0.12, 0.18, 0.18, 0.18, 0.12]\ny = [0.0, 0.0, 0.06, 0.03, 0.06]\n"}}, kMpm, kInput, {"scene.toml:24", "'obstacle[0].x'", "edge 1 (vertices 1-2) and edge 2 (vertices 2-3) fold back onto each other"}},
      {"obstacle_polygon_repeated_vertex", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"polygon\"\nx = [0.12, 0.18, 0.18, 0.18]\ny = [0.0, 0.0, 0.06, 0.06]\n"}}, kMpm, kInput, {"scene.toml:24", "'obstacle[0].x'", "repeats vertex 2 as vertex 3"}},
      {"mpm_body_polygon_bow_tie", {{"scene.toml", edit(kScene, "min = [0.0, 0.0]\nmax = [0.1, 0.06]\n", "polygon_x = [0.0, 0.1, 0.1, 0.0]\npolygon_y = [0.0, 0.06, 0.0, 0.06]\n")}}, kMpm, kInput, {"scene.toml:14", "'body[0].polygon_x'", "not a simple polygon"}},
      {"obstacle_negative_mu", {{"scene.toml", kScene + "[[obstacle]]\nkind = \"segment\"\nfrom = [0.16, 0.0]\nto = [0.16, 0.06]\nthickness = 0.04\nmu = -0.2\n"}}, kMpm, kInput, {"scene.toml:27", "'obstacle[0].mu'"}},
      // ---- gauges ([[gauge]], docs/mpm_results.md) ----------------------------------------------
      {"gauge_outside_grid", {{"scene.toml", kScene + "[[gauge]]\nfrom = [0.15, 0.0]\nto = [0.15, 0.5]\n"}}, kMpm, kInput, {"scene.toml:24", "'gauge[0].to'", "lies outside the grid"}},
      {"gauge_of_zero_length", {{"scene.toml", kScene + "[[gauge]]\nfrom = [0.15, 0.0]\nto = [0.15, 0.0]\n"}}, kMpm, kInput, {"scene.toml:24", "'gauge[0].to'", "must differ from 'from'"}},
      {"gauge_width_zero", {{"scene.toml", kScene + "[[gauge]]\nfrom = [0.15, 0.0]\nto = [0.15, 0.05]\nwidth = 0.0\n"}}, kMpm, kInput, {"scene.toml:25", "'gauge[0].width'"}},
      {"gauge_named_twice", {{"scene.toml", kScene + "[[gauge]]\nname = \"g\"\nfrom = [0.15, 0.0]\nto = [0.15, 0.05]\n[[gauge]]\nname = \"g\"\nfrom = [0.12, 0.0]\nto = [0.12, 0.05]\n"}}, kMpm, kInput, {"scene.toml:27", "'gauge[1].name'", "a second gauge named 'g'"}},
      {"gauge_in_3d_scene", {{"t3.toml", kTerrainScene + "[[gauge]]\nfrom = [0.05, 0.0, 0.05]\nto = [0.05, 0.1, 0.05]\n"}, {"dem.asc", dem()}}, kT3, kInput, {"'gauge[0].from'", "gauges are 2D only"}},
      {"base_profile_not_increasing", {{"scene.toml", kScene + "[base]\nfile = \"p.csv\"\n"}, {"p.csv", "x,y\n0,0\n0.1,0\n0.05,0\n"}}, kMpm, kInput, {"scene.toml:23", "'base.file'", "p.csv", "must increase strictly"}},
      {"release_top_missing", {{"t3.toml", edit(kTerrainScene, "min = [0.02, 0.04, 0.02]\nmax = [0.06, 0.08, 0.06]", "top = \"top.asc\"")}, {"dem.asc", dem()}}, kT3, kInput, {"t3.toml:19", "'body[0].top'", "top.asc: no such raster file"}},
      // ---- --set and --params over the scene (granflow mpm, bench mpm) ------------------------------
      {"mpm_set_unknown_key", {}, mpm_with({"--set", "grid.hh=0.01"}), kInput, {"scene.toml: --set 'grid.hh=0.01': unknown key 'grid.hh'", "allowed here"}},
      {"mpm_set_wrong_type", {}, mpm_with({"--set", "time.dt=fast"}), kInput, {"scene.toml: --set 'time.dt=fast': 'time.dt': expected a number, got a string"}},
      {"mpm_set_cap_not_boolean", {}, mpm_with({"--set", "time.cap_to_stable=1"}), kInput, {"scene.toml: --set 'time.cap_to_stable=1': 'time.cap_to_stable': expected true or false, got an integer"}},
      {"mpm_set_no_value", {}, mpm_with({"--set", "grid.h"}), kInput, {"scene.toml: --set 'grid.h': expected KEY=VALUE"}},
      {"mpm_set_no_such_stage", {}, mpm_with({"--set", "stage[1].duration=1"}), kInput, {"--set 'stage[1].duration=1'", "the scene has 1 [[stage]] table (stage[0] to stage[0])"}},
      {"mpm_set_dt_above_stability_limit", {}, mpm_with({"--set", "time.dt=1e-2"}), kInput, {"scene.toml: --set 'time.dt=1e-2': 'time.dt'", "above the stability limit"}},
      {"mpm_set_parameter_out_of_range", {}, mpm_with({"--set", "frictional.phi_c_deg=95"}), kInput, {"--set 'frictional.phi_c_deg=95': 'frictional.phi_c_deg': must be in (0, 90), got 95"}},
      {"mpm_params_unknown", {}, mpm_with({"--params", "column_colapse"}), kInput, {"--params 'column_colapse'", "no parameter set of that name", "column_collapse"}},
      // ---- several materials ([[material]], body.material, NAME= and NAME: on the command line) ----
      {"mpm_materials_mixed_models", {{"scene.toml", M2("name = \"weak\"\nparameters = \"column_collapse\"\nmodel = \"frictional\"", "name = \"weak\"\nparameters = \"column_collapse\"\nmodel = \"phase_transition\"")}}, kMpm, kInput, {"scene.toml:17", "'material[1].model'", "\"phase_transition\" differs from material[0].model (\"frictional\")", "same model"}},
      {"mpm_material_unknown_name", {{"scene.toml", M2("material = \"weak\"", "material = \"wek\"")}}, kMpm, kInput, {"scene.toml:21", "'body[0].material'", "no [[material]] is named 'wek'", "strong, weak"}},
      {"mpm_material_duplicate_name", {{"scene.toml", M2("name = \"weak\"", "name = \"strong\"")}}, kMpm, kInput, {"scene.toml:15", "'material[1].name'", "'strong' names material[0] too"}},
      {"mpm_material_body_without_one", {{"scene.toml", M2("material = \"weak\"\n", "")}}, kMpm, kInput, {"'body[0].material'", "the scene has 2 materials"}},
      {"mpm_material_named_in_single_material_scene", {{"scene.toml", S("max = [0.1, 0.06]", "max = [0.1, 0.06]\nmaterial = \"sand\"")}}, kMpm, kInput, {"scene.toml:16", "'body[0].material'", "one unnamed [material]"}},
      {"mpm_set_unqualified_with_two_materials", {{"scene.toml", kTwoMaterials}}, mpm_with({"--set", "frictional.phi_c_deg=30"}), kInput, {"--set 'frictional.phi_c_deg=30': the scene has 2 materials (strong, weak)", "--set strong:frictional.phi_c_deg=30"}},
      {"mpm_set_unknown_material", {{"scene.toml", kTwoMaterials}}, mpm_with({"--set", "wek:frictional.phi_c_deg=30"}), kInput, {"--set 'wek:frictional.phi_c_deg=30'", "no [[material]] named 'wek' (its materials: strong, weak)"}},
      {"mpm_set_named_parameter_out_of_range", {{"scene.toml", kTwoMaterials}}, mpm_with({"--set", "weak:frictional.phi_c_deg=95"}), kInput, {"--set (material weak) 'frictional.phi_c_deg=95'", "must be in (0, 90), got 95"}},
      {"mpm_params_unqualified_with_two_materials", {{"scene.toml", kTwoMaterials}}, mpm_with({"--params", "flume"}), kInput, {"--params 'flume': the scene has 2 materials (strong, weak)", "--params strong=flume"}},
      {"mpm_params_unknown_material", {{"scene.toml", kTwoMaterials}}, mpm_with({"--params", "wek=flume"}), kInput, {"--params 'wek=flume'", "no [[material]] named 'wek'"}},
      // ---- ensemble design files (granflow ensemble SCENE DESIGN) ----------------------------
      {"ens_unknown_vary_key", {{"d.toml", design("frictional.phi_cdeg", "range = [18.0, 22.0]")}}, kEns, kInput, {"d.toml:4", "vary key 'frictional.phi_cdeg'", "unknown key 'frictional.phi_cdeg'", "phi_c_deg"}},
      {"ens_stop_at_rest", {{"scene.toml", S("dt = 1e-4", "dt = 1e-4\nstop_at_rest = 1e-3")}, {"d.toml", design("frictional.phi_c_deg", "range = [18.0, 22.0]")}}, kEns, kInput, {"scene.toml:10", "'time.stop_at_rest'", "ensembles run every member to the scene's end"}},
      {"ens_empty_range", {{"d.toml", design("frictional.phi_c_deg", "range = [22.0, 18.0]")}}, kEns, kInput, {"d.toml:6", "range"}},
      {"ens_zero_members", {{"d.toml", edit(design("frictional.phi_c_deg", "range = [18.0, 22.0]"), "members = 4", "members = 0")}}, kEns, kInput, {"d.toml:3", "design.members"}},
      {"ens_duplicate_key", {{"d.toml", design("frictional.phi_c_deg", "range = [18.0, 22.0]") + "[[vary]]\nkey = \"frictional.phi_c_deg\"\nrange = [19.0, 20.0]\n"}}, kEns, kInput, {"d.toml:8", "'frictional.phi_c_deg' is varied twice", "at line 4"}},
      {"ens_too_large_for_memory", {{"d.toml", edit(design("frictional.phi_c_deg", "range = [18.0, 22.0]"), "members = 4", "members = 100000")}}, ens_with({"--set", "grid.h=0.001", "--set", "time.dt=1e-5"}), kInput, {"d.toml: 100000 members need", "at most", "members fit"}},
      {"ens_members_differ_in_grid", {{"d.toml", "[design]\nmethod = \"list\"\n[[vary]]\nkey = \"grid.h\"\nvalues = [0.02, 0.025]\n"}}, kEns, kInput, {"d.toml: grid: member 1 differs from member 0 in the grid", "members may differ in"}},
      {"ens_member_setup_fails", {{"d.toml", "[design]\nmethod = \"list\"\n[[vary]]\nkey = \"material.e0\"\nvalues = [0.95, 0.95, -1.0, -2.0, 0.95, -3.0]\n"}}, kEns, kInput, {"d.toml: member 2 (", "e0"}},
      {"ens_range_typo", {{"d.toml", design("frictional.phi_c_deg", "rnage = [18.0, 22.0]")}}, kEns, kInput, {"d.toml:4", "'vary[0].range': required key is missing", "'vary[0].rnage'", "a typo?"}},
      {"calib_scene_two_materials_unnamed", {{"job.toml", kSceneJob}, {"scene.toml", kTwoMaterials}, {"front.csv", "t,x\n0,0.1\n0.001,0.1\n"}}, kCal, kInput, {"job.toml", "'experiments[0].material'", "the scene has 2 materials"}},
      {"calib_scene_unknown_material", {{"job.toml", edit(kSceneJob, "progress = false\n", "progress = false\nmaterial = \"wek\"\n")}, {"scene.toml", kTwoMaterials}, {"front.csv", "t,x\n0,0.1\n0.001,0.1\n"}}, kCal, kInput, {"job.toml:15", "'experiments[0].material'", "no [[material]] named 'wek' (its materials: strong, weak)"}},
      {"calib_scene_front_past_end", {{"job.toml", kSceneJob}, {"front.csv", "t,x\n0,0.1\n0.001,0.1\n0.003,0.1\n"}}, kCal, kInput, {"front.csv:4", "t = 0.003 s", "past the end of the run", "0.002 s after the release"}},
      {"ens_backend_cuda_unavailable", {{"d.toml", design("frictional.phi_c_deg", "range = [18.0, 22.0]")}}, ens_with({"--backend", "cuda"}), kInput, {"--backend cuda: ", "; use --backend cpu"}},
      {"mpm_backend_cuda_unavailable", {}, mpm_with({"--backend", "cuda"}), kInput, {"--backend cuda: ", "; use --backend cpu"}},
      {"mpm_devices_more_slabs_than_columns", {}, mpm_with({"--devices", "40"}), kInput, {"--devices 40: slabs: 40 slabs of at least", "node columns each (one stencil) do not fit the grid's", "columns along x"}},
      // ---- the shipped data folder (GRANFLOW_DATA_DIR) ---------------------------------------
      {"data_dir_wrong", {}, {"element", "t.toml", "--params", "element_test", "--out", "out.csv"}, kInput, {"element_test: no such file", "GRANFLOW_DATA_DIR = '/nonexistent/data'", "/nonexistent/data/params"}, {{"GRANFLOW_DATA_DIR", "/nonexistent/data"}}},
      {"data_dir_relative", {}, {"element", "t.toml", "--params", "element_test", "--out", "out.csv"}, kInput, {"element_test: no such file", "GRANFLOW_DATA_DIR = 'data'", "relative"}, {{"GRANFLOW_DATA_DIR", "data"}}},
      {"figures_data_dir_wrong", {}, {"figures", "--out", "figs"}, kInput, {"GRANFLOW_DATA_DIR = '/nonexistent/data'"}, {{"GRANFLOW_DATA_DIR", "/nonexistent/data"}}},
      {"bench_mpm_set_unknown_table", {}, {"bench", "mpm", "scene.toml", "--set", "gird.h=0.01"}, kInput, {"scene.toml: --set 'gird.h=0.01': unknown key 'gird'"}},
  };
  cases.insert(cases.end(), mesh.begin(), mesh.end());
  return cases;
}

}  // namespace reliability
