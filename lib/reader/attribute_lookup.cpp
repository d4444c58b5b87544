// Hit -> shading attributes: (instance -> mesh) from the instance table, (mesh, prim) -> attribute
// entry and its triangle, barycentric interpolation, inverse-transpose to world space (L^-1 from the
// instance's record in the batching point the table names, SPEC §2.5).
#include "reader/attribute_lookup.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>

#include "core/error.h"
#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "reader/check_chunks.h"
#include "layout/chunk_io.h"

namespace rtp {

namespace {

using Tri = std::array<uint32_t, 3>;

// Where the attributes of one triangle live.
struct Loc {
  uint32_t chunk = fmt::kNoAttribute;  // index into Impl::chunks
  uint32_t entry = 0;
  uint32_t triangle = 0;  // local triangle within the entry
};

struct Chunk {
  AlignedBytes bytes;
  const fmt::AttributeEntry* entries = nullptr;
  const Tri* tris = nullptr;
  const std::array<float, 3>* normals = nullptr;
  const std::array<float, 2>* uvs = nullptr;
  uint64_t n_entries = 0, n_tris = 0, n_normals = 0, n_uvs = 0;
};

}  // namespace

// Keyed tables, sorted once loaded: their size follows the entries and ids stored in the file, never a
// declared mesh id or prim (a hostile id costs one element, not a table up to it).
struct AttributeLookup::Impl {
  using Key = std::pair<uint32_t, uint32_t>;  // (mesh, prim); whole meshes use prim 0
  std::vector<fmt::InstanceRef> instances;
  std::vector<std::array<float, 9>> inverse_linear;  // per instance, read from the points only for normals
  std::vector<Chunk> chunks;
  std::vector<std::pair<Key, Loc>> whole;    // scene meshes stored whole (segment meshes)
  std::vector<std::pair<Key, Loc>> per_tri;  // scene meshes stored as pieces: per triangle
  bool normals = false, uvs = false;

  static const Loc* lookup(const std::vector<std::pair<Key, Loc>>& v, Key k) {
    auto it = std::lower_bound(v.begin(), v.end(), k, [](const std::pair<Key, Loc>& a, const Key& b) { return a.first < b; });
    return it != v.end() && it->first == k ? &it->second : nullptr;
  }
  Loc find(uint32_t mesh, uint32_t prim) const {
    if (const Loc* l = lookup(per_tri, {mesh, prim})) return *l;
    if (const Loc* l = lookup(whole, {mesh, 0})) {
      Loc out = *l;
      out.triangle = prim;
      return out;
    }
    return {};
  }
};

namespace {

// Normals go to world space by their instance's L^-1, which only the batching points store: each point
// the table names is read once, its records' L^-1 copied to the instances placed there.
void load_inverse_linear(const PackageReader& r, const std::vector<fmt::InstanceRef>& instances,
                         std::vector<std::array<float, 9>>& inverse_linear) {
  inverse_linear.assign(instances.size(), {});
  std::map<uint32_t, std::vector<uint32_t>> by_point;  // keyed: a hostile point id costs one entry
  for (uint32_t g = 0; g < instances.size(); ++g)
    if (instances[g].point != fmt::InstanceRef::kNoPoint) by_point[instances[g].point].push_back(g);
  for (const auto& [p, ids] : by_point) {
    const int64_t i = r.find(fmt::ChunkKind::kBatchingPoint, p);
    if (i < 0) fail_invalid("instance table: batching point " + std::to_string(p) + " has no chunk");
    const AlignedBytes b = r.read(size_t(i));
    const std::string label = chunk_label(r.toc()[size_t(i)], size_t(i));
    ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kBatchingPoint), label);
    uint64_t n = 0, n_ids = 0;
    const fmt::InstanceRecord* rec = v.get<fmt::InstanceRecord>(fmt::SectionType::kInstances, n);
    const uint32_t* global = v.get<uint32_t>(fmt::SectionType::kGlobalIds, n_ids);
    for (uint32_t g : ids) {
      const uint32_t k = instances[g].local;
      if (k >= n || k >= n_ids || global[k] != g)
        fail_invalid("instance table: instance " + std::to_string(g) + ": local " + std::to_string(k) + " of " + label +
                     (k >= n || k >= n_ids ? " is outside its " + std::to_string(n) + " records"
                                           : " is instance " + std::to_string(global[k])));
      std::copy(std::begin(rec[k].inverse_linear), std::end(rec[k].inverse_linear), inverse_linear[g].begin());
    }
  }
}

}  // namespace

AttributeLookup::~AttributeLookup() = default;
bool AttributeLookup::has_normals() const { return impl_->normals; }
bool AttributeLookup::has_uvs() const { return impl_->uvs; }

