// Attribute chunk checks (SPEC §4.4): one chunk at a time, then against its geometry chunk.
#include "inspect/inspect_attributes.h"

#include <cmath>

#include "core/error.h"
#include "reader/check_chunks.h"
#include "layout/chunk_io.h"
#include "inspect/inspect.h"

namespace rtp::inspect_detail {
namespace {

uint32_t geometry_kind(uint32_t attr_kind) {
  return attr_kind == uint32_t(fmt::ChunkKind::kSegmentAttributes) ? uint32_t(fmt::ChunkKind::kMeshSegment)
                                                                   : uint32_t(fmt::ChunkKind::kBatchingPoint);
}

uint64_t mix(uint64_t x) {  // splitmix64 finalizer
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

}  // namespace

uint64_t prim_set_hash(const std::vector<uint32_t>& prims) {
  uint64_t h = mix(prims.size());
  for (uint32_t p : prims) h += mix(p);
  return h;
}

void AttributeChecker::geometry(uint32_t kind, uint64_t id, std::vector<GeometryEntry> entries) {
  geometry_[{kind, id}] = std::move(entries);
}

void AttributeChecker::chunk(uint32_t kind, uint64_t id, const std::string& label, const AlignedBytes& bytes, Problems& out) {
  Seen& s = attrs_[{geometry_kind(kind), id}];
  s.label = label;
  try {
    ChunkView v(bytes.data(), bytes.size(), kind, label);
    uint64_t ne = 0, nt = 0, nn = 0, nu = 0, ni = 0;
    const fmt::AttributeEntry* e = v.get<fmt::AttributeEntry>(fmt::SectionType::kAttrEntries, ne);
    const auto* tri = v.get<std::array<uint32_t, 3>>(fmt::SectionType::kAttrTriangles, nt);
    const auto* nrm = v.get<std::array<float, 3>>(fmt::SectionType::kAttrNormals, nn, false);
    const auto* uv = v.get<std::array<float, 2>>(fmt::SectionType::kAttrUvs, nu, false);
    const uint32_t* ids = v.get<uint32_t>(fmt::SectionType::kAttrTriIds, ni, false);
    s.entries.assign(e, e + ne);
    s.tri_hash.assign(ne, 0);
    uint64_t bad_idx = 0, bad_n = 0, bad_uv = 0;
    for (uint64_t k = 0; k < ne; ++k) {
      const fmt::AttributeEntry& a = e[k];
      const std::string what = label + ": entry " + str(k) + " (id " + str(a.id) + ")";
      const std::string ranges = attribute_entry_ranges(a, nt, nn, nu, ni);  // 64-bit safe
      if (!ranges.empty()) {
        out.add(what + ": " + ranges);
        continue;
      }
      const bool has_n = a.normal_first != fmt::kNoAttribute, has_uv = a.uv_first != fmt::kNoAttribute;
      if (a.triangle_count && !has_n && !has_uv) out.add(what + ": triangles but neither normals nor uvs");
      for (uint64_t t = 0; t < a.triangle_count; ++t)
        for (uint32_t i : tri[a.triangle_first + t]) bad_idx += i >= a.vertex_count;
      for (uint32_t i = 0; has_n && i < a.vertex_count; ++i) {
        const auto& n = nrm[a.normal_first + i];
        const double l2 = double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2];
        bad_n += !(l2 == 0 || std::abs(l2 - 1) < 1e-4);  // unit, or (0,0,0) = none given; NaN fails
      }
      for (uint32_t i = 0; has_uv && i < a.vertex_count; ++i)
        bad_uv += !(std::isfinite(uv[a.uv_first + i][0]) && std::isfinite(uv[a.uv_first + i][1]));
      if (a.tri_id_first != fmt::kNoAttribute) {
        std::vector<uint32_t> p(ids + a.tri_id_first, ids + a.tri_id_first + a.triangle_count);
        for (size_t t = 1; t < p.size(); ++t)
          if (p[t] <= p[t - 1]) {
            out.add(what + ": triangle ids not strictly ascending at " + str(t));
            break;
          }
        s.tri_hash[k] = prim_set_hash(p);
      }
    }
    if (bad_idx) out.add(label + ": " + str(bad_idx) + " vertex indices out of range");
    if (bad_n) out.add(label + ": " + str(bad_n) + " normals neither unit length nor (0,0,0)");
    if (bad_uv) out.add(label + ": " + str(bad_uv) + " non-finite texture coordinates");
    s.ok = true;
  } catch (const Error& err) {
    out.add(err.what());
  }
}

void AttributeChecker::finish(const std::vector<fmt::MeshInfo>& meshes, uint64_t header_flags, Problems& out) const {
  uint64_t flags = 0;
  for (const auto& [key, s] : attrs_) {
    auto g = geometry_.find(key);
    if (g == geometry_.end()) {
      out.add(s.label + ": no geometry chunk of that id was read");
      continue;
    }
    if (!s.ok) continue;
    if (s.entries.size() != g->second.size()) {
      out.add(s.label + ": " + str(s.entries.size()) + " entries, its geometry chunk has " + str(g->second.size()));
      continue;
    }
    const bool piece = key.first == uint32_t(fmt::ChunkKind::kBatchingPoint);
    for (size_t k = 0; k < s.entries.size(); ++k) {
      const fmt::AttributeEntry& a = s.entries[k];
      const GeometryEntry& ge = g->second[k];
      const std::string what = s.label + ": entry " + str(k);
      if (a.id != ge.id || a.mesh != ge.mesh)
        out.add(what + ": id " + str(a.id) + " mesh " + str(a.mesh) + ", the geometry entry's are " + str(ge.id) + " and " +
                str(ge.mesh));
      if (a.reserved) out.add(what + ": reserved field not 0");
      const bool has_n = a.normal_first != fmt::kNoAttribute, has_uv = a.uv_first != fmt::kNoAttribute;
      flags |= (has_n ? fmt::kFlagNormals : 0) | (has_uv ? fmt::kFlagUvs : 0);
      if ((has_n || has_uv) && a.triangle_count != ge.triangles)
        out.add(what + ": " + str(a.triangle_count) + " triangles, the geometry entry has " + str(ge.triangles));
      if (ge.mesh < meshes.size()) {
        const uint32_t mf = meshes[ge.mesh].flags;
        if (bool(mf & fmt::kMeshNormals) != has_n || bool(mf & fmt::kMeshUvs) != has_uv)
          out.add(what + ": attributes disagree with the mesh table's flags for mesh " + str(ge.mesh));
      }
      if (piece && (has_n || has_uv) && (a.tri_id_first == fmt::kNoAttribute || s.tri_hash[k] != ge.prim_hash))
        out.add(what + ": its triangle ids are not the piece's triangles");
      if (!piece && a.tri_id_first != fmt::kNoAttribute) out.add(what + ": a whole mesh with triangle ids");
    }
  }
  for (const auto& [key, entries] : geometry_) {
    bool wants = false;
    for (const GeometryEntry& ge : entries)
      wants |= ge.mesh < meshes.size() && (meshes[ge.mesh].flags & (fmt::kMeshNormals | fmt::kMeshUvs));
    if (wants && !attrs_.count(key))
      out.add(std::string(key.first == uint32_t(fmt::ChunkKind::kMeshSegment) ? "mesh segment " : "batching point ") +
              str(key.second) + ": holds meshes with attributes but has no attribute chunk");
  }
  if ((header_flags & (fmt::kFlagNormals | fmt::kFlagUvs)) != flags)
    out.add("header: attribute flags " + str(header_flags & 3) + ", the attribute chunks hold " + str(flags));
}

}  // namespace rtp::inspect_detail
