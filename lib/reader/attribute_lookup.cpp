// Hit -> shading attributes: (instance -> mesh) from the instance table, (mesh, prim) -> attribute
// entry and its triangle, barycentric interpolation, inverse-transpose to world space.
#include "reader/attribute_lookup.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>

#include "core/error.h"
#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "reader/check_chunks.h"
#include "reader/chunk_io.h"

namespace rtp {

namespace {

using Tri = std::array<uint32_t, 3>;

// Where the attributes of one triangle live.
struct Loc {
  uint32_t chunk = fmt::kNoAttribute;  // index into Impl::chunks
  uint32_t entry = 0;
  uint32_t triangle = 0;               // local triangle within the entry
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
  std::vector<fmt::InstanceRecord> instances;
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
    m.instances = v.copy<fmt::InstanceRecord>(fmt::SectionType::kInstances);
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
  const fmt::InstanceRecord& rec = m.instances[hit.instance];
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
    const float* wl = rec.inverse_linear;
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
