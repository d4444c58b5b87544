// Mesh clean-up: drop non-finite and degenerate triangles, optional vertex welding on a uniform grid
// hash, compaction of unreferenced vertices, and a topology report. Non-manifold configurations are
// reported (via edge incidence counts and OpenMesh's half-edge construction, which refuses faces
// that would create a "complex edge" or "complex vertex", see OpenMesh PolyConnectivity::add_face)
// but never removed.
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <mutex>
#include <unordered_map>

#include "core/error.h"
#include "mesh/mesh.h"
#include "mesh/mesh_util.h"

namespace rtp {
namespace {

using OmMesh = OpenMesh::TriMesh_ArrayKernelT<>;

// ---- welding --------------------------------------------------------------------------------------

struct CellKey {
  int64_t x, y, z;
  bool operator==(const CellKey&) const = default;
};
struct CellHash {
  size_t operator()(const CellKey& k) const {
    uint64_t h = uint64_t(k.x) * 0x9E3779B97F4A7C15ull;
    h ^= uint64_t(k.y) * 0xC2B2AE3D27D4EB4Full + (h << 6) + (h >> 2);
    h ^= uint64_t(k.z) * 0x165667B19E3779F9ull + (h << 6) + (h >> 2);
    return size_t(h);
  }
};

// Grid cell of one coordinate. eps > 0: floor(c / eps), clamped (clamping is monotone and
// 1-Lipschitz, so two values within eps stay in the same or adjacent cells). eps == 0: the exact
// value's bits (with -0 folded into +0), so only exact duplicates share a cell.
int64_t cell_of(float c, double eps) {
  if (eps == 0) {
    if (c == 0) c = 0.0f;
    uint32_t bits;
    std::memcpy(&bits, &c, sizeof bits);
    return int64_t(bits);
  }
  double q = std::floor(double(c) / eps);
  constexpr double kLimit = 4.0e18;
  return int64_t(std::clamp(q, -kLimit, kLimit));
}

// Same attributes: bitwise equal normal and uv, each compared only when its array is present. A
// normal or uv seam (hard edge, UV island border) has coincident vertices that must stay apart.
bool same_attributes(const Mesh& mesh, uint32_t a, uint32_t b) {
  if (!mesh.normals.empty() && std::memcmp(&mesh.normals[a], &mesh.normals[b], sizeof(Vec3f)) != 0) return false;
  return mesh.uvs.empty() || std::memcmp(&mesh.uvs[a], &mesh.uvs[b], sizeof(Vec2f)) == 0;
}

// Deterministic welding: vertices are visited in index order; each one merges into the lowest-index
// representative within eps (L-infinity) with the same attributes found in the 27 neighbouring
// cells, or becomes a representative itself. Merging is never transitive (every merged vertex is
// within eps of its representative), and the result does not depend on hash-map iteration order.
uint64_t weld_vertices(const Mesh& mesh, const std::vector<char>& referenced, double eps, std::vector<uint32_t>& remap) {
  remap.resize(mesh.positions.size());
  for (uint32_t v = 0; v < remap.size(); ++v) remap[v] = v;
  std::unordered_map<CellKey, std::vector<uint32_t>, CellHash> grid;
  grid.reserve(mesh.positions.size());
  const int reach = eps == 0 ? 0 : 1;
  uint64_t welded = 0;
  for (uint32_t v = 0; v < mesh.positions.size(); ++v) {
    if (!referenced[v]) continue;
    const Vec3f& p = mesh.positions[v];
    const CellKey key{cell_of(p.x, eps), cell_of(p.y, eps), cell_of(p.z, eps)};
    uint32_t best = kNoIndex;
    for (int dx = -reach; dx <= reach; ++dx)
      for (int dy = -reach; dy <= reach; ++dy)
        for (int dz = -reach; dz <= reach; ++dz) {
          auto it = grid.find({key.x + dx, key.y + dy, key.z + dz});
          if (it == grid.end()) continue;
          for (uint32_t r : it->second) {
            const Vec3f& q = mesh.positions[r];
            if (r < best && std::abs(double(p.x) - q.x) <= eps && std::abs(double(p.y) - q.y) <= eps &&
                std::abs(double(p.z) - q.z) <= eps && same_attributes(mesh, v, r))
              best = r;
          }
        }
    if (best != kNoIndex) {
      remap[v] = best;
      ++welded;
    } else {
      grid[key].push_back(v);
    }
  }
  return welded;
}

// ---- degeneracy -----------------------------------------------------------------------------------

// Repeated index, or exactly zero area: the cross product of the edge vectors, evaluated in double,
// is the zero vector (the three points are collinear). A needle with tiny but non-zero area is kept.
bool is_degenerate(const Mesh& mesh, uint32_t a, uint32_t b, uint32_t c) {
  if (a == b || b == c || c == a) return true;
  const Vec3d pa = to_d(mesh.positions[a]);
  const Vec3d n = cross(to_d(mesh.positions[b]) - pa, to_d(mesh.positions[c]) - pa);
  return n.x == 0 && n.y == 0 && n.z == 0;
}

// ---- topology -------------------------------------------------------------------------------------

// Silences OpenMesh's error stream (add_face logs "complex edge"/"complex vertex" for every refused
// face) while the analysis runs. The stream is global, so concurrent clean_mesh calls share one guard.
class OmErrSilencer {
 public:
  OmErrSilencer() {
    std::lock_guard<std::mutex> lock(mutex());
    if (depth()++ == 0) {
      was_enabled() = omerr().is_enabled();
      omerr().disable();
    }
  }
  ~OmErrSilencer() {
    std::lock_guard<std::mutex> lock(mutex());
    if (--depth() == 0 && was_enabled()) omerr().enable();
  }
  OmErrSilencer(const OmErrSilencer&) = delete;
  OmErrSilencer& operator=(const OmErrSilencer&) = delete;

