// Hit -> shading attributes: (instance -> mesh) from the instance table, (mesh, prim) -> attribute
// entry and its triangle, barycentric interpolation, inverse-transpose to world space (L^-1 from the
// instance's record in the batching point the table names, SPEC §2.5). Every attribute chunk is checked
// (decode_attributes, check_attribute_geometry: SPEC §4.4) once, when it is loaded, before a lookup
// trusts an index or an id in it.
#include "reader/attribute_lookup.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
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

std::string dec(uint64_t v) { return std::to_string(v); }

// ---- The checks of an attribute chunk (SPEC §4.4) ----

uint64_t splitmix(uint64_t x) {  // splitmix64 finalizer
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

std::string float_list(const float* v, int n) {
  std::string out = "(";
  for (int a = 0; a < n; ++a) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%s%g", a ? ", " : "", double(v[a]));
    out += buf;
  }
  return out + ")";
}

std::string first_field(const char* name, uint32_t v) {
  return std::string(name) + " " + (v == fmt::kNoAttribute ? std::string("0xFFFFFFFF") : dec(v));
}

// The rules of one entry's own fields: "" or what is wrong.
std::string entry_fields(const fmt::AttributeEntry& a, bool piece) {
  if (a.reserved) return "reserved " + dec(a.reserved) + ", not 0";
  if (!piece && a.tri_id_first != fmt::kNoAttribute)
    return first_field("tri_id_first", a.tri_id_first) +
           " in a mesh segment's chunk (a whole mesh has no triangle ids: 0xFFFFFFFF)";
  const bool stores = a.normal_first != fmt::kNoAttribute || a.uv_first != fmt::kNoAttribute;
  if (a.triangle_count == 0) {
    if (a.vertex_count || a.triangle_first || stores || a.tri_id_first != fmt::kNoAttribute)
      return "triangle_count 0 (an entry that stores nothing) with vertex_count " + dec(a.vertex_count) + ", triangle_first " +
             dec(a.triangle_first) + ", " + first_field("normal_first", a.normal_first) + ", " +
             first_field("uv_first", a.uv_first) + ", " + first_field("tri_id_first", a.tri_id_first) +
             " (needs 0, 0 and 0xFFFFFFFF)";
    return {};
  }
  if (!stores) return "triangle_count " + dec(a.triangle_count) + " but neither normals nor uvs";
  if (piece && a.tri_id_first == fmt::kNoAttribute)
    return "tri_id_first 0xFFFFFFFF: a piece's entry needs triangle ids (its triangles in the scene mesh)";
  return {};
}

// Entry k's vertex indices < its vertex_count (its triangle range already inside the section).
void check_vertex_indices(const AttributeSections& s, uint64_t k, const std::string& what) {
  const fmt::AttributeEntry& a = s.entries[k];
  for (uint64_t t = 0; t < a.triangle_count; ++t)
    for (uint32_t vi : s.tris[a.triangle_first + t])
      if (vi >= a.vertex_count)
        fail_invalid(what + ": vertex indices out of range: triangle " + dec(t) + " (element " + dec(a.triangle_first + t) +
                     " of section 18) has vertex index " + dec(vi) + ", vertex_count " + dec(a.vertex_count));
}

// Entry k's triangle ids strictly ascending (its range already inside the section); their summary.
AttributeTriIds tri_id_set(const AttributeSections& s, uint64_t k, const std::string& what) {
  const fmt::AttributeEntry& a = s.entries[k];
  AttributeTriIds out;
  if (a.tri_id_first == fmt::kNoAttribute) return out;
  const uint32_t* ids = s.tri_ids + a.tri_id_first;
  PrimSetHash h;
  for (uint64_t t = 0; t < a.triangle_count; ++t) {
    if (t && ids[t] <= ids[t - 1])
      fail_invalid(what + ": triangle ids not strictly ascending at " + dec(t) + " (" + dec(ids[t]) + " after " +
                   dec(ids[t - 1]) + ")");
    h.add(ids[t]);
  }
  out.hash = h.value();
  out.count = a.triangle_count;
  out.last = a.triangle_count ? ids[a.triangle_count - 1] : 0;
  return out;
}

