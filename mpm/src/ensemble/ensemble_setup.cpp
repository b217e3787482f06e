// One set-up of the members of an ensemble (ensemble.hpp): particles member after member,
// stage blocks mask_stride bytes apart, the scene's materials per member.
#include <algorithm>
#include <cstring>
#include <sstream>
#include <string>

#include <granflow/mpm/ensemble.hpp>

namespace granflow::mpm {

namespace {

// Field of n points with `comps` components (component-major), members appended.
void append(std::vector<double>& out, const std::vector<double>& in, int comps, long n, long n_total, int k) {
  out.resize(static_cast<size_t>(comps) * n_total);
  for (int c = 0; c < comps; ++c)
    std::copy(in.begin() + c * n, in.begin() + (c + 1) * n, out.begin() + c * n_total + k * n);
}

void require(bool same, int k, const std::string& key, const std::string& what) {
  if (same) return;
  std::ostringstream os;
  os << "member " << k << " differs from member 0 in " << what
     << "; members may differ in material parameters, initial state, wall and base friction and gate speed only";
  throw SceneError(key, os.str());
}

}  // namespace

SceneSetup make_ensemble_setup(const std::vector<SceneSetup>& members) {
  if (members.empty()) throw SceneError("ensemble", "no members");
  const SceneSetup& m0 = members[0];
  const Scene& s0 = m0.scene;
  const int nm = static_cast<int>(members.size());
  const long n = m0.particles.n;
  if (s0.terrain)  // terrain is 3D; ensembles are compiled for 2D scenes
    throw SceneError("terrain", "ensembles run 2D scenes only; a scene with terrain runs alone (granflow mpm)");
  for (size_t b = 0; b < s0.bodies.size(); ++b)
    if (s0.bodies[b].is_mesh())
      throw SceneError("body[" + std::to_string(b) + "].mesh", "ensembles take no meshes; a scene with a mesh runs alone (granflow mpm)");
  for (const Obstacle& o : s0.obstacles)
    if (o.shape == Obstacle::Shape::Mesh)
      throw SceneError(o.key + ".mesh", "ensembles take no meshes; a scene with a mesh runs alone (granflow mpm)");
  if (s0.stop_at_rest > 0)  // the members share one time loop to the scene's end
    throw SceneError("time.stop_at_rest", "ensembles run every member to the scene's end; leave stop_at_rest out");
  for (int k = 1; k < nm; ++k) {
    const SceneSetup& m = members[k];
    const Scene& s = m.scene;
    require(s.dim == s0.dim && m.nodes == m0.nodes && m.origin == m0.origin && s.h == s0.h, k, "grid", "the grid");
    require(m.particles.n == n && s.ppc_axis == s0.ppc_axis, k, "body", "the particles (count)");
    require(s.material.model == s0.material.model, k, "material.model", "the model");
    require(s.material_count() == s0.material_count() && m.point_material == m0.point_material, k, "material",
            "the materials (count, or which points have which)");
    require(s.shape == s0.shape && s.modified_boundary_splines == s0.modified_boundary_splines, k, "solver.shape",
            "the shape functions");
    require(s.precision == s0.precision, k, "solver.precision", "the precision");
    require(s.dt == s0.dt && s.adaptive == s0.adaptive && s.cfl == s0.cfl && s.cap_to_stable == s0.cap_to_stable, k, "time", "the time stepping");
    require(s.flip == s0.flip && s.pic_speed == s0.pic_speed && s.transfer == s0.transfer &&
                s.volumetric_averaging == s0.volumetric_averaging,
            k, "solver", "the transfer scheme");
    require(s.gravity == s0.gravity, k, "gravity", "gravity");
    bool stages = s.stages.size() == s0.stages.size();
    for (size_t i = 0; stages && i < s.stages.size(); ++i)
      stages = s.stages[i].duration == s0.stages[i].duration && s.stages[i].damping == s0.stages[i].damping &&
               s.stages[i].flip == s0.stages[i].flip;
    require(stages, k, "stage", "the stages (count, durations, damping, flip)");
    require(s.output.times == s0.output.times && s.output.series_dt == s0.output.series_dt, k, "output",
            "the output times");
    require(m.has_boundary == m0.has_boundary && m.stage_masks.size() == m0.stage_masks.size(), k, "wall",
            "the boundaries");
  }

  SceneSetup su;
  su.scene = s0;
  su.origin = m0.origin;
  su.nodes = m0.nodes;
  su.walls = m0.walls;
  su.n_nodes = m0.n_nodes;
  su.spacing = m0.spacing;
  su.has_boundary = m0.has_boundary;
  su.tracked = m0.tracked;
  su.members = nm;
  su.dt_estimate = m0.dt_estimate;

  HostParticles& hp = su.particles;
  const int D = m0.particles.dim;
  hp.dim = D;
  hp.n = n * nm;
  for (int k = 0; k < nm; ++k) {
    const HostParticles& p = members[k].particles;
    append(hp.x, p.x, D, n, hp.n, k);
    append(hp.v, p.v, D, n, hp.n, k);
    append(hp.m, p.m, 1, n, hp.n, k);
    append(hp.sig, p.sig, 6, n, hp.n, k);
    append(hp.sigf, p.sigf, 6, n, hp.n, k);
    append(hp.L, p.L, D * D, n, hp.n, k);
    append(hp.eps, p.eps, 1, n, hp.n, k);
    append(hp.e, p.e, 1, n, hp.n, k);
    append(hp.s, p.s, 1, n, hp.n, k);
    for (int j = 0; j < s0.material_count(); ++j) su.member_materials.push_back(members[k].scene.material_at(j));
    su.point_body.insert(su.point_body.end(), members[k].point_body.begin(), members[k].point_body.end());
    su.point_material.insert(su.point_material.end(), members[k].point_material.begin(),
                             members[k].point_material.end());
    su.dt_estimate = std::min(su.dt_estimate, members[k].dt_estimate);
  }

  // Stage blocks: member k's at k * stride (16-byte aligned, for the contact table's doubles).
  size_t stride = 0;
  for (const SceneSetup& m : members)
    for (const auto& b : m.stage_masks) stride = std::max(stride, b.size());
  stride = (stride + 15) / 16 * 16;
  su.mask_stride = static_cast<long>(stride);
  for (size_t s = 0; s < m0.stage_masks.size(); ++s) {
    std::vector<std::uint8_t> block(stride * nm, 0);
    bool contacts = false;
    for (int k = 0; k < nm; ++k) {
      const auto& b = members[k].stage_masks[s];
      std::memcpy(block.data() + k * stride, b.data(), b.size());
      contacts = contacts || stage_has_contacts(members[k], static_cast<int>(s));
    }
    su.stage_masks.push_back(std::move(block));
    su.stage_contacts.push_back(contacts ? 1 : 0);
  }
  // Obstacles and force probes: each member's, its nodes offset by its grid block; parts and
  // boundaries member after member (member k's boundary b is k * boundaries + b).
  for (int k = 0; k < nm; ++k) {
    const SceneSetup& m = members[k];
    require(m.force_parts.size() == m0.force_parts.size() && m.force_boundaries == m0.force_boundaries, k,
            "obstacle", "the obstacles and the boundaries whose forces are measured");
    const long off = static_cast<long>(k) * m0.n_nodes, p0 = static_cast<long>(su.probes.size());
    const int q0 = static_cast<int>(su.force_parts.size()), b0 = static_cast<int>(su.force_boundaries.size());
    for (ObstacleNode o : m.obstacle_nodes) {
      o.node += off;
      su.obstacle_nodes.push_back(o);
    }
    for (ForceProbe p : m.probes) {
      p.node += off;
      p.part += q0;
      su.probes.push_back(p);
    }
    for (ForcePart q : m.force_parts) {
      q.boundary += b0;
      q.first += p0;
      su.force_parts.push_back(q);
    }
    su.force_boundaries.insert(su.force_boundaries.end(), m.force_boundaries.begin(), m.force_boundaries.end());
  }
  return su;
}

Frame member_frame(const Frame& all, int k, long n) {
  Frame f;
  f.n = n;
  f.dim = all.dim;
  const long N = all.n;
  auto slice = [&](const std::vector<double>& in, int comps, std::vector<double>& out) {
    if (in.empty()) return;
    out.resize(static_cast<size_t>(comps) * n);
    for (int c = 0; c < comps; ++c)
      std::copy(in.begin() + c * N + k * n, in.begin() + c * N + (k + 1) * n, out.begin() + c * n);
  };
  slice(all.x, all.dim, f.x);
  slice(all.v, all.dim, f.v);
  slice(all.T, 1, f.T);
  for (auto [in, out] : {std::pair{&all.p, &f.p}, {&all.q, &f.q}, {&all.eps_pd, &f.eps_pd}, {&all.eta_c, &f.eta_c},
                         {&all.K_col, &f.K_col}, {&all.e, &f.e}, {&all.sxx, &f.sxx}, {&all.syy, &f.syy},
                         {&all.sxy, &f.sxy}})
    slice(*in, 1, *out);
  for (auto [in, out] : {std::pair{&all.material, &f.material}, {&all.body, &f.body}})
    if (!in->empty()) out->assign(in->begin() + k * n, in->begin() + (k + 1) * n);
  return f;
}

}  // namespace granflow::mpm