AttributeLookup::AttributeLookup(const PackageReader& r) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  const auto& toc = r.toc();
  const int64_t ii = r.find(fmt::ChunkKind::kInstances, 0);
  if (ii < 0) fail_invalid("the package has no instance table");
  {
    const AlignedBytes b = r.read(size_t(ii));
    ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kInstances), chunk_label(toc[size_t(ii)], size_t(ii)));
    m.instances = v.copy<fmt::InstanceRef>(fmt::SectionType::kInstanceRefs);
  }
  for (size_t i = 0; i < toc.size(); ++i) {
    const uint32_t kind = toc[i].kind;
    if (kind != uint32_t(fmt::ChunkKind::kSegmentAttributes) && kind != uint32_t(fmt::ChunkKind::kPointAttributes)) continue;
    const std::string label = chunk_label(toc[i], i);
    Chunk c;
    c.bytes = r.read(i);
    ChunkView v(c.bytes.data(), c.bytes.size(), kind, label);
    c.entries = v.get<fmt::AttributeEntry>(fmt::SectionType::kAttrEntries, c.n_entries);
    c.tris = v.get<Tri>(fmt::SectionType::kAttrTriangles, c.n_tris);
    c.normals = v.get<std::array<float, 3>>(fmt::SectionType::kAttrNormals, c.n_normals, false);
    c.uvs = v.get<std::array<float, 2>>(fmt::SectionType::kAttrUvs, c.n_uvs, false);
    uint64_t n_ids = 0;
    const uint32_t* ids = v.get<uint32_t>(fmt::SectionType::kAttrTriIds, n_ids, false);
    const uint32_t ci = uint32_t(m.chunks.size());
    for (uint32_t k = 0; k < c.n_entries; ++k) {
      const fmt::AttributeEntry& e = c.entries[k];
      const bool has_n = e.normal_first != fmt::kNoAttribute, has_uv = e.uv_first != fmt::kNoAttribute;
      if (!has_n && !has_uv) continue;
      // Every index a lookup can follow is checked here, once.
      const std::string ranges = attribute_entry_ranges(e, c.n_tris, c.n_normals, c.n_uvs, n_ids);  // 64-bit safe
      if (!ranges.empty()) fail_invalid(label + ": entry " + std::to_string(k) + ": " + ranges);
      for (uint64_t t = 0; t < e.triangle_count; ++t)
        for (uint32_t vi : c.tris[e.triangle_first + t])
          if (vi >= e.vertex_count) fail_invalid(label + ": entry " + std::to_string(k) + ": vertex index out of range");
      m.normals |= has_n;
      m.uvs |= has_uv;
      if (e.tri_id_first == fmt::kNoAttribute) {
        m.whole.push_back({{e.mesh, 0}, {ci, k, 0}});
      } else {
        for (uint32_t t = 0; t < e.triangle_count; ++t) m.per_tri.push_back({{e.mesh, ids[e.tri_id_first + t]}, {ci, k, t}});
      }
    }
    m.chunks.push_back(std::move(c));
  }
  if (m.normals) load_inverse_linear(r, m.instances, m.inverse_linear);
  // Sorted by key; for a key stored twice the last one stored wins (as the direct tables did).
  for (auto* v : {&m.whole, &m.per_tri}) {
    std::stable_sort(v->begin(), v->end(), [](const auto& a, const auto& b) { return a.first < b.first; });
    auto last = std::unique(v->rbegin(), v->rend(), [](const auto& a, const auto& b) { return a.first == b.first; });
    v->erase(v->begin(), last.base());
  }
}

fmt::Shading AttributeLookup::shade(const fmt::Hit& hit) const {
  const Impl& m = *impl_;
  fmt::Shading s{};
  if (hit.instance >= m.instances.size()) return s;
  const fmt::InstanceRef& rec = m.instances[hit.instance];
  const Loc loc = m.find(rec.mesh, hit.prim);
  if (loc.chunk == fmt::kNoAttribute) return s;
  const Chunk& c = m.chunks[loc.chunk];
  const fmt::AttributeEntry& e = c.entries[loc.entry];
  if (loc.triangle >= e.triangle_count) return s;
  const Tri& tri = c.tris[e.triangle_first + loc.triangle];
  const double w[3] = {1.0 - double(hit.u) - double(hit.v), double(hit.u), double(hit.v)};
  if (e.normal_first != fmt::kNoAttribute) {
    double n[3] = {0, 0, 0};
    for (int k = 0; k < 3; ++k)
      for (int a = 0; a < 3; ++a) n[a] += w[k] * c.normals[e.normal_first + tri[size_t(k)]][size_t(a)];
    // Normals transform by the inverse transpose of local->world: the transpose of world->local.
    const float* wl = m.inverse_linear[hit.instance].data();
    double out[3], len2 = 0;
    for (int a = 0; a < 3; ++a) {
      out[a] = wl[a] * n[0] + wl[3 + a] * n[1] + wl[6 + a] * n[2];
      len2 += out[a] * out[a];
    }
    if (len2 > 0 && std::isfinite(len2))
      for (int a = 0; a < 3; ++a) s.normal[a] = float(out[a] / std::sqrt(len2));
  }
  if (e.uv_first != fmt::kNoAttribute)
    for (int a = 0; a < 2; ++a) {
      double t = 0;
      for (int k = 0; k < 3; ++k) t += w[k] * c.uvs[e.uv_first + tri[size_t(k)]][size_t(a)];
      s.uv[a] = float(t);
    }
  return s;
}

}  // namespace rtp
