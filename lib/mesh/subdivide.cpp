// Loop subdivision (C. Loop, "Smooth Subdivision Surfaces Based on Triangles", 1987) through
// OpenSubdiv: Far::TopologyRefiner with Sdc::SCHEME_LOOP and VTX_BOUNDARY_EDGE_ONLY (boundary edges
// are infinitely sharp creases, corners are not pinned), uniform refinement, positions and the
// optional normals/uvs interpolated level by level as vertex primvars with
// Far::PrimvarRefinerReal<double> (normals renormalized at the end). Child faces are traced back to
// their base face with TopologyLevel::GetFaceParentFace to carry the source map. Also: a midpoint
// 1-to-4 fallback and the adaptive per-mesh level selection from the instances' largest scale.
#include <opensubdiv/far/error.h>
#include <opensubdiv/far/primvarRefiner.h>
#include <opensubdiv/far/topologyDescriptor.h>
#include <opensubdiv/far/topologyRefinerFactory.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <memory>
#include <numeric>
#include <unordered_map>

#include "core/error.h"
#include "mesh/mesh.h"
#include "mesh/mesh_util.h"

namespace rtp {
namespace {

namespace Far = OpenSubdiv::Far;
namespace Sdc = OpenSubdiv::Sdc;

// A vertex primvar (position, normal: N = 3; uv: N = 2) as PrimvarRefiner wants it: Clear() and
// AddWithWeight(), accumulated in double.
template <int N>
struct DPrimvar {
  double p[N];
  void Clear(void* = nullptr) {
    for (double& c : p) c = 0;
  }
  void AddWithWeight(const DPrimvar& s, double w) {
    for (int i = 0; i < N; ++i) p[i] += w * s.p[i];
  }
};
using DVertex = DPrimvar<3>;
using DUv = DPrimvar<2>;

// Unit-length float normal of an interpolated one; (0,0,0) when its length is 0 or not finite (a
// "none given" normal stays none).
Vec3f unit_normal(const Vec3d& n) {
  const double len = length(n);
  if (!(len > 0) || !std::isfinite(len)) return {0, 0, 0};
  const Vec3d u = n * (1.0 / len);
  return {float(u.x), float(u.y), float(u.z)};
}

// Interpolates one vertex primvar from the base level to `levels` (vertex rules, as positions).
template <int N>
std::vector<DPrimvar<N>> refine_primvar(const Far::TopologyRefiner& refiner, int levels, std::vector<DPrimvar<N>> src) {
  Far::PrimvarRefinerReal<double> primvar(refiner);
  std::vector<DPrimvar<N>> dst;
  for (int level = 1; level <= levels; ++level) {
    dst.assign(size_t(refiner.GetLevel(level).GetNumVertices()), DPrimvar<N>{});
    DPrimvar<N>* out = dst.data();
    primvar.Interpolate(level, src.data(), out);
    src.swap(dst);
  }
  return src;
}

// OpenSubdiv indexes with int: refuse sizes it cannot represent before allocating anything.
void check_size(const Mesh& mesh, int levels, const char* what) {
  double tris = double(mesh.triangle_count()) * std::pow(4.0, levels);
  if (tris * 3 > double(INT_MAX) || double(mesh.positions.size()) + tris * 3 > double(INT_MAX))
    fail_invalid(std::string(what) + ": mesh '" + mesh.name + "' would have " + std::to_string(tris) + " triangles after " +
                 std::to_string(levels) + " levels, too many");
}

void check_levels(int levels, const char* what) {
  if (levels < 0 || levels > 15)
    throw Error(ExitCode::kUsage, std::string(what) + ": levels must be in [0, 15], got " + std::to_string(levels));
}

// Returns the refiner, or nullptr (with the reason) when OpenSubdiv refuses the topology.
std::unique_ptr<Far::TopologyRefiner> make_refiner(const Mesh& mesh, std::string& reason) {
  const int faces = int(mesh.triangle_count());
  std::vector<int> verts_per_face(faces, 3);
  std::vector<int> face_verts(mesh.indices.begin(), mesh.indices.end());
  Far::TopologyDescriptor desc;
  desc.numVertices = int(mesh.positions.size());
  desc.numFaces = faces;
  desc.numVertsPerFace = verts_per_face.data();
  desc.vertIndicesPerFace = face_verts.data();
  Sdc::Options sdc;
  sdc.SetVtxBoundaryInterpolation(Sdc::Options::VTX_BOUNDARY_EDGE_ONLY);
  using Factory = Far::TopologyRefinerFactory<Far::TopologyDescriptor>;
  Factory::Options options(Sdc::SCHEME_LOOP, sdc);
  try {
    std::unique_ptr<Far::TopologyRefiner> refiner(Factory::Create(desc, options));
    if (!refiner) reason = "OpenSubdiv TopologyRefinerFactory refused the topology";
    return refiner;
  } catch (const std::exception& e) {
    reason = std::string("OpenSubdiv failed: ") + e.what();
    return nullptr;
  }
}

void apply_loop(Mesh& mesh, Far::TopologyRefiner& refiner, int levels) {
  Far::TopologyRefiner::UniformOptions uniform(levels);
  uniform.fullTopologyInLastLevel = false;
  refiner.RefineUniform(uniform);

  // Positions, level by level (double), from the float base positions; the attributes likewise.
  std::vector<DVertex> src(mesh.positions.size());
  for (size_t v = 0; v < mesh.positions.size(); ++v) src[v] = {{mesh.positions[v].x, mesh.positions[v].y, mesh.positions[v].z}};
  src = refine_primvar(refiner, levels, std::move(src));
  std::vector<Vec3f> normals;
  if (!mesh.normals.empty()) {
    std::vector<DVertex> n(mesh.normals.size());
    for (size_t v = 0; v < n.size(); ++v) n[v] = {{mesh.normals[v].x, mesh.normals[v].y, mesh.normals[v].z}};
    n = refine_primvar(refiner, levels, std::move(n));
    normals.resize(n.size());
    for (size_t v = 0; v < n.size(); ++v) normals[v] = unit_normal({n[v].p[0], n[v].p[1], n[v].p[2]});
  }
  std::vector<Vec2f> uvs;
  if (!mesh.uvs.empty()) {
    std::vector<DUv> uv(mesh.uvs.size());
    for (size_t v = 0; v < uv.size(); ++v) uv[v] = {{mesh.uvs[v].x, mesh.uvs[v].y}};
    uv = refine_primvar(refiner, levels, std::move(uv));
    uvs.resize(uv.size());
    for (size_t v = 0; v < uv.size(); ++v) uvs[v] = {float(uv[v].p[0]), float(uv[v].p[1])};
  }

  // Base face of every last-level face, following GetFaceParentFace up the levels.
  const Far::TopologyLevel& last = refiner.GetLevel(levels);
  const int faces = last.GetNumFaces();
  std::vector<int> root(static_cast<size_t>(faces));
  std::iota(root.begin(), root.end(), 0);
  for (int level = levels; level >= 1; --level) {
    const Far::TopologyLevel& lv = refiner.GetLevel(level);
    for (int& f : root) f = lv.GetFaceParentFace(f);
  }
  // OpenSubdiv numbers child faces parent by parent; a stable sort makes that grouping a guarantee.
  std::vector<int> order(static_cast<size_t>(faces));
  std::iota(order.begin(), order.end(), 0);
  if (!std::is_sorted(root.begin(), root.end()))
    std::stable_sort(order.begin(), order.end(), [&](int a, int b) { return root[a] < root[b]; });

  std::vector<uint32_t> indices;
  indices.reserve(size_t(faces) * 3);
  std::vector<TriangleSource> source;
  if (!mesh.source.empty()) source.reserve(size_t(faces));
  for (int f : order) {
    Far::ConstIndexArray fv = last.GetFaceVertices(f);
    if (fv.size() != 3) throw Error(ExitCode::kInternal, "subdivide_uniform: Loop produced a non-triangle");
    for (int k = 0; k < 3; ++k) indices.push_back(uint32_t(fv[k]));
    if (!mesh.source.empty()) source.push_back(mesh.source[size_t(root[f])]);
  }
  std::vector<Vec3f> positions(src.size());
  for (size_t v = 0; v < src.size(); ++v) positions[v] = {float(src[v].p[0]), float(src[v].p[1]), float(src[v].p[2])};
  mesh.positions = std::move(positions);
  mesh.normals = std::move(normals);
  mesh.uvs = std::move(uvs);
  mesh.indices = std::move(indices);
  mesh.source = std::move(source);
}

// One midpoint level: children (a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca), the same layout
// as Loop's; one new vertex per undirected edge, numbered in first-use order. Its attributes are the
// edge's midpoints too, the normal renormalized (unit_normal).
void midpoint_level(Mesh& mesh) {
  const bool has_normals = !mesh.normals.empty(), has_uvs = !mesh.uvs.empty();
  std::unordered_map<uint64_t, uint32_t> edge_vertex;
  edge_vertex.reserve(mesh.indices.size());
  auto mid = [&](uint32_t a, uint32_t b) {
    uint64_t key = a < b ? (uint64_t(a) << 32 | b) : (uint64_t(b) << 32 | a);
    auto [it, inserted] = edge_vertex.try_emplace(key, uint32_t(mesh.positions.size()));
    if (inserted) {
      Vec3d m = (to_d(mesh.positions[a]) + to_d(mesh.positions[b])) * 0.5;
      mesh.positions.push_back({float(m.x), float(m.y), float(m.z)});
      if (has_normals) mesh.normals.push_back(unit_normal(to_d(mesh.normals[a]) + to_d(mesh.normals[b])));
      if (has_uvs)
        mesh.uvs.push_back(
            {float((double(mesh.uvs[a].x) + mesh.uvs[b].x) * 0.5), float((double(mesh.uvs[a].y) + mesh.uvs[b].y) * 0.5)});
    }
    return it->second;
  };
  std::vector<uint32_t> indices;
  indices.reserve(mesh.indices.size() * 4);
  std::vector<TriangleSource> source;
  if (!mesh.source.empty()) source.reserve(mesh.source.size() * 4);
  for (size_t t = 0; t < mesh.indices.size() / 3; ++t) {
    const uint32_t a = mesh.indices[3 * t], b = mesh.indices[3 * t + 1], c = mesh.indices[3 * t + 2];
    const uint32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
    for (uint32_t v : {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca}) indices.push_back(v);
    if (!mesh.source.empty()) source.insert(source.end(), 4, mesh.source[t]);
  }
  mesh.indices = std::move(indices);
  mesh.source = std::move(source);
}

}  // namespace

void subdivide_midpoint(Mesh& mesh, int levels) {
  check_levels(levels, "subdivide_midpoint");
  mesh_detail::validate_mesh(mesh, "subdivide_midpoint");
  check_size(mesh, levels, "subdivide_midpoint");
  for (int i = 0; i < levels; ++i) midpoint_level(mesh);
}

UniformSubdivideResult subdivide_uniform(Mesh& mesh, int levels) {
  check_levels(levels, "subdivide_uniform");
  mesh_detail::validate_mesh(mesh, "subdivide_uniform");
  UniformSubdivideResult result;
  result.levels = levels;
  if (levels == 0 || mesh.triangle_count() == 0) return result;
  check_size(mesh, levels, "subdivide_uniform");
  std::unique_ptr<Far::TopologyRefiner> refiner = make_refiner(mesh, result.fallback_reason);
  if (refiner) {
    apply_loop(mesh, *refiner, levels);
  } else {
    result.used_fallback = true;
    for (int i = 0; i < levels; ++i) midpoint_level(mesh);
  }
  return result;
}

double longest_edge(const Mesh& mesh) {
  double longest = 0;
  for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = mesh.indices[t + k], b = mesh.indices[t + (k + 1) % 3];
      if (a >= mesh.positions.size() || b >= mesh.positions.size()) continue;
      const double l = length(to_d(mesh.positions[a]) - to_d(mesh.positions[b]));
      if (std::isfinite(l)) longest = std::max(longest, l);
    }
  return longest;
}