 private:
  static std::mutex& mutex() {
    static std::mutex m;
    return m;
  }
  static int& depth() {
    static int d = 0;
    return d;
  }
  static bool& was_enabled() {
    static bool e = true;
    return e;
  }
};

// Edge incidence: boundary = used once, non-manifold = used > 2 times. Edges are bucketed by their
// smaller vertex (a counting sort, linear) and each bucket's few larger vertices are sorted on their
// own: the same counts as sorting every edge key, without the O(E log E) sort that was 4 % of a
// FlightHelmet convert. The indices are valid here (clean_mesh has rebuilt the mesh).
void count_edges(const Mesh& mesh, CleanReport& report) {
  const size_t nv = mesh.positions.size();
  std::vector<uint32_t> first(nv + 1, 0);
  auto each_edge = [&](auto&& f) {
    for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
      for (int k = 0; k < 3; ++k) {
        const uint32_t a = mesh.indices[t + k], b = mesh.indices[t + (k + 1) % 3];
        f(std::min(a, b), std::max(a, b));
      }
  };
  each_edge([&](uint32_t a, uint32_t) { ++first[a + 1]; });
  for (size_t v = 0; v < nv; ++v) first[v + 1] += first[v];
  std::vector<uint32_t> other(first[nv]), fill(first.begin(), first.end() - 1);
  each_edge([&](uint32_t a, uint32_t b) { other[fill[a]++] = b; });
  for (size_t v = 0; v < nv; ++v) {
    uint32_t* const lo = other.data() + first[v];
    uint32_t* const hi = other.data() + first[v + 1];
    std::sort(lo, hi);
    for (uint32_t* i = lo; i < hi;) {
      uint32_t* j = i;
      while (j < hi && *j == *i) ++j;
      if (j - i == 1) ++report.boundary_edges;
      if (j - i > 2) ++report.nonmanifold_edges;
      i = j;
    }
  }
}

// Builds the OpenMesh half-edge structure in triangle order: faces add_face refuses (complex
// edge/vertex: a half-edge already in use, inconsistent winding, a fan that cannot be closed) and
// vertices OpenMesh considers non-manifold are counted.
void analyze_with_openmesh(const Mesh& mesh, CleanReport& report) {
  OmErrSilencer silence;
  OmMesh om;
  om.reserve(mesh.positions.size(), mesh.indices.size() / 2 + 3, mesh.indices.size() / 3);
  std::vector<OmMesh::VertexHandle> vh;
  vh.reserve(mesh.positions.size());
  for (const Vec3f& p : mesh.positions) vh.push_back(om.add_vertex(OmMesh::Point(p.x, p.y, p.z)));
  for (size_t t = 0; t < mesh.indices.size(); t += 3) {
    OmMesh::FaceHandle f = om.add_face(vh[mesh.indices[t]], vh[mesh.indices[t + 1]], vh[mesh.indices[t + 2]]);
    if (!f.is_valid()) ++report.nonmanifold_faces;
  }
  for (OmMesh::VertexHandle v : om.vertices())
    if (!om.is_manifold(v)) ++report.nonmanifold_vertices;
}

}  // namespace

CleanReport clean_mesh(Mesh& mesh, const CleanOptions& opt) {
  mesh_detail::validate_mesh(mesh, "clean_mesh");
  if (!(opt.weld_eps < 0) && !std::isfinite(opt.weld_eps)) throw Error(ExitCode::kUsage, "clean_mesh: weld_eps must be finite");
  CleanReport report;
  const uint32_t tri_count = uint32_t(mesh.indices.size() / 3);
  const uint64_t old_vertices = mesh.positions.size();

  // 1. Non-finite triangles.
  std::vector<char> vertex_finite(mesh.positions.size());
  for (size_t v = 0; v < mesh.positions.size(); ++v) vertex_finite[v] = is_finite(mesh.positions[v]);
  std::vector<uint32_t> finite_tris;
  finite_tris.reserve(tri_count);
  for (uint32_t t = 0; t < tri_count; ++t) {
    const uint32_t* i = &mesh.indices[3 * size_t(t)];
    if (vertex_finite[i[0]] && vertex_finite[i[1]] && vertex_finite[i[2]])
      finite_tris.push_back(t);
    else
      ++report.nonfinite_removed;
  }

  // 2. Optional welding of the vertices the remaining triangles use.
  std::vector<uint32_t> remap(mesh.positions.size());
  for (uint32_t v = 0; v < remap.size(); ++v) remap[v] = v;
  if (opt.weld_eps >= 0) {
    std::vector<char> referenced(mesh.positions.size(), 0);
    for (uint32_t t : finite_tris)
      for (int k = 0; k < 3; ++k) referenced[mesh.indices[3 * size_t(t) + k]] = 1;
    report.welded_vertices = weld_vertices(mesh, referenced, opt.weld_eps, remap);
  }

  // 3. Degenerate triangles, judged on the welded indices and positions.
  std::vector<uint32_t> kept;
  kept.reserve(finite_tris.size());
  for (uint32_t t : finite_tris) {
    const uint32_t* i = &mesh.indices[3 * size_t(t)];
    if (is_degenerate(mesh, remap[i[0]], remap[i[1]], remap[i[2]]))
      ++report.degenerate_removed;
    else
      kept.push_back(t);
  }

  // 4. Rebuild: kept triangles in order, referenced vertices (with their attributes) in order.
  mesh_detail::extract_triangles(mesh, kept, mesh, &remap);
  report.unused_vertices_removed = old_vertices - mesh.positions.size() - report.welded_vertices;

  // 5. Topology report.
  count_edges(mesh, report);
  if (opt.topology) {
    analyze_with_openmesh(mesh, report);
    report.topology_analysed = true;
  }
  return report;
}

}  // namespace rtp