// Section-wide: every normal unit length or (0,0,0) (NaN fails), every uv finite.
void check_vertex_values(const AttributeSections& s, const std::string& label) {
  for (uint64_t i = 0; i < s.n_normals; ++i) {
    const auto& n = s.normals[i];
    const double l2 = double(n[0]) * n[0] + double(n[1]) * n[1] + double(n[2]) * n[2];
    if (!(l2 == 0 || std::abs(l2 - 1) < 1e-4))
      fail_invalid(label + ": normals neither unit length nor (0,0,0): normal " + dec(i) + " = " + float_list(n.data(), 3));
  }
  for (uint64_t i = 0; i < s.n_uvs; ++i)
    if (!std::isfinite(s.uvs[i][0]) || !std::isfinite(s.uvs[i][1]))
      fail_invalid(label + ": non-finite texture coordinates: uv " + dec(i) + " = " + float_list(s.uvs[i].data(), 2));
}

}  // namespace

void PrimSetHash::add(uint32_t prim) {
  sum_ += splitmix(prim);
  ++count_;
}
uint64_t PrimSetHash::value() const { return splitmix(count_) + sum_; }

AttributeSections decode_attributes(const ChunkView& v, uint32_t kind) {
  const std::string& label = v.label();
  const bool piece = kind == uint32_t(fmt::ChunkKind::kPointAttributes);
  AttributeSections s;
  s.entries = v.get<fmt::AttributeEntry>(fmt::SectionType::kAttrEntries, s.n_entries);
  s.tris = v.get<Tri>(fmt::SectionType::kAttrTriangles, s.n_tris);
  s.normals = v.get<std::array<float, 3>>(fmt::SectionType::kAttrNormals, s.n_normals, false);
  s.uvs = v.get<std::array<float, 2>>(fmt::SectionType::kAttrUvs, s.n_uvs, false);
  s.tri_ids = v.get<uint32_t>(fmt::SectionType::kAttrTriIds, s.n_tri_ids, false);
  s.id_sets.resize(s.n_entries);
  // SPEC §4.4: each section holds the entries' elements in entry order, without gaps (so no two entries share
  // any, and Σ of the counts is the section's size: all the per-entry loops are O(bytes of the chunk)).
  uint64_t at_tri = 0, at_normal = 0, at_uv = 0, at_id = 0;
  for (uint64_t k = 0; k < s.n_entries; ++k) {
    const fmt::AttributeEntry& a = s.entries[k];
    const std::string what = label + ": entry " + dec(k) + " (id " + dec(a.id) + ")";
    std::string bad = entry_fields(a, piece);
    if (bad.empty()) bad = attribute_entry_ranges(a, s.n_tris, s.n_normals, s.n_uvs, s.n_tri_ids);  // 64-bit safe
    if (!bad.empty()) fail_invalid(what + ": " + bad);
    if (a.triangle_count) {
      auto in_order = [&](const char* field, uint64_t first, uint64_t& at, uint64_t count) {
        if (first != at)
          fail_invalid(what + ": " + field + " " + dec(first) + ", expected " + dec(at) +
                       " (each section holds the entries' elements in entry order, without gaps)");
        at += count;
      };
      in_order("triangle_first", a.triangle_first, at_tri, a.triangle_count);
      if (a.normal_first != fmt::kNoAttribute) in_order("normal_first", a.normal_first, at_normal, a.vertex_count);
      if (a.uv_first != fmt::kNoAttribute) in_order("uv_first", a.uv_first, at_uv, a.vertex_count);
      if (a.tri_id_first != fmt::kNoAttribute) in_order("tri_id_first", a.tri_id_first, at_id, a.triangle_count);
    }
    check_vertex_indices(s, k, what);
    s.id_sets[k] = tri_id_set(s, k, what);
  }
  if (at_tri != s.n_tris || at_normal != s.n_normals || at_uv != s.n_uvs || at_id != s.n_tri_ids)
    fail_invalid(label + ": the entries use " + dec(at_tri) + " triangles, " + dec(at_normal) + " normals, " + dec(at_uv) +
                 " uvs, " + dec(at_id) + " triangle ids of sections holding " + dec(s.n_tris) + ", " + dec(s.n_normals) + ", " +
                 dec(s.n_uvs) + ", " + dec(s.n_tri_ids));
  check_vertex_values(s, label);
  return s;
}