SubdivideReport subdivide_to_length(Scene& scene, double max_edge_length, int max_levels) {
  if (!(max_edge_length > 0) || !std::isfinite(max_edge_length))
    throw Error(ExitCode::kUsage, "subdivide_to_length: max_edge_length must be finite and > 0");
  check_levels(max_levels, "subdivide_to_length");

  SubdivideReport report;
  report.meshes.resize(scene.meshes.size());
  for (uint32_t m = 0; m < scene.meshes.size(); ++m) {
    mesh_detail::validate_mesh(scene.meshes[m], "subdivide_to_length");
    report.meshes[m].mesh = m;
  }
  // Largest scale per mesh over the instances that reference it (serial: instance order is fixed).
  for (size_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    if (inst.mesh >= scene.meshes.size())
      fail_invalid("subdivide_to_length: instance " + std::to_string(i) + " references mesh " + std::to_string(inst.mesh) +
                   " of " + std::to_string(scene.meshes.size()));
    MeshSubdivideReport& r = report.meshes[inst.mesh];
    r.instanced = true;
    r.max_scale = std::max(r.max_scale, inst.transform.max_scale());
  }

  // Each mesh once, independently: the outcome per mesh does not depend on scheduling.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, scene.meshes.size(), 1), [&](const tbb::blocked_range<size_t>& range) {
    for (size_t m = range.begin(); m != range.end(); ++m) {
      Mesh& mesh = scene.meshes[m];
      MeshSubdivideReport& r = report.meshes[m];
      r.triangles_before = r.triangles_after = mesh.triangle_count();
      r.longest_world_edge_before = longest_edge(mesh) * r.max_scale;
      r.longest_world_edge_after = r.longest_world_edge_before;
      if (!r.instanced || r.longest_world_edge_before < max_edge_length) continue;
      while (r.levels < max_levels && !(r.longest_world_edge_after < max_edge_length)) {
        UniformSubdivideResult u = subdivide_uniform(mesh, 1);
        r.used_fallback = r.used_fallback || u.used_fallback;
        ++r.levels;
        r.longest_world_edge_after = longest_edge(mesh) * r.max_scale;
      }
      r.hit_cap = !(r.longest_world_edge_after < max_edge_length);
      r.triangles_after = mesh.triangle_count();
    }
  });

  for (const MeshSubdivideReport& r : report.meshes) {
    report.meshes_subdivided += r.levels > 0;
    report.meshes_at_cap += r.hit_cap;
    report.triangles_before += r.triangles_before;
    report.triangles_after += r.triangles_after;
  }
  return report;
}

}  // namespace rtp
