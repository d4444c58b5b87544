// Attribute chunk checks (SPEC §4.4): one chunk at a time, then against its geometry chunk, both by the
// attribute lookup's own checks (reader/attribute_lookup.h); then the mesh table's and header's flags.
#include "inspect/inspect_attributes.h"

#include "core/error.h"
#include "layout/chunk_io.h"
#include "inspect/inspect.h"

namespace rtp::inspect_detail {
namespace {

uint32_t geometry_kind(uint32_t attr_kind) {
  return attr_kind == uint32_t(fmt::ChunkKind::kSegmentAttributes) ? uint32_t(fmt::ChunkKind::kMeshSegment)
                                                                   : uint32_t(fmt::ChunkKind::kBatchingPoint);
}

}  // namespace

uint64_t prim_set_hash(const std::vector<uint32_t>& prims) {
  PrimSetHash h;
  for (uint32_t p : prims) h.add(p);
  return h.value();
}

void AttributeChecker::geometry(uint32_t kind, uint64_t id, std::vector<GeometryEntry> entries) {
  geometry_[{kind, id}] = std::move(entries);
}

// The chunk on its own: the attribute lookup's check (decode_attributes); what the cross-checks need kept.
void AttributeChecker::chunk(uint32_t kind, uint64_t id, const std::string& label, const AlignedBytes& bytes, Problems& out) {
  Seen& s = attrs_[{geometry_kind(kind), id}];
  s.label = label;
  s.kind = kind;
  try {
    ChunkView v(bytes.data(), bytes.size(), kind, label);
    AttributeSections a = decode_attributes(v, kind);
    s.entries.assign(a.entries, a.entries + a.n_entries);
    s.id_sets = std::move(a.id_sets);
    s.ok = true;
  } catch (const Error& err) {
    out.add(err.what());
  }
}

uint64_t AttributeChecker::check_flags(const Seen& s, const std::vector<GeometryEntry>& geometry,
                                       const std::vector<fmt::MeshInfo>& meshes, Problems& out) {
  uint64_t flags = 0;
  for (size_t k = 0; k < s.entries.size(); ++k) {
    const fmt::AttributeEntry& a = s.entries[k];
    const bool has_n = a.normal_first != fmt::kNoAttribute, has_uv = a.uv_first != fmt::kNoAttribute;
    flags |= (has_n ? fmt::kFlagNormals : 0) | (has_uv ? fmt::kFlagUvs : 0);
    const uint32_t mesh = k < geometry.size() ? geometry[k].mesh : a.mesh;
    if (mesh >= meshes.size()) continue;
    const uint32_t mf = meshes[mesh].flags;
    if (bool(mf & fmt::kMeshNormals) != has_n || bool(mf & fmt::kMeshUvs) != has_uv)
      out.add(s.label + ": entry " + str(k) + ": attributes disagree with the mesh table's flags for mesh " + str(mesh));
  }
  return flags;
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
    try {  // the attribute lookup's check against the geometry chunk and the mesh table
      check_attribute_geometry(s.entries.data(), s.id_sets.data(), s.entries.size(), g->second, meshes.data(), meshes.size(),
                               s.kind, key.second, s.label);
    } catch (const Error& err) {
      out.add(err.what());
    }
    flags |= check_flags(s, g->second, meshes, out);
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