namespace {

// Entry `a` (index k) against its MeshEntry `g` and the mesh table: "" or what is wrong.
std::string entry_geometry(const fmt::AttributeEntry& a, const AttributeTriIds& ids, const AttributeGeometry& g,
                           const fmt::MeshInfo* meshes, uint64_t n_meshes, bool piece, uint64_t chunk_id) {
  if (a.mesh >= n_meshes) return "mesh " + dec(a.mesh) + " out of range (" + dec(n_meshes) + " meshes)";
  if (a.id != g.id || a.mesh != g.mesh)
    return "id " + dec(a.id) + " mesh " + dec(a.mesh) + ", the geometry entry's are " + dec(g.id) + " and " + dec(g.mesh);
  const fmt::MeshInfo& mi = meshes[a.mesh];
  const uint32_t want_segment = piece ? fmt::kNoAttribute : uint32_t(chunk_id);
  if (mi.segment != want_segment || (!piece && chunk_id >= fmt::kNoAttribute))
    return "mesh " + dec(a.mesh) + ": the mesh table stores it " +
           (mi.segment == fmt::kNoAttribute ? std::string("as pieces") : "in mesh segment " + dec(mi.segment)) + ", not " +
           (piece ? std::string("as pieces") : "in mesh segment " + dec(chunk_id));
  if (a.triangle_count && a.triangle_count != g.triangles)
    return "triangle_count " + dec(a.triangle_count) + ", the geometry entry has " + dec(g.triangles) + " triangles";
  if (ids.count && ids.last >= mi.triangles)
    return "triangle id " + dec(ids.last) + " out of range (mesh " + dec(a.mesh) + " has " + dec(mi.triangles) + " triangles)";
  if (piece && a.triangle_count && ids.hash != g.prim_hash)
    return "its triangle ids are not the piece's triangles (the prims of its leaves)";
  return {};
}

}  // namespace

void check_attribute_geometry(const fmt::AttributeEntry* entries, const AttributeTriIds* id_sets, uint64_t count,
                              const std::vector<AttributeGeometry>& geometry, const fmt::MeshInfo* meshes, uint64_t n_meshes,
                              uint32_t kind, uint64_t chunk_id, const std::string& label) {
  const bool piece = kind == uint32_t(fmt::ChunkKind::kPointAttributes);
  if (count != geometry.size())
    fail_invalid(label + ": " + dec(count) + " entries, its geometry chunk has " + dec(geometry.size()) + " mesh entries");
  for (uint64_t k = 0; k < count; ++k) {
    const std::string bad = entry_geometry(entries[k], id_sets[k], geometry[k], meshes, n_meshes, piece, chunk_id);
    if (!bad.empty()) fail_invalid(label + ": entry " + dec(k) + " (id " + dec(entries[k].id) + "): " + bad);
  }
}

// ---- The lookup ----

namespace {

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
};

}  // namespace

