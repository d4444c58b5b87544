// Structural checks at decode (formats/SPEC.md §4): every index in range, every range inside its array
// (64-bit safe), BVH links acyclic (a child index is greater than its parent's; checked in one pass over
// the nodes) and no node reached twice, boxes finite. One pass over each chunk's bytes, no allocation
// larger than the sections themselves.
#include "reader/check_chunks.h"

#include <cmath>
#include <vector>

#include "core/error.h"
#include "reader/check_references.h"

namespace rtp {
namespace {

std::string str(uint64_t v) { return std::to_string(v); }

bool finite_box(float lo, float hi) { return std::isfinite(lo) && std::isfinite(hi) && lo <= hi; }

// A wide BVH (mesh, piece or instance level): nodes [0, nn), `root` a ChildRef relative to them, leaves
// ranges inside [0, items). `seen` has >= nn zero bytes and is left zeroed. `what` prefixes messages.
template <int W, class What>
void check_wide_bvh(const fmt::WideNode<W>* nodes, uint64_t nn, uint32_t root, uint64_t items, std::vector<uint8_t>& seen,
                    const What& what, const char* item_name) {
  using fmt::ChildRef;
  auto leaf_ok = [&](uint32_t ref) { return range_inside(ChildRef::first_block(ref), ChildRef::block_count(ref), items); };
  auto leaf_msg = [&](uint32_t ref) {
    return item_name + std::string("s ") + str(ChildRef::first_block(ref)) + ".." +
           str(uint64_t(ChildRef::first_block(ref)) + ChildRef::block_count(ref) - 1) + " out of range (" + str(items) + ")";
  };
  if (ChildRef::is_leaf(root)) {
    if (!leaf_ok(root)) fail_invalid(what() + ": root leaf: " + leaf_msg(root));
  } else if (!ChildRef::is_empty(root)) {
    if (root >= nn) fail_invalid(what() + ": root node " + str(root) + " out of range (" + str(nn) + " nodes)");
    seen[root] = 1;
  }
  // The hot loop only tests; a message is built once something failed (the first failure is named).
  std::string msg;
  for (uint64_t i = 0; i < nn && msg.empty(); ++i) {
    const fmt::WideNode<W>& n = nodes[i];
    for (int l = 0; l < W && msg.empty(); ++l) {
      const uint32_t c = n.child[l];
      auto where = [&] { return what() + ": node " + str(i) + " lane " + str(uint64_t(l)); };
      for (int o = 0; o < 8 && msg.empty(); ++o)
        if (n.order[o][l] >= W)
          msg = where() + ": octant order " + str(uint64_t(o)) + " names lane " + str(n.order[o][l]) + " (width " + str(W) + ")";
      if (!msg.empty() || ChildRef::is_empty(c)) continue;
      for (int a = 0; a < 3 && msg.empty(); ++a)
        if (!finite_box(n.lo[a][l], n.hi[a][l])) msg = where() + ": box not finite or inverted on axis " + str(uint64_t(a));
      if (!msg.empty()) continue;
      if (ChildRef::is_leaf(c)) {
        if (!leaf_ok(c)) msg = where() + ": leaf " + leaf_msg(c);
      } else if (c >= nn) {
        msg = where() + ": child " + str(c) + " out of range (" + str(nn) + " nodes)";
      } else if (c <= i) {
        msg = where() + ": child " + str(c) + " is not after its parent";
      } else if (seen[c]++) {
        msg = where() + ": child " + str(c) + " is referenced a second time";
      }
    }
  }
  std::fill(seen.begin(), seen.begin() + std::ptrdiff_t(nn), uint8_t(0));
  if (!msg.empty()) fail_invalid(msg);
}

// Every lane's prim of `count` leaf blocks < `triangles` (kUnknownCount: unchecked).
template <int B, class What>
void check_leaf_prims(const fmt::LeafBlock<B>* blocks, uint64_t count, uint64_t triangles, const What& what) {
  if (triangles == kUnknownCount) return;
  for (uint64_t b = 0; b < count; ++b)
    for (int l = 0; l < B; ++l)
      if (blocks[b].prim[l] >= triangles)
        fail_invalid(what() + ": block " + str(b) + " lane " + str(uint64_t(l)) + ": prim " + str(blocks[b].prim[l]) +
                     " out of range (" + str(triangles) + " triangles)");
}

// The entries' BVHs of a geometry chunk. `prims`: also every leaf prim < the entry's triangles.
template <int W, int B>
void check_entries(const GeometrySections<W, B>& g, const std::string& label, const char* entry_name, bool prims) {
  uint64_t nodes_total = 0, blocks_total = 0;
  std::vector<uint8_t> seen;
  for (uint64_t k = 0; k < g.n_entries; ++k) {
    const fmt::MeshEntry& e = g.entries[k];
    auto what = [&] { return label + ": " + entry_name + " " + str(e.id) + " (entry " + str(k) + ")"; };
    if (!range_inside(e.node_first, e.node_count, g.n_nodes))
      fail_invalid(what() + ": node_first " + str(e.node_first) + " + node_count " + str(e.node_count) + " outside the " +
                   str(g.n_nodes) + " nodes");
    if (!range_inside(e.block_first, e.block_count, g.n_blocks))
      fail_invalid(what() + ": block_first " + str(e.block_first) + " + block_count " + str(e.block_count) + " outside the " +
                   str(g.n_blocks) + " blocks");
    // SPEC §2.2: the entries' node and block ranges follow each other in entry order, without gaps (a range
    // moved onto another entry's blocks traced triangles outside their leaf boxes: hits lost, exit 0).
    if (e.node_first != nodes_total || e.block_first != blocks_total)
      fail_invalid(what() + ": node_first " + str(e.node_first) + ", block_first " + str(e.block_first) + ", expected " +
                   str(nodes_total) + " and " + str(blocks_total) + " (the entries' ranges follow each other in entry order)");
    nodes_total += e.node_count;
    blocks_total += e.block_count;
    if (seen.size() < e.node_count) seen.assign(e.node_count, 0);
    check_wide_bvh<W>(g.nodes + e.node_first, e.node_count, e.root, e.block_count, seen, what, "block");
    if (prims) check_leaf_prims(g.blocks + e.block_first, e.block_count, e.triangles, what);
  }
  if (nodes_total != g.n_nodes || blocks_total != g.n_blocks)
    fail_invalid(label + ": the entries hold " + str(nodes_total) + " nodes and " + str(blocks_total) +
                 " blocks of sections of " + str(g.n_nodes) + " and " + str(g.n_blocks));
}

template <int W, int B>
void get_geometry(const ChunkView& v, GeometrySections<W, B>& g) {
  g.entries = v.get<fmt::MeshEntry>(fmt::SectionType::kMeshEntries, g.n_entries);
  g.nodes = v.get<fmt::WideNode<W>>(fmt::SectionType::kNodes, g.n_nodes);
  g.blocks = v.get<fmt::LeafBlock<B>>(fmt::SectionType::kBlocks, g.n_blocks);
}

}  // namespace

void check_top_level(const fmt::TopNode* nodes, uint64_t count, uint64_t points, const std::string& label) {
  using fmt::TopNode;
  if (count == 0) {
    if (points) fail_invalid(label + ": no nodes but " + str(points) + " batching points");
    return;
  }
  std::vector<uint8_t> node_refs(count, 0), point_refs(points == kUnknownCount ? 0 : points, 0);
  for (uint64_t n = 0; n < count; ++n)
    for (int l = 0; l < 4; ++l) {
      const uint32_t c = nodes[n].child[l];
      if (c == TopNode::kEmpty) continue;
      const std::string where = label + ": node " + str(n) + " lane " + str(uint64_t(l));  // top level: small
      for (int a = 0; a < 3; ++a)
        if (!finite_box(nodes[n].lo[a][l], nodes[n].hi[a][l]))
          fail_invalid(where + ": box not finite or inverted on axis " + str(uint64_t(a)));
      if (c & TopNode::kLeafBit) {
        const uint32_t p = c & ~TopNode::kLeafBit;
        if (points == kUnknownCount) continue;
        if (p >= points) fail_invalid(where + ": batching point " + str(p) + " out of range (" + str(points) + ")");
        if (point_refs[p]++) fail_invalid(where + ": batching point " + str(p) + " is a leaf a second time");
        continue;
      }
      if (c >= count) fail_invalid(where + ": child " + str(c) + " out of range (" + str(count) + " nodes)");
      if (c <= n) fail_invalid(where + ": child " + str(c) + " is not after its parent");
      if (node_refs[c]++) fail_invalid(where + ": child " + str(c) + " is referenced a second time");
      // The out-of-core tracer resumes a paused ray by climbing parent pointers (Molenaar 2019 §4.1).
      if (nodes[c].parent != n || nodes[c].slot != uint32_t(l))
        fail_invalid(where + ": child " + str(c) + " names parent " + str(nodes[c].parent) + " lane " + str(nodes[c].slot));
    }
  if (nodes[0].parent != TopNode::kEmpty) fail_invalid(label + ": root node 0 names parent " + str(nodes[0].parent));
  for (uint64_t n = 1; n < count; ++n)
    if (!node_refs[n]) fail_invalid(label + ": node " + str(n) + " is no node's child");
  for (uint64_t p = 0; p < point_refs.size(); ++p)
    if (!point_refs[p]) fail_invalid(label + ": batching point " + str(p) + " is in no leaf");
}

void check_point_descs(const fmt::BatchingPointDesc* descs, uint64_t count, uint64_t segment_refs, const std::string& label) {
  for (uint64_t p = 0; p < count; ++p) {
    const fmt::BatchingPointDesc& d = descs[p];
    auto what = [&] { return label + ": batching point " + str(p); };
    if (d.chunk_id != p) fail_invalid(what() + ": chunk_id " + str(d.chunk_id) + " is not its index");
    if (!range_inside(d.segment_first, d.segment_count, segment_refs))
      fail_invalid(what() + ": segment_first " + str(d.segment_first) + " + segment_count " + str(d.segment_count) +
                   " outside the " + str(segment_refs) + " segment references");
    for (int a = 0; a < 3; ++a)
      if (!finite_box(d.lo[a], d.hi[a])) fail_invalid(what() + ": bounds not finite or inverted on axis " + str(uint64_t(a)));
  }
}

void check_instance_table(const fmt::InstanceRef* refs, uint64_t count, uint64_t meshes, uint64_t points,
                          const std::string& label) {
  for (uint64_t i = 0; i < count; ++i) {
    const fmt::InstanceRef& r = refs[i];
    if (r.mesh >= meshes)
      fail_invalid(label + ": instance " + str(i) + ": mesh " + str(r.mesh) + " out of range (" + str(meshes) + " meshes)");
    if (r.point == fmt::InstanceRef::kNoPoint) {
      if (r.local != 0) fail_invalid(label + ": instance " + str(i) + ": in no batching point but local " + str(r.local));
    } else if (r.point >= points) {
      fail_invalid(label + ": instance " + str(i) + ": batching point " + str(r.point) + " out of range (" + str(points) +
                   " points)");
    }
  }
}

void check_mesh_table(const fmt::MeshInfo* meshes, uint64_t count, uint64_t source_prims, uint64_t source_tris, uint64_t segments,
                      const std::string& label) {
  for (uint64_t m = 0; m < count; ++m) {
    const fmt::MeshInfo& mi = meshes[m];
    auto what = [&] { return label + ": mesh " + str(m); };
    if (source_prims != kUnknownCount && !range_inside(mi.source_prim_first, mi.source_prim_count, source_prims))
      fail_invalid(what() + ": source_prim_first " + str(mi.source_prim_first) + " + source_prim_count " +
                   str(mi.source_prim_count) + " outside the source map's " + str(source_prims) + " primitives");
    if (source_tris != kUnknownCount && !range_inside(mi.source_tri_first, mi.triangles, source_tris))
      fail_invalid(what() + ": source_tri_first " + str(mi.source_tri_first) + " + triangles " + str(mi.triangles) +
                   " outside the source map's " + str(source_tris) + " triangles");
    if (mi.segment != 0xFFFFFFFFu && segments != kUnknownCount && mi.segment >= segments)
      fail_invalid(what() + ": segment " + str(mi.segment) + " out of range (" + str(segments) + " mesh segments)");
  }
}

template <int W, int B>
GeometrySections<W, B> decode_segment(const ChunkView& v, const SceneTables& tables, uint64_t segment) {
  GeometrySections<W, B> g;
  get_geometry(v, g);
  check_entries(g, v.label(), "mesh", true);
  check_segment_meshes(g.entries, g.n_entries, segment, tables, v.label());
  return g;
}

template <int W, int B>
PointSections<W, B> decode_point(const ChunkView& v, const SceneTables& tables, uint64_t point) {
  using fmt::SectionType;
  const std::string& L = v.label();
  PointSections<W, B> p;
  get_geometry<W, B>(v, p);
  uint64_t n_te = 0, n_gid = 0;
  p.instance_bvh = v.get<fmt::MeshEntry>(SectionType::kInstanceBvh, n_te);
  p.instance_nodes = v.get<fmt::WideNode<W>>(SectionType::kInstanceNodes, p.n_instance_nodes);
  p.instance_ids = v.get<uint32_t>(SectionType::kInstanceIds, p.n_instance_ids);
  p.records = v.get<fmt::InstanceRecord>(SectionType::kInstances, p.n_records);
  p.global_ids = v.get<uint32_t>(SectionType::kGlobalIds, n_gid);
  p.slots = v.get<uint32_t>(SectionType::kMeshSlots, p.n_slots);
  check_entries<W, B>(p, L, "piece", false);
  if (n_te != 1) fail_invalid(L + ": instance BVH section has " + str(n_te) + " entries, expected 1");
  const fmt::MeshEntry& te = p.instance_bvh[0];
  if (te.node_first != 0 || te.node_count != p.n_instance_nodes || te.block_first != 0 || te.block_count != p.n_instance_ids)
    fail_invalid(L + ": instance BVH entry (nodes " + str(te.node_first) + "+" + str(te.node_count) + ", ids " +
                 str(te.block_first) + "+" + str(te.block_count) + ") disagrees with its sections (" + str(p.n_instance_nodes) +
                 " nodes, " + str(p.n_instance_ids) + " ids)");
  std::vector<uint8_t> seen(p.n_instance_nodes, 0);
  check_wide_bvh<W>(
      p.instance_nodes, p.n_instance_nodes, te.root, p.n_instance_ids, seen, [&] { return L + ": instance BVH"; }, "instance id");
  std::vector<uint8_t> used(p.n_records, 0);
  for (uint64_t k = 0; k < p.n_instance_ids; ++k) {
    const uint32_t id = p.instance_ids[k];
    if (id >= p.n_records)
      fail_invalid(L + ": instance id " + str(k) + " = " + str(id) + " out of range (" + str(p.n_records) + " instances)");
    if (used[id]++)
      fail_invalid(L + ": instance id " + str(k) + " = " + str(id) + " is referenced a second time by the instance BVH");
  }
  if (n_gid != p.n_records) fail_invalid(L + ": " + str(n_gid) + " global ids for " + str(p.n_records) + " instances");
  for (uint64_t k = 0; k < p.n_records; ++k) {
    if (tables.n_instances != kUnknownCount && p.global_ids[k] >= tables.n_instances)
      fail_invalid(L + ": global id " + str(k) + " = " + str(p.global_ids[k]) + " out of range (" + str(tables.n_instances) +
                   " scene instances)");
    if (p.records[k].mesh >= p.n_slots)
      fail_invalid(L + ": instance " + str(k) + ": mesh slot " + str(p.records[k].mesh) + " out of range (" + str(p.n_slots) +
                   " slots)");
  }
  for (uint64_t s = 0; s < p.n_slots; ++s)
    if ((p.slots[s] & fmt::kPieceBit) && (p.slots[s] & ~fmt::kPieceBit) >= p.n_entries)
      fail_invalid(L + ": mesh slot " + str(s) + " names piece entry " + str(p.slots[s] & ~fmt::kPieceBit) + " out of range (" +
                   str(p.n_entries) + " entries)");
  // Each piece is traced once (SPEC §4.2): every piece entry named by exactly one mesh slot, every piece
  // slot by exactly one record (instanced meshes' slots are shared by their instances).
  std::vector<uint32_t> entry_slots(p.n_entries, 0), slot_records(p.n_slots, 0);
  for (uint64_t s = 0; s < p.n_slots; ++s)
    if (p.slots[s] & fmt::kPieceBit) ++entry_slots[p.slots[s] & ~fmt::kPieceBit];
  for (uint64_t k = 0; k < p.n_entries; ++k)
    if (entry_slots[k] != 1)
      fail_invalid(L + ": piece entry " + str(k) + " is named by " + str(entry_slots[k]) + " mesh slots, expected 1");
  for (uint64_t k = 0; k < p.n_records; ++k) ++slot_records[p.records[k].mesh];
  for (uint64_t s = 0; s < p.n_slots; ++s)
    if ((p.slots[s] & fmt::kPieceBit) && slot_records[s] != 1)
      fail_invalid(L + ": mesh slot " + str(s) + " (a piece) is used by " + str(slot_records[s]) + " instances, expected 1");
  check_instance_records(p.records, p.n_records, L);
  // A piece's leaves index its scene mesh's triangles (SPEC §4.2).
  const std::vector<uint64_t> bounds =
      piece_triangle_bounds({p.records, p.global_ids, p.slots, p.n_records, p.n_entries, point}, tables, L);
  for (uint64_t k = 0; k < p.n_entries; ++k)
    check_leaf_prims(p.blocks + p.entries[k].block_first, p.entries[k].block_count, bounds[k],
                     [&] { return L + ": piece " + str(p.entries[k].id) + " (entry " + str(k) + ")"; });
  return p;
}

std::string attribute_entry_ranges(const fmt::AttributeEntry& e, uint64_t tris, uint64_t normals, uint64_t uvs,
                                   uint64_t tri_ids) {
  auto outside = [](const char* first, uint64_t f, const char* count, uint64_t c, uint64_t n, const char* what) {
    return std::string(first) + " " + str(f) + " + " + count + " " + str(c) + " outside the section (" + str(n) + " " + what +
           ")";
  };
  if (!range_inside(e.triangle_first, e.triangle_count, tris))
    return outside("triangle_first", e.triangle_first, "triangle_count", e.triangle_count, tris, "triangles");
  if (e.normal_first != fmt::kNoAttribute && !range_inside(e.normal_first, e.vertex_count, normals))
    return outside("normal_first", e.normal_first, "vertex_count", e.vertex_count, normals, "normals");
  if (e.uv_first != fmt::kNoAttribute && !range_inside(e.uv_first, e.vertex_count, uvs))
    return outside("uv_first", e.uv_first, "vertex_count", e.vertex_count, uvs, "uvs");
  if (e.tri_id_first != fmt::kNoAttribute && !range_inside(e.tri_id_first, e.triangle_count, tri_ids))
    return outside("tri_id_first", e.tri_id_first, "triangle_count", e.triangle_count, tri_ids, "triangle ids");
  return {};
}

#define RTP_CHECK_WB(W, B)                                                                              \
  template GeometrySections<W, B> decode_segment<W, B>(const ChunkView&, const SceneTables&, uint64_t); \
  template PointSections<W, B> decode_point<W, B>(const ChunkView&, const SceneTables&, uint64_t);
RTP_CHECK_WB(4, 4)
RTP_CHECK_WB(8, 8)
RTP_CHECK_WB(16, 16)
RTP_CHECK_WB(8, 4)
RTP_CHECK_WB(16, 8)
#undef RTP_CHECK_WB

}  // namespace rtp
