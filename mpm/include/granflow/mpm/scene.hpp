// A scene as plain data: what the TOML loader (mpm/src/scene/scene_file.cpp) fills and the MPM takes.
// No file format here; programs and tests may build scenes in code (see small_column_scene).
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include <granflow/constitutive.hpp>

#include "mesh.hpp"
#include "shape.hpp"

namespace granflow::io {
struct Raster;  // granflow/io/raster.hpp (the scene file and make_setup read it; the kernels never)
}

namespace granflow::mpm {

// An inconsistent scene; the message starts with the offending key (e.g. "time.dt: ...").
class SceneError : public std::runtime_error {
 public:
  SceneError(const std::string& key, const std::string& message)
      : std::runtime_error(key + ": " + message), key_(key) {}
  const std::string& key() const { return key_; }

 private:
  std::string key_;
};

enum class ModelKind { PhaseTransition, Frictional };

// Scalar of particle/grid storage and of P2G, grid update and G2P, and of the constitutive
// update (solver.precision): fp64 both double; mixed float storage and transfers with the
// constitutive update in double; fp32 both float (the library's float tolerances, config.hpp).
enum class Precision { FP64, Mixed, FP32 };
inline const char* precision_name(Precision p) {
  return p == Precision::FP64 ? "fp64" : (p == Precision::Mixed ? "mixed" : "fp32");
}
// "fp64" | "mixed" | "fp32"; false for anything else.
inline bool parse_precision(const std::string& s, Precision& p) {
  if (s == "fp64") p = Precision::FP64;
  else if (s == "mixed") p = Precision::Mixed;
  else if (s == "fp32") p = Precision::FP32;
  else return false;
  return true;
}

// Axis-aligned wall: nodes on and beyond `position` along `axis` are held.
struct Wall {
  int axis = 0;
  bool at_max = false;    // false: the wall bounds the domain from below (x <= position)
  double position = 0;
  bool no_slip = true;    // no-slip: all components held; free-slip (roller): the normal one
  std::string key;        // for messages
  // Coulomb friction coefficient (>= 0): a frictional wall instead (no_slip unused); its
  // nodes go through the contact condition of boundary.hpp.
  std::optional<double> mu;
};

// Rigid base given as a polyline y = b(x) (x increasing): every node with y <= b(x) has all
// components held (no-slip on an inclined plane: the flume). 2D only.
struct BaseLine {
  std::vector<double> x, y;
  // Coulomb friction coefficient (>= 0): the contact condition with the normal of the
  // segment above the node instead of the no-slip hold.
  std::optional<double> mu;
  std::string file;  // the profile file x and y came from (base.file), empty: inline
};

// A gate: nodes with (x - point) . normal >= 0 are held while the stage lasts.
// Rigid ground of a 3D scene from an elevation raster (docs/mpm_terrain.md): easting,
// northing and elevation minus `origin` are the scene's x, z and y. Nodes on or below the
// ground are held: no-slip, or (mu) Coulomb friction with the raster's own normal.
struct Terrain {
  // Which nodes take the contact law (docs/mpm_terrain.md, "Held nodes and contact"): Support,
  // also every node above the ground whose shape function's support the ground cuts; Nodes,
  // the nodes on or below the ground only (before issue 51).
  enum class Contact { Support, Nodes };
  std::string file;                            // as the scene gives it (messages)
  std::vector<double> origin = {0.0, 0.0, 0.0};  // easting, northing, elevation [m]
  std::optional<double> mu;                    // absent: no-slip
  Contact contact = Contact::Support;
  std::shared_ptr<const io::Raster> raster;
};

// A rigid, fixed obstacle in the flow (docs/mpm_obstacles.md): every node inside it or on its
// surface is held, no-slip or (mu) by Coulomb friction with the normal of its nearest face.
// 2D: a polygon (a box, a wall segment of some thickness, or polygon_x/polygon_y as given); 3D:
// an axis-aligned box, a vertical cylinder (a pier) or a closed triangle mesh (docs/mpm_meshes.md).
struct Obstacle {
  enum class Shape { Polygon, Box, Cylinder, Mesh };
  Shape shape = Shape::Polygon;
  std::string name;                  // for the force rows ("obstacle[k]" when none is given)
  std::string key;                   // "obstacle[k]", for messages
  std::string kind;                  // as the scene gave it: box, segment, polygon, cylinder
  std::vector<double> poly_x, poly_y;  // 2D: counter-clockwise vertices
  std::vector<double> box_min, box_max;  // 3D box
  std::vector<double> center;        // cylinder: axis at (center[0], center[1]) in x and z
  double radius = 0, y_min = 0, y_max = 0;  // cylinder
  std::shared_ptr<const TriMesh> mesh;  // mesh: placed, in scene coordinates
  std::optional<double> mu;          // absent: no-slip
  std::vector<double> moment_point;  // moments about it (default: the centroid)
};

// A 3D pier: the vertical cylinder of `radius` about (x, z) = center from y_min to y_max.
inline Obstacle pier_obstacle(std::string name, std::string key, std::vector<double> center, double radius,
                              double y_min, double y_max) {
  Obstacle o;
  o.shape = Obstacle::Shape::Cylinder;
  o.name = std::move(name);
  o.key = std::move(key);
  o.kind = "cylinder";
  o.center = std::move(center);
  o.radius = radius;
  o.y_min = y_min;
  o.y_max = y_max;
  return o;
}

struct Gate {
  std::vector<double> point, normal;
  bool normal_only = true;  // hold only the normal component (axis-aligned normals only)
  // > 0 [m/s]: the gate is lifted from the start of its stage; it holds only the nodes at and
  // above its lower edge, at point's height (y) at the start and rising at lift_speed. The
  // normal must be horizontal. 0: held whole while the stage lasts.
  double lift_speed = 0;
  // > 0 [m] (3D): a vertical cylinder instead of a plane, about the axis through point along y;
  // it holds the nodes at and outside this radius (normal is empty). "normal" holds the radial
  // component (free slip on the cylinder), "all" every component. A release volume's plan
  // cannot be held by a plane: the axisymmetric collapse (docs/mpm_results.md) needs this.
  double radius = 0;
};

struct Stage {
  std::string name;
  double duration = 0;
  std::optional<Gate> gate;
  double damping = 0;                 // Cundall local damping factor in [0, 1)
  std::optional<double> flip;         // overrides the scene's FLIP fraction in this stage
};

// Material region: an axis-aligned box, (2D) a polygon, or (3D) a release volume between two
// surfaces: from `bottom` (the failure surface; null: the terrain) up to `top` (the ground
// before failure), within the plan polygon (plan_x, plan_z) where one is given, else wherever
// top lies above bottom in the grid's footprint. Surfaces are rasters georeferenced like the
// terrain (terrain.origin), which such a scene needs. 3D: or inside a closed triangle mesh.
struct Body {
  std::vector<double> box_min, box_max;
  std::vector<double> poly_x, poly_y;
  std::shared_ptr<const io::Raster> top, bottom;
  std::vector<double> plan_x, plan_z;
  std::shared_ptr<const TriMesh> mesh;  // placed, in scene coordinates
  int material = 0;  // index of its material (Scene::material_at)
  bool is_polygon() const { return !poly_x.empty(); }
  bool is_release() const { return top != nullptr; }
  bool is_mesh() const { return mesh != nullptr; }
};

struct Material {
  std::string name;                   // parameter-set name or file, for the record
  std::string label;                  // a [[material]] table's name ("": the single [material])
  ModelKind model = ModelKind::PhaseTransition;
  PhaseTransitionParams<double> params;  // the frictional-only model uses params.f and c.rho_p
  double e0 = 0;
  double T0 = 1e-15;
};

struct InitialStress {
  bool geostatic = false;  // false: stress free (a consolidation stage builds it)
  double K0 = -1;          // lateral coefficient; < 0: Jaky, 1 - sin(phi_c)
};

struct Track {
  std::string name;
  std::vector<double> x;  // the particle nearest to this point at t = 0
};

// A cross-section of the flow (2D): a line from the base (`from`) across the flow (`to`). Each
// sample measures the points within width/2 of it: depth, depth-averaged velocity, density.
struct Gauge {
  std::string name;
  std::vector<double> from, to;
  double width = 0;  // band about the line [m]
};

// Encoding of the VTU frames' arrays (output.format): Raw, raw bytes appended after the XML
// ("binary", UInt64 headers); Base64, inline base64 (UInt32 headers); Ascii, decimal text.
enum class FrameFormat { Raw, Base64, Ascii };

struct OutputSpec {
  std::vector<double> times;     // frames, measured from the start of the last stage
  double series_dt = 1e-3;       // sampling of run-out, height and tracked particles
  FrameFormat format = FrameFormat::Raw;  // of the VTU frames
  bool frames_in_stages = true;  // one frame at the end of every earlier stage
  std::vector<std::string> png_fields;  // fields plot_mpm.py draws
  double checkpoint_dt = 0;      // simulated time between checkpoints (0: only when interrupted)
  // Point arrays of the VTU frames besides position (frame_field_names()); empty: all of them.
  std::vector<std::string> fields;
  // 3D terrain runs: the plan direction (x, z) of the deposit's extent in deposit.csv.
  std::vector<double> deposit_direction = {1.0, 0.0};
  // 3D terrain runs: a plan centre [x, z] (grid coordinates) of deposit.csv's edge_radius, the
  // deposit's edge about it (an axisymmetric collapse's axis); empty: no edge_radius column.
  std::vector<double> deposit_centre;
  // With deposit_centre: the thickness [m] at which edge_radius is read; 0: one point spacing
  // (which shrinks with h: a fixed thickness makes a mesh series measure one quantity).
  double edge_thickness = 0;
  // 3D terrain runs: the maps' cell size [m], a whole multiple of the raster's; 0: the raster's.
  double map_cell = 0;
  // The forces on obstacles, walls, base and terrain (obstacle_forces.csv); default: on when the
  // scene has an obstacle. Walls, base and terrain take moments about moment_point (default 0).
  std::optional<bool> forces;
  std::vector<double> moment_point;
  bool forces_on(bool has_obstacles) const { return forces.value_or(has_obstacles); }
};

// The point arrays a VTU frame may carry (output.fields), in the order they are written.
inline const std::vector<std::string>& frame_field_names() {
  static const std::vector<std::string> names = {"velocity", "p",        "q",        "eps_pd",   "T",
                                                 "eta_c",    "K_col",    "e",        "sigma_xx", "sigma_yy",
                                                 "sigma_xy", "material", "body"};
  return names;
}

struct Scene {
  std::string name;
  std::string file;
  int dim = 2;
  std::vector<double> origin, size;  // grid box
  double h = 0;                      // grid spacing
  int ppc_axis = 2;                  // particles per cell along each axis (4 per cell in 2D)
  ShapeKind shape = ShapeKind::Linear;
  // Quadratic B-splines at axis-aligned walls: boundary-modified (interpolatory at the wall,
  // shape.hpp weight_1d) or merely truncated (the held nodes beyond the wall keep their share).
  bool modified_boundary_splines = true;
  double flip = 0.99;
  // > 0: the PIC part is a rate instead of a fraction per step: each step the particle
  // velocities relax towards the grid (PIC) velocity by min(1, pic_speed dt / h), i.e. once
  // per time a signal at pic_speed [m/s] needs to cross a cell; `flip` is then not used. A
  // fixed fraction per step is a transfer viscosity ~ (1 - flip) h^2 / dt that grows as the
  // step shrinks (column run-out 0.23 to 0.28 m at 20 mm between dt 1e-5 and 1e-4 s with
  // flip 0.99); the rate gives ~ pic_speed h, independent of dt, vanishing with h. The paper's
  // scenes use 1 m/s (~ sqrt(g h0) of the column), which is flip 0.99 at 1 mm and dt 1e-5 s.
  double pic_speed = 0;
  // Velocity transfer. FlipPic: P2G of m v, G2P blend of FLIP and PIC (`flip`). TaylorPic:
  // P2G of m (v + L (x_I - x_p)) with the particle's velocity gradient L (Taylor PIC,
  // Nakamura et al. 2023, CMAME 403:115720; APIC with C = L); with flip = 0 the G2P is PIC.
  // PIC damps every velocity field that is not affine on the scale of a cell; the FLIP/PIC
  // blend damps (1 - flip) of it per step, a viscosity of order (1 - flip) h^2 / dt.
  enum class Transfer { FlipPic, TaylorPic };
  Transfer transfer = Transfer::FlipPic;
  bool volumetric_averaging = false;  // cell-averaged tr L in the constitutive update
  // Light nodes (kernels.hpp grid_update_node): below this fraction of the lightest point's mass
  // the internal force accelerates the fraction instead of the node's own mass. It keeps a node
  // reached only by a stencil's edge from flinging its neighbours' points, and it is the one term
  // of the step that does not conserve momentum (docs/mpm_obstacles.md); 0 turns it off.
  double light_node_mass = 0.05;
  Precision precision = Precision::FP64;
  std::vector<double> gravity;