// Keyed tables, sorted once loaded: their size follows the entries and ids stored in the file, never a
// declared mesh id or prim (a hostile id costs one element, not a table up to it).
struct AttributeLookup::Impl {
  using Key = std::pair<uint32_t, uint32_t>;  // (mesh, prim); whole meshes use prim 0
  std::vector<fmt::InstanceRef> instances;
  std::vector<fmt::MeshInfo> meshes;
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
  void add_chunk(const PackageReader& r, size_t toc_index);
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

// The chunk (kind, id) an attribute chunk belongs to, read; throws when there is none.
AlignedBytes read_geometry(const PackageReader& r, fmt::ChunkKind kind, uint64_t id, const std::string& attr_label,
                           std::string& label) {
  const int64_t i = r.find(kind, id);
  if (i < 0)
    fail_invalid(attr_label + ": its geometry chunk (" + chunk_kind_name(uint32_t(kind)) + " " + dec(id) + ") is missing");
  label = chunk_label(r.toc()[size_t(i)], size_t(i));
  return r.read(size_t(i));
}

// Per piece entry: PrimSetHash of the prims in its leaf blocks (a short block repeats its last lane, §2.3).
template <int B>
void piece_prim_hashes(const ChunkView& v, const fmt::MeshEntry* e, std::vector<AttributeGeometry>& geo) {
  uint64_t nb = 0;
  const fmt::LeafBlock<B>* blocks = v.get<fmt::LeafBlock<B>>(fmt::SectionType::kBlocks, nb);
  for (size_t k = 0; k < geo.size(); ++k) {
    if (!range_inside(e[k].block_first, e[k].block_count, nb))
      fail_invalid(v.label() + ": piece " + dec(e[k].id) + " (entry " + dec(k) + "): block_first " + dec(e[k].block_first) +
                   " + block_count " + dec(e[k].block_count) + " outside the " + dec(nb) + " blocks");
    PrimSetHash h;
    for (uint64_t b = e[k].block_first; b < uint64_t(e[k].block_first) + e[k].block_count; ++b)
      for (int l = 0; l < B && (l == 0 || blocks[b].prim[l] != blocks[b].prim[l - 1]); ++l) h.add(blocks[b].prim[l]);
    geo[k].prim_hash = h.value();
  }
}

// What the entries of attribute chunk (kind, id) must agree with, from its geometry chunk: MeshEntry ids
// and triangles; the mesh of a segment entry is its id, a piece's is the instance table's mesh of the
// instance whose record's slot names it (as rtpack-inspect --verify relates them).
std::vector<AttributeGeometry> geometry_of(const PackageReader& r, uint32_t kind, uint64_t id,
                                           const std::vector<fmt::InstanceRef>& instances, const std::string& attr_label) {
  const bool piece = kind == uint32_t(fmt::ChunkKind::kPointAttributes);
  const fmt::ChunkKind gk = piece ? fmt::ChunkKind::kBatchingPoint : fmt::ChunkKind::kMeshSegment;
  std::string label;
  const AlignedBytes b = read_geometry(r, gk, id, attr_label, label);
  ChunkView v(b.data(), b.size(), uint32_t(gk), label);
  uint64_t ne = 0;
  const fmt::MeshEntry* e = v.get<fmt::MeshEntry>(fmt::SectionType::kMeshEntries, ne);
  std::vector<AttributeGeometry> geo(ne);
  for (uint64_t k = 0; k < ne; ++k) geo[k] = {e[k].id, piece ? fmt::kNoAttribute : e[k].id, e[k].triangles, 0};
  if (!piece) return geo;
  uint64_t n_rec = 0, n_gid = 0, n_slots = 0;
  const fmt::InstanceRecord* rec = v.get<fmt::InstanceRecord>(fmt::SectionType::kInstances, n_rec);
  const uint32_t* global = v.get<uint32_t>(fmt::SectionType::kGlobalIds, n_gid);
  const uint32_t* slots = v.get<uint32_t>(fmt::SectionType::kMeshSlots, n_slots);
  for (uint64_t k = 0; k < n_rec && k < n_gid; ++k) {
    const uint32_t slot = rec[k].mesh;
    if (slot >= n_slots || !(slots[slot] & fmt::kPieceBit)) continue;
    const uint32_t entry = slots[slot] & ~fmt::kPieceBit;
    if (entry < ne && global[k] < instances.size()) geo[entry].mesh = instances[global[k]].mesh;
  }
  switch (r.header().leaf_width) {
    case 4: piece_prim_hashes<4>(v, e, geo); break;
    case 8: piece_prim_hashes<8>(v, e, geo); break;
    case 16: piece_prim_hashes<16>(v, e, geo); break;
    default: fail_invalid("header: unsupported leaf width " + dec(r.header().leaf_width));
  }
  return geo;
}

// A resident table's one section, copied.
template <class T>
std::vector<T> resident_section(const PackageReader& r, fmt::ChunkKind kind, fmt::SectionType type, const char* what) {
  const int64_t i = r.find(kind, 0);
  if (i < 0) fail_invalid(std::string("the package has no ") + what);
  const AlignedBytes b = r.read(size_t(i));
  ChunkView v(b.data(), b.size(), uint32_t(kind), chunk_label(r.toc()[size_t(i)], size_t(i)));
  return v.copy<T>(type);
}

}  // namespace

