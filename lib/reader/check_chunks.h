#pragma once
// The package trust boundary (formats/SPEC.md §4, "Structural checks at decode"): every chunk that a
// tool or tracer decodes passes these checks before any kernel, table lookup or allocation trusts a
// value in it. Each failure throws Error(kInputInvalid) naming the chunk and the field, e.g.
//   "mesh segment 3 (chunk #12 ...): mesh 5 (entry 0): node 17 lane 2: child 9 is not after its parent".
// Every check is O(bytes of the chunk) (plus O(1) per cross-chunk reference), so it is always on.
// The semantic invariants that cost more (coverage, bounds containment, CRCs of unread chunks) stay in
// rtpack-inspect --verify.
#include <cstdint>
#include <string>

#include "formats/bvh_layout.h"
#include "formats/chunk.h"
#include "formats/top_level.h"
#include "layout/chunk_io.h"

namespace rtp {

// [first, first + count) lies inside [0, size), without 64-bit wrap.
constexpr bool range_inside(uint64_t first, uint64_t count, uint64_t size) { return first <= size && count <= size - first; }

// "Unknown" for a cross-chunk count that the caller has not read (that reference is then not checked).
inline constexpr uint64_t kUnknownCount = ~uint64_t(0);

// Kind 2: every child an empty lane, a batching point < `points` or a node after its parent; every
// node but the root and every batching point referenced exactly once; filled lanes' boxes finite;
// every child node's parent and slot naming the node and lane that reference it, the root's parent none.
void check_top_level(const fmt::TopNode* nodes, uint64_t count, uint64_t points, const std::string& label);

// Kind 3: each descriptor's chunk_id = its index, its segment range inside section 10 and its bounds finite.
void check_point_descs(const fmt::BatchingPointDesc* descs, uint64_t count, uint64_t segment_refs, const std::string& label);

// Kind 4 (SPEC §2.5): every entry's mesh < `meshes`, its point < `points` or none (then local 0). Whether
// the point holds a record at `local` is its chunk's to say (rtpack-inspect --verify, attribute lookup).
void check_instance_table(const fmt::InstanceRef* refs, uint64_t count, uint64_t meshes, uint64_t points,
                          const std::string& label);

// Kind 5 against kind 6: every mesh's source ranges inside the source map (so every triangle count is
// backed by 8 bytes of the file; kUnknownCount: the source map not read), segment < `segments` or none.
void check_mesh_table(const fmt::MeshInfo* meshes, uint64_t count, uint64_t source_prims, uint64_t source_tris, uint64_t segments,
                      const std::string& label);

// The resident tables a reader checks geometry chunks against (SPEC §4.6): the instance table (kind 4,
// passed check_instance_table) and the mesh table (kind 5, passed check_mesh_table). A null table was not
// read (or failed its own check): the rules that need it are then not checked (rtpack-inspect lists why).
struct SceneTables {
  const fmt::InstanceRef* instances = nullptr;
  uint64_t n_instances = kUnknownCount;
  const fmt::MeshInfo* meshes = nullptr;
  uint64_t n_meshes = kUnknownCount;
};

// Kind 16 section 5 (SPEC §2.4): T finite and inside the float range (the world is float), L^-1 finite,
// either all zeros (singular L) or of non-zero determinant, flags = the sign of that determinant, reserved 0.
void check_instance_records(const fmt::InstanceRecord* records, uint64_t count, const std::string& label);

// The sections of a geometry chunk (kind 17 mesh segment; kind 16 uses these for its pieces).
template <int W, int B>
struct GeometrySections {
  const fmt::MeshEntry* entries = nullptr;
  const fmt::WideNode<W>* nodes = nullptr;
  const fmt::LeafBlock<B>* blocks = nullptr;
  uint64_t n_entries = 0, n_nodes = 0, n_blocks = 0;
};

// Kind 16: the pieces plus the instance level.
template <int W, int B>
struct PointSections : GeometrySections<W, B> {
  const fmt::MeshEntry* instance_bvh = nullptr;  // exactly one
  const fmt::WideNode<W>* instance_nodes = nullptr;
  const uint32_t* instance_ids = nullptr;
  const fmt::InstanceRecord* records = nullptr;
  const uint32_t* global_ids = nullptr;
  const uint32_t* slots = nullptr;
  uint64_t n_instance_nodes = 0, n_instance_ids = 0, n_records = 0, n_slots = 0;
};

// Parses and checks a mesh segment: per entry its node and block ranges inside the sections (and the
// entries' node ranges not overlapping), its root, every child in range and after its parent, every
// node referenced at most once, every leaf's blocks inside the entry's, octant orders < W, filled
// lanes' boxes finite, every leaf prim < the entry's triangles.
// With the mesh table: every entry's mesh in range, held by this segment (`segment`) and of the table's
// triangle count, and no mesh twice.
template <int W, int B>
GeometrySections<W, B> decode_segment(const ChunkView& v, const SceneTables& tables, uint64_t segment);

// Parses and checks a batching point: its pieces as decode_segment (prims unchecked: they index the
// scene mesh), the instance BVH (one entry whose sizes match its sections, the same node rules, leaves
// inside the instance ids), instance ids < records and none twice, one global id per record and each
// < the scene's instances, record meshes < slots, piece slots naming an entry, the records' transforms
// (check_instance_records). With both tables, per record: a piece slot for a mesh the mesh table stores as
// pieces, and every leaf prim of that piece < the mesh's triangles; otherwise the slot's mesh is the
// instance's and the mesh table places it in a segment; and the instance table places the record's
// instance in this point (`point`) at its index (a piece: its first piece, at or before this one).
template <int W, int B>
PointSections<W, B> decode_point(const ChunkView& v, const SceneTables& tables, uint64_t point);

// Kinds 18/19: one attribute entry's ranges inside sections of `tris` triangles, `normals` / `uvs`
// vertices and `tri_ids` ids (64-bit safe). Returns "" or what is wrong (the field named).
std::string attribute_entry_ranges(const fmt::AttributeEntry& e, uint64_t tris, uint64_t normals, uint64_t uvs, uint64_t tri_ids);

}  // namespace rtp