  double dt = 0;         // fixed step, or the first/maximum step when adaptive
  bool adaptive = false;
  double cfl = 0.5;
  // A fixed step is shortened to the stable step at CFL 1 (P-wave plus particle speed, and the
  // viscous limit) wherever that falls below it: the step time.dt gets past the set-up check
  // (the at-rest column) but flowing or impacting material can outrun (issue 52's 2D slide).
  bool cap_to_stable = true;
  // End the run once the flow is at rest (time.stop_at_rest > 0): the kinetic energy of every
  // sample in the last rest_hold seconds of the last stage below stop_at_rest times that
  // stage's peak. The outputs are those of a complete run at that time.
  double stop_at_rest = 0;
  double rest_hold = 0.1;
  // The steps follow the stable limit: adaptive, or a capped fixed step.
  bool limited_steps() const { return adaptive || cap_to_stable; }
  // The Courant number of that limit: time.cfl when adaptive, 1 for the cap of a fixed step.
  double step_cfl() const { return adaptive ? cfl : 1.0; }

  // Material 0: the scene's single [material], or its first [[material]] table; the others
  // follow in other_materials (material i > 0 is other_materials[i - 1]). One model for all.
  Material material;
  std::vector<Material> other_materials;
  InitialStress initial;
  std::vector<Body> bodies;
  std::vector<Wall> walls;
  std::optional<BaseLine> base;
  std::optional<Terrain> terrain;
  std::vector<Obstacle> obstacles;
  std::vector<Stage> stages;