// Attribute chunk toc()[i]: checked on its own and against its geometry chunk, then indexed.
void AttributeLookup::Impl::add_chunk(const PackageReader& r, size_t i) {
  const fmt::TocEntry& te = r.toc()[i];
  const std::string label = chunk_label(te, i);
  Chunk c;
  c.bytes = r.read(i);
  ChunkView v(c.bytes.data(), c.bytes.size(), te.kind, label);
  const AttributeSections s = decode_attributes(v, te.kind);
  check_attribute_geometry(s.entries, s.id_sets.data(), s.n_entries, geometry_of(r, te.kind, te.id, instances, label),
                           meshes.data(), meshes.size(), te.kind, te.id, label);
  c.entries = s.entries;
  c.tris = s.tris;
  c.normals = s.normals;
  c.uvs = s.uvs;
  const uint32_t ci = uint32_t(chunks.size());
  for (uint32_t k = 0; k < s.n_entries; ++k) {
    const fmt::AttributeEntry& e = s.entries[k];
    const bool has_n = e.normal_first != fmt::kNoAttribute, has_uv = e.uv_first != fmt::kNoAttribute;
    if (!has_n && !has_uv) continue;
    normals |= has_n;
    uvs |= has_uv;
    if (e.tri_id_first == fmt::kNoAttribute) {
      whole.push_back({{e.mesh, 0}, {ci, k, 0}});
    } else {
      for (uint32_t t = 0; t < e.triangle_count; ++t) per_tri.push_back({{e.mesh, s.tri_ids[e.tri_id_first + t]}, {ci, k, t}});
    }
  }
  chunks.push_back(std::move(c));
}

AttributeLookup::~AttributeLookup() = default;
bool AttributeLookup::has_normals() const { return impl_->normals; }
bool AttributeLookup::has_uvs() const { return impl_->uvs; }

AttributeLookup::AttributeLookup(const PackageReader& r) : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.instances =
      resident_section<fmt::InstanceRef>(r, fmt::ChunkKind::kInstances, fmt::SectionType::kInstanceRefs, "instance table");
  bool any = false;
  for (size_t i = 0; i < r.toc().size(); ++i) {
    const uint32_t kind = r.toc()[i].kind;
    if (kind != uint32_t(fmt::ChunkKind::kSegmentAttributes) && kind != uint32_t(fmt::ChunkKind::kPointAttributes)) continue;
    if (!any) m.meshes = resident_section<fmt::MeshInfo>(r, fmt::ChunkKind::kMeshes, fmt::SectionType::kMeshTable, "mesh table");
    any = true;
    m.add_chunk(r, i);
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
