// rtpack-inspect --verify: the cross-chunk invariants of formats/SPEC.md §3–§4 (the in-BVH ones are
// checked by the walk in inspect_stats.cpp). Every failure names its chunk (chunk_label) and object.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <set>
#include <string>

#include "core/math.h"
#include "inspect/inspect.h"
#include "reader/check_chunks.h"

namespace rtp::inspect_detail {
namespace {

using fmt::ChunkKind;
constexpr uint32_t kNone = 0xFFFFFFFFu;
constexpr float kFInf = std::numeric_limits<float>::infinity();

std::string triangles(uint64_t n) { return str(n) + (n == 1 ? " triangle" : " triangles"); }

Box3d box_of(const float lo[3], const float hi[3]) {
  Box3d b;
  for (int a = 0; a < 3; ++a) b.lo[a] = lo[a], b.hi[a] = hi[a];
  return b;
}

bool inside(const Box3d& in, const Box3d& out, const double tol[3] = nullptr) {
  for (int a = 0; a < 3; ++a) {
    const double t = tol ? tol[a] : 0.0;
    if (!(out.lo[a] <= in.lo[a] + t && in.hi[a] - t <= out.hi[a])) return false;
  }
  return true;
}

Box3d top_lane(const fmt::TopNode& n, int l) {
  Box3d b;
  for (int a = 0; a < 3; ++a) b.lo[a] = n.lo[a][l], b.hi[a] = n.hi[a][l];
  return b;
}

// Counts `prims` into `count` (one counter per triangle of the mesh). Returns what is wrong with these
// prims: ids out of range, triangles already counted (here or by an earlier piece); "" when fine.
std::string coverage(const std::vector<uint32_t>& prims, uint64_t total, std::vector<uint8_t>& count) {
  uint64_t oor = 0, first_oor = 0, dup = 0, first_dup = 0;
  for (uint32_t p : prims) {
    if (p >= total) {
      if (!oor++) first_oor = p;
    } else if (count[p]++ && !dup++) {
      first_dup = p;
    }
    if (p < total && count[p] == 0) count[p] = 255;  // saturate
  }
  std::string s;
  if (oor) s = str(oor) + " prim ids out of range (first: " + str(first_oor) + "; the mesh has " + str(total) + " triangles)";
  if (dup) s += std::string(s.empty() ? "" : ", ") + triangles(dup) + " stored more than once (first: " + str(first_dup) + ")";
  return s;
}

// Where the instance table says a record is (SPEC §2.5).
std::string place(const fmt::InstanceRef& r) {
  if (r.point == fmt::InstanceRef::kNoPoint) return "no batching point";
  return "batching point " + str(r.point) + " (local " + str(r.local) + ")";
}

// "N triangles missing (first: t)" or "" when every triangle was counted.
std::string missing(const std::vector<uint8_t>& count) {
  uint64_t n = 0, first = 0;
  for (size_t t = 0; t < count.size(); ++t)
    if (count[t] == 0 && !n++) first = t;
  return n ? triangles(n) + " missing (first: " + str(first) + ")" : std::string();
}

}  // namespace

Verifier::Verifier(const PackageReader& reader, const Resident& resident, Problems& problems)
    : r_(reader), res_(resident), out_(problems) {
  instance_seen_.assign(res_.instances.size(), 0);
  unique_cover_.resize(res_.instances.size());
  mesh_in_segment_.assign(res_.meshes.size(), 0);
  check_toc();
  check_tables();
  check_top();
}

void Verifier::check_toc() {
  const fmt::Header& h = r_.header();
  bool reserved = (h.flags & ~(fmt::kFlagNormals | fmt::kFlagUvs | fmt::kFlagDag)) != 0;
  for (uint8_t b : h.reserved) reserved |= b != 0;
  if (reserved) out_.add("header: flags or reserved bytes are not 0");
  // World bounds (SPEC §1): finite with lo <= hi, or the empty box (lo = +inf, hi = -inf) of a package
  // without triangles. The automatic camera frames them: NaN bounds gave a blank image and exit 0.
  static const char* kAxis = "xyz";
  for (int k = 0; k < 3; ++k) {
    const float lo = h.bounds_lo[k], hi = h.bounds_hi[k];
    const bool empty = h.unique_triangles == 0 && lo == INFINITY && hi == -INFINITY;
    if (!empty && !(std::isfinite(lo) && std::isfinite(hi) && lo <= hi))
      out_.add(std::string("header: world bounds on ") + kAxis[k] + " are [" + std::to_string(lo) + ", " + std::to_string(hi) +
               "], not finite with min <= max");
  }
  check_padding();
  const auto& toc = r_.toc();
  std::set<std::pair<uint32_t, uint64_t>> seen;
  for (size_t i = 0; i < toc.size(); ++i) {
    const fmt::TocEntry& e = toc[i];
    const std::string label = chunk_label(e, i);
    if (!seen.insert({e.kind, e.id}).second) out_.add(label + ": a second chunk of this kind with this id");
    if (e.kind >= 1 && e.kind <= 7 && e.id != 0) out_.add(label + ": a resident chunk with an id other than 0");
    if (e.reserved != 0) out_.add(label + ": table-of-contents entry has a non-zero reserved field");
    if (e.kind == uint32_t(ChunkKind::kMeshSegment)) ++segments_;
    if (e.kind == uint32_t(ChunkKind::kBatchingPoint)) {
      ++points_;
      if (res_.descs_ok && e.id >= res_.descs.size()) out_.add(label + ": no batching-point descriptor has this id");
    }
  }
  for (size_t i = 0; i < toc.size(); ++i)
    if (toc[i].kind == uint32_t(ChunkKind::kMeshSegment) && toc[i].id >= segments_)
      out_.add(chunk_label(toc[i], i) + ": segment ids are not 0.." + str(segments_ - 1));
}

// The bytes no checksum covers (SPEC §1): the header block after the 128-byte header, the padding
// between chunks up to each 4 KiB boundary, and nothing after the table of contents. All zeros.
void Verifier::check_padding() {
  const fmt::Header& h = r_.header();
  auto zeros = [&](uint64_t from, uint64_t to, const std::string& what) {
    if (to <= from) return;
    const uint64_t at = r_.first_nonzero(from, to - from);
    if (at != PackageReader::kAllZero) out_.add(what + ": byte " + str(at) + " of the file is not 0");
  };
  zeros(sizeof(fmt::Header), fmt::kAlignment, "header block padding (bytes 128..4095)");
  std::vector<std::pair<uint64_t, size_t>> order;  // (offset, toc index)
  for (size_t i = 0; i < r_.toc().size(); ++i) order.push_back({r_.toc()[i].offset, i});
  std::sort(order.begin(), order.end());
  uint64_t end = fmt::kAlignment;
  std::string after = "the header block";
  for (const auto& [offset, i] : order) {
    const fmt::TocEntry& e = r_.toc()[i];
    if (offset < end)
      out_.add(chunk_label(e, i) + ": overlaps " + after);
    else
      zeros(end, offset, "padding after " + after);
    end = std::max(end, offset + e.stored_size);
    after = chunk_label(e, i);
  }
  zeros(end, h.toc_offset, "padding after " + after);
  const uint64_t toc_end = h.toc_offset + h.toc_count * h.toc_entry_size;
  if (toc_end != h.file_size) out_.add("file: " + str(h.file_size - toc_end) + " bytes after the table of contents");
}

void Verifier::check_tables() {
  const fmt::Header& h = r_.header();
  const uint64_t n_meshes = res_.meshes.size();
  std::vector<uint32_t> uses(n_meshes, 0);
  uint64_t instanced = 0, unique = 0;
  if (res_.instances_ok && res_.meshes_ok) {
    for (size_t i = 0; i < res_.instances.size(); ++i) {
      const fmt::InstanceRef& rec = res_.instances[i];
      const std::string what = res_.instances_label + ": instance " + str(i);
      if (rec.mesh >= n_meshes) {
        out_.add(what + ": mesh " + str(rec.mesh) + " out of range (" + str(n_meshes) + " meshes)");
        continue;
      }
      ++uses[rec.mesh];
      instanced += res_.meshes[rec.mesh].triangles;
    }
    if (instanced != h.instanced_triangles)
      out_.add("header: instanced_triangles " + str(h.instanced_triangles) + ", the instance table gives " + str(instanced));
  }
  if (res_.meshes_ok) {
    uint64_t prims = 0, tris = 0;
    for (size_t m = 0; m < n_meshes; ++m) {
      const fmt::MeshInfo& mi = res_.meshes[m];
      const std::string what = res_.meshes_label + ": mesh " + str(m);
      unique += mi.triangles;
      prims += mi.source_prim_count;
      tris += mi.triangles;
      const bool flag = mi.flags & 1u;
      if (res_.instances_ok && flag != (uses[m] >= 2))
        out_.add(what + ": instanced flag " + str(flag) + " but used by " + str(uses[m]) + " instances");
      if (flag != (mi.segment != kNone)) out_.add(what + ": instanced flag disagrees with its segment");
      if (mi.segment != kNone && mi.segment >= segments_)
        out_.add(what + ": segment " + str(mi.segment) + " out of range (" + str(segments_) + " segments)");
      if (!res_.source_ok) continue;
      if (!range_inside(mi.source_prim_first, mi.source_prim_count, res_.source_prims.size()) ||
          !range_inside(mi.source_tri_first, mi.triangles, res_.source_tris.size())) {
        out_.add(res_.source_label + ": mesh " + str(m) + ": source map range outside the section");
        continue;
      }
      for (uint64_t t = 0; t < mi.triangles; ++t)
        if (res_.source_tris[mi.source_tri_first + t][0] >= mi.source_prim_count) {
          out_.add(res_.source_label + ": mesh " + str(m) + " triangle " + str(t) + ": primitive slot out of range");
          break;
        }
    }
    if (unique != h.unique_triangles)
      out_.add("header: unique_triangles " + str(h.unique_triangles) + ", the mesh table gives " + str(unique));
    if (res_.source_ok && (prims != res_.source_prims.size() || tris != res_.source_tris.size()))
      out_.add(res_.source_label + ": " + str(res_.source_prims.size()) + " primitives and " + str(res_.source_tris.size()) +
               " triangles, the mesh table gives " + str(prims) + " and " + str(tris));
  }
  if (res_.descs_ok) {
    if (points_ != res_.descs.size())
      out_.add(res_.descs_label + ": " + str(res_.descs.size()) + " descriptors, " + str(points_) + " batching-point chunks");
    for (size_t p = 0; p < res_.descs.size(); ++p) {
      const fmt::BatchingPointDesc& d = res_.descs[p];
      const std::string what = res_.descs_label + ": batching point " + str(p);
      if (d.chunk_id != p) out_.add(what + ": chunk id " + str(d.chunk_id) + " is not its index");
      if (r_.find(ChunkKind::kBatchingPoint, d.chunk_id) < 0) out_.add(what + ": its chunk is missing");
      if (!range_inside(d.segment_first, d.segment_count, res_.segment_refs.size())) {
        out_.add(what + ": segment range outside the section");
        continue;
      }
      for (uint32_t k = 0; k < d.segment_count; ++k)
        if (res_.segment_refs[d.segment_first + k] >= segments_)
          out_.add(what + ": needs segment " + str(res_.segment_refs[d.segment_first + k]) + ", out of range");
      if (box_of(d.lo, d.hi).empty()) out_.add(what + ": empty or invalid bounds");
    }
  }
  if (res_.meta_ok) {
    const nlohmann::json& m = res_.meta;
    auto expect = [&](const char* key, uint64_t want) {
      if (!m.contains(key) || !m[key].is_number_unsigned() || m[key].get<uint64_t>() != want)
        out_.add(res_.meta_label + ": \"" + key + "\" is " + (m.contains(key) ? m[key].dump() : "missing") + ", expected " +
                 str(want));
    };
    expect("bvh_width", h.bvh_width);
    expect("leaf_width", h.leaf_width);
    expect("mesh_segments", segments_);
    if (res_.descs_ok) expect("batching_points", res_.descs.size());
  }
}

// SPEC §4.1 top level: 4-wide, node 0 = root, leaves = batching points, parent/slot/depth consistent,
// children after their parents, each node and each batching point referenced exactly once.
void Verifier::check_top() {
  if (!res_.top_ok) return;
  const auto& top = res_.top;
  const uint64_t n_points = res_.descs.size();
  const std::string& L = res_.top_label;
  if (top.empty()) {
    if (n_points) out_.add(L + ": no nodes but " + str(n_points) + " batching points");
    return;
  }
  if (top[0].parent != fmt::TopNode::kEmpty || top[0].slot != 0 || top[0].depth != 0)
    out_.add(L + ": node 0 (root): parent/slot/depth are not none/0/0");
  std::vector<uint32_t> node_refs(top.size(), 0), point_refs(n_points, 0);
  for (size_t n = 0; n < top.size(); ++n) {
    const fmt::TopNode& node = top[n];
    for (int l = 0; l < 4; ++l) {
      const uint32_t c = node.child[l];
      const std::string where = L + ": node " + str(n) + " lane " + str(l) + ": ";
      const Box3d lane = top_lane(node, l);
      if (c == fmt::TopNode::kEmpty) {
        for (int a = 0; a < 3; ++a)
          if (!(node.lo[a][l] == kFInf && node.hi[a][l] == -kFInf)) {
            out_.add(where + "empty lane without the empty box");
            break;
          }
        continue;
      }
      if (c & fmt::TopNode::kLeafBit) {
        const uint32_t p = c & ~fmt::TopNode::kLeafBit;
        if (p >= n_points) {
          out_.add(where + "batching point " + str(p) + " out of range (" + str(n_points) + ")");
          continue;
        }
        ++point_refs[p];
        const fmt::BatchingPointDesc& d = res_.descs[p];
        if (!inside(box_of(d.lo, d.hi), lane))
          out_.add(where + "batching point " + str(p) + ": its bounds are not inside the lane box");
        continue;
      }
      if (c >= top.size() || c <= n) {
        out_.add(where + "child node " + str(c) + " out of range or not after its parent");
        continue;
      }
      ++node_refs[c];
      const fmt::TopNode& ch = top[c];
      if (ch.parent != n || ch.slot != uint32_t(l) || ch.depth != node.depth + 1)
        out_.add(where + "child node " + str(c) + " has parent/slot/depth " + str(ch.parent) + "/" + str(ch.slot) + "/" +
                 str(ch.depth) + ", expected " + str(n) + "/" + str(l) + "/" + str(node.depth + 1));
      Box3d u;
      for (int k = 0; k < 4; ++k)
        if (ch.child[k] != fmt::TopNode::kEmpty) u.grow(top_lane(ch, k));
      if (!inside(u, lane)) out_.add(where + "child box not inside parent (node " + str(c) + ")");
    }
  }
  for (size_t n = 1; n < top.size(); ++n)
    if (node_refs[n] != 1) out_.add(L + ": node " + str(n) + " is referenced " + str(node_refs[n]) + " times");
  for (size_t p = 0; p < n_points; ++p)
    if (point_refs[p] != 1) out_.add(L + ": batching point " + str(p) + " is referenced " + str(point_refs[p]) + " times");
}

void Verifier::segment(const SegmentData& s) {
  std::vector<GeometryEntry> geo;
  for (const fmt::MeshEntry& e : s.entries) geo.push_back({e.id, e.id, e.triangles, 0});
  attrs_.geometry(uint32_t(ChunkKind::kMeshSegment), s.id, std::move(geo));
  for (size_t k = 0; k < s.entries.size(); ++k) {
    const fmt::MeshEntry& e = s.entries[k];
    const std::string what = s.label + ": mesh " + str(e.id);
    if (e.id >= res_.meshes.size()) {
      out_.add(what + ": out of range (" + str(res_.meshes.size()) + " meshes)");
      continue;
    }
    const fmt::MeshInfo& mi = res_.meshes[e.id];
    if (mi.segment != s.id) out_.add(what + ": the mesh table puts it in segment " + str(mi.segment));
    if (mesh_in_segment_[e.id]++) out_.add(what + ": stored a second time");
    if (e.triangles != mi.triangles)
      out_.add(what + ": " + str(e.triangles) + " triangles, the mesh table says " + str(mi.triangles));
    std::vector<uint8_t> count(mi.triangles, 0);
    std::string bad = coverage(s.prims[k], mi.triangles, count);
    const std::string t = missing(count);
    if (!t.empty()) bad += (bad.empty() ? "" : ", ") + t;
    if (!bad.empty()) out_.add(what + ": " + bad);
  }
}

void Verifier::point(const PointData& p) {
  const std::string& L = p.label;
  if (p.te_count != 1 || p.te.node_count != p.inode_count || p.te.block_count != p.id_count)
    out_.add(L + ": instance BVH entry disagrees with its sections (" + str(p.te_count) + " entries, " + str(p.inode_count) +
             " nodes, " + str(p.id_count) + " ids)");
  if (p.global_ids.size() != p.records.size())
    out_.add(L + ": " + str(p.global_ids.size()) + " global ids for " + str(p.records.size()) + " instances");
  const fmt::BatchingPointDesc* d = p.id < res_.descs.size() ? &res_.descs[p.id] : nullptr;
  std::set<uint32_t> segs_needed;
  std::vector<uint32_t> entry_slots(p.entries.size(), 0);
  for (size_t s = 0; s < p.slots.size(); ++s) {
    const uint32_t v = p.slots[s];
    if (v & fmt::kPieceBit) {
      if ((v & ~fmt::kPieceBit) >= p.entries.size())
        out_.add(L + ": mesh slot " + str(s) + " names a missing piece entry");
      else
        ++entry_slots[v & ~fmt::kPieceBit];
    } else if (v >= res_.meshes.size() || res_.meshes[v].segment == kNone) {
      out_.add(L + ": mesh slot " + str(s) + ": mesh " + str(v) + " is not an instanced mesh in a segment");
    } else {
      segs_needed.insert(res_.meshes[v].segment);
    }
  }
  for (size_t k = 0; k < entry_slots.size(); ++k)
    if (entry_slots[k] != 1) out_.add(L + ": piece entry " + str(k) + " is named by " + str(entry_slots[k]) + " mesh slots");
  if (d)
    for (uint32_t seg : segs_needed) {
      bool listed = false;
      for (uint32_t k = 0; k < d->segment_count && d->segment_first + uint64_t(k) < res_.segment_refs.size(); ++k)
        listed |= res_.segment_refs[d->segment_first + k] == seg;
      if (!listed) out_.add(L + ": needs mesh segment " + str(seg) + ", which its descriptor does not list");
    }
  std::vector<uint32_t> refs(p.records.size(), 0);
  for (uint32_t id : p.instance_refs)
    if (id < refs.size()) ++refs[id];
  uint64_t instances = 0, instanced_tris = 0;
  bool pieces_done = false;
  for (size_t k = 0; k < p.records.size(); ++k) {
    const fmt::InstanceRecord& rec = p.records[k];
    const std::string what = L + ": local instance " + str(k);
    if (refs[k] != 1) out_.add(what + ": referenced " + str(refs[k]) + " times by the instance BVH");
    if (rec.mesh >= p.slots.size()) {
      out_.add(what + ": mesh slot " + str(rec.mesh) + " out of range");
      continue;
    }
    const bool piece = p.slots[rec.mesh] & fmt::kPieceBit;
    if (piece && pieces_done) out_.add(what + ": a piece after the instances (pieces come first)");
    pieces_done |= !piece;
    if (d && !p.bounds[k].box.empty() && !inside(p.bounds[k].box, box_of(d->lo, d->hi), p.bounds[k].tol))
      out_.add(what + ": its bounds are not inside the batching point's descriptor bounds");
    if (k >= p.global_ids.size()) continue;
    const uint32_t g = p.global_ids[k];
    if (g >= res_.instances.size() || res_.instances[g].mesh >= res_.meshes.size()) {
      out_.add(what + ": global instance " + str(g) + " out of range");
      continue;
    }
    const fmt::InstanceRef& gref = res_.instances[g];
    const fmt::MeshInfo& mi = res_.meshes[gref.mesh];
    if (((rec.flags & 1u) != 0) != (det3_of(rec.inverse_linear) < 0))
      out_.add(what + ": mirrored flag disagrees with the determinant");
    if (piece) {
      const uint32_t entry = p.slots[rec.mesh] & ~fmt::kPieceBit;
      if (mi.flags & 1u) out_.add(what + ": a piece of instance " + str(g) + ", whose mesh " + str(gref.mesh) + " is instanced");
      // Every piece of one instance carries its record; the table points at the first (SPEC §2.5).
      PieceHome& home = piece_home_[g];
      const bool seen = home.point != kNone;
      if (seen && std::memcmp(&rec.translation, &home.rec.translation, offsetof(fmt::InstanceRecord, mesh)))
        out_.add(what + ": a piece of instance " + str(g) + " whose transform differs from its piece in batching point " +
                 str(home.point) + " (local " + str(home.local) + ")");
      if (!seen || std::pair(uint32_t(p.id), uint32_t(k)) < std::pair(home.point, home.local))
        home = {uint32_t(p.id), uint32_t(k), rec};
      if (entry >= p.entries.size() || (mi.flags & 1u)) continue;
      std::vector<uint8_t>& cover = unique_cover_[g];
      cover.resize(mi.triangles, 0);
      const std::string bad = coverage(p.piece_prims[entry], mi.triangles, cover);
      if (!bad.empty()) out_.add(L + ": piece " + str(p.entries[entry].id) + " (entry " + str(entry) + "): " + bad);
    } else {
      ++instances;
      instanced_tris += mi.triangles;
      ++instance_seen_[g];
      if (p.slots[rec.mesh] != gref.mesh)
        out_.add(what + ": mesh " + str(p.slots[rec.mesh]) + ", the instance table says " + str(gref.mesh) + " for instance " +
                 str(g));
      if (gref.point != p.id || gref.local != k)
        out_.add(what + ": instance " + str(g) + ", which " + res_.instances_label + " places in " + place(gref));
    }
  }
  std::vector<GeometryEntry> geo;
  for (size_t k = 0; k < p.entries.size(); ++k)
    geo.push_back({p.entries[k].id, kNone, p.entries[k].triangles, prim_set_hash(p.piece_prims[k])});
  for (size_t k = 0; k < p.records.size() && k < p.global_ids.size(); ++k) {  // piece entry -> scene mesh
    const uint32_t mesh_slot = p.records[k].mesh;
    if (mesh_slot >= p.slots.size() || !(p.slots[mesh_slot] & fmt::kPieceBit)) continue;
    const uint32_t entry = p.slots[mesh_slot] & ~fmt::kPieceBit;
    if (entry < geo.size() && p.global_ids[k] < res_.instances.size()) geo[entry].mesh = res_.instances[p.global_ids[k]].mesh;
  }
  attrs_.geometry(uint32_t(ChunkKind::kBatchingPoint), p.id, std::move(geo));
  uint64_t unique = 0;
  for (size_t k = 0; k < p.entries.size(); ++k) {
    const fmt::MeshEntry& e = p.entries[k];
    unique += e.triangles;
    if (e.triangles != p.piece_prims[k].size())
      out_.add(L + ": piece " + str(e.id) + " (entry " + str(k) + "): says " + str(e.triangles) + " triangles, its leaves hold " +
               str(p.piece_prims[k].size()));
    if (piece_seen_[e.id]++) out_.add(L + ": piece " + str(e.id) + " is stored a second time");
    ++pieces_;
  }
  if (!d) {
    out_.add(L + ": no descriptor for this batching point");
    return;
  }
  if (d->piece_count != p.entries.size() || d->instance_count != instances || d->unique_triangles != unique ||
      d->instanced_triangles != instanced_tris)
    out_.add(L + ": descriptor says " + str(d->piece_count) + " pieces, " + str(d->instance_count) + " instances, " +
             str(d->unique_triangles) + "+" + str(d->instanced_triangles) + " triangles; the chunk has " + str(p.entries.size()) +
             ", " + str(instances) + ", " + str(unique) + "+" + str(instanced_tris));
}

void Verifier::attributes(size_t i, const AlignedBytes& bytes) {
  const fmt::TocEntry& e = r_.toc()[i];
  attrs_.chunk(e.kind, e.id, chunk_label(e, i), bytes, out_);
}

void Verifier::finish() {
  attrs_.finish(res_.meshes, r_.header().flags, out_);
  for (size_t g = 0; g < res_.instances.size(); ++g) {
    const uint32_t m = res_.instances[g].mesh;
    if (m >= res_.meshes.size()) continue;
    const std::string what = res_.instances_label + ": instance " + str(g) + " (mesh " + str(m) + ")";
    if (bad_points_.count(res_.instances[g].point)) continue;  // its point is already a problem
    if (res_.meshes[m].flags & 1u) {
      if (instance_seen_[g] != 1) out_.add(what + ": in " + str(instance_seen_[g]) + " batching points, expected 1");
      continue;
    }
    if (instance_seen_[g]) out_.add(what + ": a unique mesh's instance referenced as an instance, not as pieces");
    const auto home = piece_home_.find(uint32_t(g));
    const fmt::InstanceRef& ref = res_.instances[g];
    if (home == piece_home_.end() ? ref.point != fmt::InstanceRef::kNoPoint
                                  : ref.point != home->second.point || ref.local != home->second.local)
      out_.add(what + ": the instance table places it in " + place(ref) + ", its first piece is in " +
               (home == piece_home_.end()
                    ? std::string("no batching point")
                    : "batching point " + str(home->second.point) + " (local " + str(home->second.local) + ")"));
    if (res_.meshes[m].triangles == 0) continue;
    if (unique_cover_[g].empty()) {
      out_.add(what + ": none of its triangles is in a piece");
      continue;
    }
    const std::string t = missing(unique_cover_[g]);
    if (!t.empty()) out_.add(what + ": its pieces: " + t);
  }
  for (size_t m = 0; m < res_.meshes.size(); ++m)
    if ((res_.meshes[m].flags & 1u) && mesh_in_segment_[m] != 1 && !bad_segments_.count(res_.meshes[m].segment))
      out_.add(res_.meshes_label + ": mesh " + str(m) + " is stored " + str(mesh_in_segment_[m]) + " times in mesh segments");
  // Piece ids are 0..pieces-1: the ids seen are a map (a hostile id costs one entry, not 4 GB), and the
  // missing ones are one message (count and first), not one per id.
  uint64_t expect = 0, missing_ids = 0, first_missing = 0;
  for (const auto& [id, n] : piece_seen_) {
    if (id > expect && !missing_ids) first_missing = expect;
    missing_ids += id - expect;
    expect = uint64_t(id) + 1;
  }
  if (missing_ids)
    out_.add(str(missing_ids) + (missing_ids == 1 ? " piece id is" : " piece ids are") +
             " in no batching point (first: " + str(first_missing) + "; the highest id stored is " + str(expect - 1) + ")");
  if (res_.meta_ok && res_.meta.contains("pieces") && res_.meta["pieces"] != pieces_)
    out_.add(res_.meta_label + ": \"pieces\" is " + res_.meta["pieces"].dump() + ", the batching points hold " + str(pieces_));
}

}  // namespace rtp::inspect_detail