  // Run-out is the curvilinear abscissa, along this polyline, of the front of the contiguous
  // deposit; height is the largest distance above it (the floor in the column collapse).
  std::vector<double> runout_x, runout_y;
  std::vector<Track> tracks;
  std::vector<Gauge> gauges;
  OutputSpec output;
  std::map<std::string, long> lines;  // scene files: line of each key make_setup may name
  // --set assignments applied over the file, as given and in order (a restart must repeat them)
  std::vector<std::string> overrides;

  int material_count() const { return 1 + static_cast<int>(other_materials.size()); }
  const Material& material_at(int i) const { return i == 0 ? material : other_materials.at(i - 1); }
  Material& material_at(int i) { return i == 0 ? material : other_materials.at(i - 1); }
  // Index of the material labelled `label`; -1 when none is.
  int material_index(const std::string& label) const {
    for (int i = 0; i < material_count(); ++i)
      if (material_at(i).label == label) return i;
    return -1;
  }

  double duration() const {
    double t = 0;
    for (const auto& s : stages) t += s.duration;
    return t;
  }
};

// The paper's scenes built in code, fixtures of the tests and of mpm_cuda_check; runs use
// mpm/scenes/*.toml, and a test checks that the files with --set overrides give these scenes.
// Column: 0.1 s damped consolidation with the gate, then `collapse_time` of collapse.
Scene column_scene(double h, double dt, ModelKind model, ShapeKind shape, double collapse_time);
// Flume: 0.1 s damped consolidation behind the gate, then `flow_time` of flow.
Scene flume_scene(double h, double dt, ModelKind model, ShapeKind shape, double flow_time);
// The CI column collapse: 10 mm grid, 4 points per cell, dt 5e-5 s, 0.4 s of collapse.
Scene small_column_scene(ModelKind model, ShapeKind shape = ShapeKind::Linear);
// The CI column as a 3D slab 8 cm wide between free-slip side walls (grid 40 x 16 x 8 cm),
// released at once for `duration` (one stage): mpm_cuda_check's obstacle scene, no obstacle yet.
Scene slab_3d_scene(ModelKind model, ShapeKind shape, double duration);

}  // namespace granflow::mpm
