// rtpack-inspect's analysis: one pass over the package (resident chunks, then mesh segments, then
// batching points), each chunk read once (CRC-checked, decompressed) and dropped after use; sizes,
// batching-point and segment statistics, per-chunk BVH statistics, and (verify) every invariant.
#include "inspect/inspect.h"
#include "inspect/dag_coverage.h"

#include <cfloat>
#include <cmath>
#include <cstring>
#include <map>
#include <memory>
#include <optional>

#include "core/error.h"
#include "core/json_checked.h"
#include "core/math.h"
#include "reader/attribute_lookup.h"
#include "reader/camera.h"
#include "reader/check_chunks.h"
#include "reader/check_culling.h"
#include "layout/chunk_io.h"

namespace rtp {
namespace {

using namespace inspect_detail;
using fmt::ChunkKind;
using fmt::SectionType;

bool is_resident(uint32_t kind) { return kind >= 1 && kind <= 7; }  // 7: the DAG pool (2.0)

struct Ctx {
  Ctx(const PackageReader& reader, const InspectOptions& opt) : r(reader), o(opt), problems(opt.max_listed) {}
  const PackageReader& r;
  const InspectOptions& o;
  Problems problems;
  Resident res;
  std::unique_ptr<Verifier> ver;
  std::vector<nlohmann::json> rows;  // per TOC entry
  BvhGroup seg_meshes, pieces, inst_bvhs;
  std::map<uint32_t, Box3d> mesh_root;          // instanced mesh -> its BVH's root bounds (local space)
  std::map<uint32_t, MeshTriangles> mesh_tris;  // --verify: instanced mesh -> its leaf triangles
  Spread seg_meshes_n, seg_tris, seg_stored, seg_raw;
  uint64_t segments_read = 0, points_read = 0;
  std::string label(size_t i) const { return chunk_label(r.toc()[i], i); }
};

// Reads chunk i; a checksum or decompression failure becomes a problem (I/O errors propagate).
std::optional<AlignedBytes> load(Ctx& c, size_t i) {
  try {
    return c.r.read(i);
  } catch (const Error& e) {
    if (e.code() == ExitCode::kInputIo) throw;
    c.problems.add(e.what());
    return std::nullopt;
  }
}

// Runs `f` (which parses a chunk); a malformed chunk becomes a problem naming it.
template <class F>
void guarded(Ctx& c, F&& f) {
  try {
    f();
  } catch (const Error& e) {
    if (e.code() == ExitCode::kInputIo) throw;
    c.problems.add(e.what());
  }
}

// The structural checks of the resident chunks against each other (check_chunks.h). A mesh table
// whose triangle counts the source map does not back is dropped, so no check allocates by them.
void check_resident(Ctx& c) {
  Resident& res = c.res;
  uint64_t segments = 0;
  for (const fmt::TocEntry& e : c.r.toc()) segments += e.kind == uint32_t(ChunkKind::kMeshSegment);
  if (res.meshes_ok) {
    bool ok = false;
    guarded(c, [&] {
      if (!res.source_ok) fail_invalid(res.meshes_label + ": no readable source map backs its triangle counts");
      check_mesh_table(res.meshes.data(), res.meshes.size(), res.source_prims.size(), res.source_tris.size(), segments,
                       res.meshes_label);
      ok = true;
    });
    if (!ok) {
      res.meshes_ok = false;
      res.meshes.clear();
    }
  }
  if (res.instances_ok)
    guarded(c, [&] {
      check_instance_table(res.instances.data(), res.instances.size(), res.meshes_ok ? res.meshes.size() : kUnknownCount,
                           res.descs_ok ? res.descs.size() : kUnknownCount, res.instances_label);
      res.instances_checked = res.meshes_ok;
    });
  if (res.descs_ok)
    guarded(c, [&] { check_point_descs(res.descs.data(), res.descs.size(), res.segment_refs.size(), res.descs_label); });
  if (res.top_ok) {
    bool ok = false;
    guarded(c, [&] {
      check_top_level(res.top.data(), res.top.size(), res.descs_ok ? res.descs.size() : kUnknownCount, res.top_label);
      ok = true;
    });
    res.top_ok = ok;
  }
}

void read_resident(Ctx& c) {
  Resident& res = c.res;
  for (uint32_t kind = 1; kind <= 7; ++kind) {
    const int64_t idx = c.r.find(ChunkKind(kind), 0);
    if (idx < 0) {  // the DAG pool is optional (--no-dag); --verify checks it against the grids
      if (ChunkKind(kind) != ChunkKind::kDagPool) c.problems.add(std::string("missing ") + chunk_kind_name(kind) + " chunk");
      continue;
    }
    if (ChunkKind(kind) == ChunkKind::kDagPool) {
      res.dag_present = true;
      res.dag_label = c.label(size_t(idx));
    }
    const size_t i = size_t(idx);
    const std::optional<AlignedBytes> b = load(c, i);
    if (!b) continue;
    const std::string label = c.label(i);
    guarded(c, [&] {
      ChunkView v(b->data(), b->size(), kind, label);
      switch (ChunkKind(kind)) {
        case ChunkKind::kMetadata: {
          const std::vector<uint8_t> text = v.copy<uint8_t>(SectionType::kJson);
          jsonc::check_depth(std::string_view(reinterpret_cast<const char*>(text.data()), text.size()), label + ": metadata ");
          res.meta = nlohmann::json::parse(text.begin(), text.end(), nullptr, false);
          if (res.meta.is_discarded() || !res.meta.is_object()) fail_invalid(label + ": metadata is not a JSON object");
          res.meta_ok = true;
          res.meta_label = label;
          break;
        }
        case ChunkKind::kTopLevelBvh:
          res.top = v.copy<fmt::TopNode>(SectionType::kTopNodes);
          res.top_ok = true;
          res.top_label = label;
          break;
        case ChunkKind::kBatchingPoints:
          res.descs = v.copy<fmt::BatchingPointDesc>(SectionType::kPointDescs);
          res.segment_refs = v.copy<uint32_t>(SectionType::kSegmentRefs);
          res.descs_ok = true;
          res.descs_label = label;
          res.grids_present = v.has(SectionType::kPointGrids);
          res.grids = v.copy<fmt::DagGrid>(SectionType::kPointGrids, false);  // a bad element size throws
          res.grids_ok = res.grids_present;
          break;
        case ChunkKind::kDagPool:
          res.dag_words = v.copy<uint32_t>(SectionType::kDagNodes);
          res.dag_leaves = v.copy<uint64_t>(SectionType::kDagLeaves);
          if (const size_t nb = fmt::cull_node_bytes(c.r.header().bvh_width);
              const void* cn = v.get_raw(SectionType::kCullNodes, nb, res.cull_count, false)) {
            res.cull_nodes.resize(res.cull_count * nb);
            if (!res.cull_nodes.empty()) std::memcpy(res.cull_nodes.data(), cn, res.cull_nodes.size());  // none: no pointer
          }
          res.dag_ok = true;
          break;
        case ChunkKind::kInstances:
          res.instances = v.copy<fmt::InstanceRef>(SectionType::kInstanceRefs);
          res.instances_ok = true;
          res.instances_label = label;
          break;
        case ChunkKind::kMeshes:
          res.meshes = v.copy<fmt::MeshInfo>(SectionType::kMeshTable);
          res.meshes_ok = true;
          res.meshes_label = label;
          break;
        default:
          res.source_prims = v.copy<Pair>(SectionType::kSourcePrims);
          res.source_tris = v.copy<Pair>(SectionType::kSourceTris);
          res.source_ok = true;
          res.source_label = label;
          break;
      }
    });
  }
  check_resident(c);
}

// The image of `b` under the record's transform (SPEC §2.4: double T, float L^-1; L is L^-1 inverted
// here in double), with a tolerance per axis of two float steps at the magnitude of the terms, the
// linear ones scaled by L's condition number (L^-1 was rounded from the double inverse of the L the
// writer placed the box with; inverting the rounded floats moves L by up to about that much).
ItemBound transformed(const fmt::InstanceRecord& rec, const Box3d& b) {
  ItemBound out;
  if (b.empty()) return out;
  const float* li = rec.inverse_linear;
  double m[9];                          // L = adj(L^-1) / det, row-major
  if (!inverse3_of(li, m)) return out;  // singular: never hit, nothing to contain
  double norm_l = 0, norm_li = 0;       // infinity norms
  for (int r = 0; r < 3; ++r) {
    norm_l = std::max(norm_l, std::fabs(m[3 * r]) + std::fabs(m[3 * r + 1]) + std::fabs(m[3 * r + 2]));
    norm_li =
        std::max(norm_li, std::fabs(double(li[3 * r])) + std::fabs(double(li[3 * r + 1])) + std::fabs(double(li[3 * r + 2])));
  }
  const double cond = std::max(1.0, norm_l * norm_li);
  for (int corner = 0; corner < 8; ++corner) {
    double p[3], w[3];
    for (int a = 0; a < 3; ++a) p[a] = (corner >> a & 1) ? b.hi[a] : b.lo[a];
    for (int r = 0; r < 3; ++r)
      w[r] = double(m[3 * r]) * p[0] + double(m[3 * r + 1]) * p[1] + double(m[3 * r + 2]) * p[2] + rec.translation[r];
    out.box.grow(w);
  }
  for (int r = 0; r < 3; ++r) {
    double lin = 0;
    for (int a = 0; a < 3; ++a) lin += std::fabs(m[3 * r + a]) * std::max(std::fabs(b.lo[a]), std::fabs(b.hi[a]));
    out.tol[r] = 2.0 * double(FLT_EPSILON) * (std::fabs(rec.translation[r]) + 2.0 * cond * lin);
  }
  return out;
}

// What decode_segment / decode_point check geometry chunks against: the tables that passed their own checks.
SceneTables scene_tables(const Resident& res) {
  SceneTables t;
  if (res.instances_ok) t.n_instances = res.instances.size();
  if (res.instances_checked) t.instances = res.instances.data();
  if (res.meshes_ok) t.meshes = res.meshes.data(), t.n_meshes = res.meshes.size();
  return t;
}

template <int W, int B>
void segment_chunk(Ctx& c, size_t i, const AlignedBytes& b) {
  const std::string label = c.label(i);
  ChunkView v(b.data(), b.size(), uint32_t(ChunkKind::kMeshSegment), label);
  // Throws: the chunk becomes a problem.
  const GeometrySections<W, B> geo = decode_segment<W, B>(v, scene_tables(c.res), c.r.toc()[i].id);
  const uint64_t ne = geo.n_entries;
  const fmt::MeshEntry* e = geo.entries;
  const fmt::WideNode<W>* nodes = geo.nodes;
  const fmt::LeafBlock<B>* blocks = geo.blocks;
  SegmentData sd;
  sd.id = c.r.toc()[i].id;
  sd.label = label;
  sd.entries.assign(e, e + ne);
  sd.prims.resize(ne);
  BvhGroup g;
  uint64_t tris = 0;
  for (uint64_t k = 0; k < ne; ++k) {
    const std::string what = label + ": mesh " + std::to_string(e[k].id);
    tris += e[k].triangles;
    BvhCheck ck;
    ck.label = what;
    if (c.ver) ck.problems = &c.problems, ck.prims = &sd.prims[k];
    const BvhShape s = mesh_bvh_shape<W, B>(nodes + e[k].node_first, e[k].node_count, blocks + e[k].block_first, e[k].block_count,
                                            e[k].root, &ck);
    g.add(s);
    c.seg_meshes.add(s);
    c.mesh_root[e[k].id] = ck.root_box;
    if (c.ver) append_triangles<B>(blocks + e[k].block_first, e[k].block_count, c.mesh_tris[e[k].id]);
  }
  ++c.segments_read;
  c.seg_meshes_n.add(double(ne));
  c.seg_tris.add(double(tris));
  c.rows[i]["meshes"] = ne;
  c.rows[i]["triangles"] = tris;
  c.rows[i]["bvh"] = g.json();
  if (c.ver) c.ver->segment(sd);
}

// --verify: the point's voxel grid covers every triangle it traces (SPEC §4.5; instance-box grids are
// checked against the instance BVH at decode). Segments are read before points, so mesh_tris is complete.
template <int W, int B>
void voxel_coverage(Ctx& c, uint64_t point, const PointSections<W, B>& sec, const std::string& label) {
  if (!c.res.grids_ok || !c.res.dag_ok || point >= c.res.grids.size()) return;
  const fmt::DagGrid& grid = c.res.grids[point];
  const voxel::DagView view = dag_view(c.r, c.res);
  if (grid.resolution == fmt::kDagBoxes || !voxel::check_dag(grid, view).empty()) return;  // dag_report names it
  std::vector<MeshTriangles> pieces(sec.n_entries);
  for (uint64_t k = 0; k < sec.n_entries; ++k)
    append_triangles<B>(sec.blocks + sec.entries[k].block_first, sec.entries[k].block_count, pieces[k]);
  const std::string bad =
      point_coverage_problem(grid, view, sec.records, sec.n_records, sec.slots, sec.n_slots, pieces, c.mesh_tris);
  if (!bad.empty()) c.problems.add(label + ": " + bad);
}

template <int W, int B>
void point_chunk(Ctx& c, size_t i, const AlignedBytes& b) {
  const std::string label = c.label(i);
  ChunkView v(b.data(), b.size(), uint32_t(ChunkKind::kBatchingPoint), label);
  // Throws (the chunk becomes a problem) unless every index and range a walk follows is sound.
  const PointSections<W, B> sec = decode_point<W, B>(v, scene_tables(c.res), c.r.toc()[i].id);
  const uint64_t point = c.r.toc()[i].id;
  if (c.res.grids_ok && c.res.dag_ok && point < c.res.grids.size())
    check_instance_boxes<W>(c.res.grids[point], dag_view(c.r, c.res), sec.instance_nodes, sec.n_instance_nodes, label);
  const uint64_t n_te = 1, n_in = sec.n_instance_nodes, n_ids = sec.n_instance_ids, ne = sec.n_entries;
  const fmt::MeshEntry* te = sec.instance_bvh;
  const fmt::WideNode<W>* inodes = sec.instance_nodes;
  const uint32_t* ids = sec.instance_ids;
  const fmt::MeshEntry* e = sec.entries;
  const fmt::WideNode<W>* nodes = sec.nodes;
  const fmt::LeafBlock<B>* blocks = sec.blocks;
  PointData pd;
  pd.id = c.r.toc()[i].id;
  pd.label = label;
  pd.te_count = n_te;
  pd.inode_count = n_in;
  pd.id_count = n_ids;
  if (n_te) pd.te = te[0];
  pd.records = v.copy<fmt::InstanceRecord>(SectionType::kInstances);
  pd.global_ids = v.copy<uint32_t>(SectionType::kGlobalIds);
  pd.slots = v.copy<uint32_t>(SectionType::kMeshSlots);
  pd.entries.assign(e, e + ne);
  pd.piece_prims.resize(ne);
  BvhGroup g;
  uint64_t unique = 0;
  std::vector<Box3d> piece_root(ne);
  for (uint64_t k = 0; k < ne; ++k) {
    const std::string what = label + ": piece " + std::to_string(e[k].id) + " (entry " + std::to_string(k) + ")";
    unique += e[k].triangles;
    BvhCheck ck;
    ck.label = what;
    if (c.ver) ck.problems = &c.problems, ck.prims = &pd.piece_prims[k];
    const BvhShape s = mesh_bvh_shape<W, B>(nodes + e[k].node_first, e[k].node_count, blocks + e[k].block_first, e[k].block_count,
                                            e[k].root, &ck);
    g.add(s);
    c.pieces.add(s);
    piece_root[k] = ck.root_box;
  }
  // What each local instance's leaf box must contain: its mesh's (piece's) root bounds placed by its
  // transform (SPEC §4.2: pieces stay in their unique mesh's local space, with its instance transform).
  pd.bounds.resize(pd.records.size());
  uint64_t instances = 0, instanced = 0;
  for (size_t k = 0; k < pd.records.size(); ++k) {
    const uint32_t slot = pd.records[k].mesh;
    if (slot >= pd.slots.size()) continue;
    if (pd.slots[slot] & fmt::kPieceBit) {
      const uint32_t entry = pd.slots[slot] & ~fmt::kPieceBit;
      if (entry < ne) pd.bounds[k] = transformed(pd.records[k], piece_root[entry]);
      continue;
    }
    ++instances;
    if (pd.slots[slot] < c.res.meshes.size()) instanced += c.res.meshes[pd.slots[slot]].triangles;
    const auto it = c.mesh_root.find(pd.slots[slot]);
    if (it != c.mesh_root.end()) pd.bounds[k] = transformed(pd.records[k], it->second);
  }
  BvhShape top;
  if (n_te) {
    BvhCheck ck;
    ck.label = label + ": instance BVH";
    ck.items = pd.bounds.data();
    ck.item_count = pd.bounds.size();
    if (c.ver) ck.problems = &c.problems, ck.prims = &pd.instance_refs;
    top = instance_bvh_shape<W>(inodes, n_in, ids, n_ids, te[0].root, &ck);
    c.inst_bvhs.add(top);
  }
  if (c.ver) voxel_coverage<W, B>(c, point, sec, label);
  ++c.points_read;
  nlohmann::json& row = c.rows[i];
  row["pieces"] = ne;
  row["instances"] = instances;
  row["unique_triangles"] = unique;
  row["instanced_triangles"] = instanced;
  row["bvh"] = g.json();
  row["instance_bvh"] = {{"nodes", top.nodes},
                         {"c_box", top.c_box},
                         {"c_tri", top.c_tri},
                         {"branching", top.branching},
                         {"max_depth", top.max_depth}};
  if (c.ver) c.ver->point(pd);
}

template <int W, int B>
void on_demand(Ctx& c) {
  const auto& toc = c.r.toc();
  for (uint32_t kind : {uint32_t(ChunkKind::kMeshSegment), uint32_t(ChunkKind::kBatchingPoint)})
    for (size_t i = 0; i < toc.size(); ++i) {
      if (toc[i].kind != kind) continue;
      const std::optional<AlignedBytes> b = load(c, i);
      bool decoded = false;
      if (b)
        guarded(c, [&] {
          if (kind == uint32_t(ChunkKind::kMeshSegment))
            segment_chunk<W, B>(c, i, *b);
          else
            point_chunk<W, B>(c, i, *b);
          decoded = true;
        });
      if (!decoded && c.ver) c.ver->unreadable(kind, toc[i].id);
    }
}

nlohmann::json sizes(Ctx& c, double tris) {
  struct Sum {
    uint64_t chunks = 0, raw = 0, stored = 0;
  };
  std::map<uint32_t, Sum> by_kind;
  Sum resident, demand;
  for (const fmt::TocEntry& e : c.r.toc()) {
    for (Sum* s : {&by_kind[e.kind], is_resident(e.kind) ? &resident : &demand}) {
      ++s->chunks;
      s->raw += e.raw_size;
      s->stored += e.stored_size;
    }
  }
  auto row = [tris](const Sum& s) {
    return nlohmann::json{{"chunks", s.chunks},
                          {"raw_bytes", s.raw},
                          {"stored_bytes", s.stored},
                          {"ratio", s.stored ? double(s.raw) / double(s.stored) : 1.0},
                          {"raw_bytes_per_unique_triangle", double(s.raw) / tris},
                          {"stored_bytes_per_unique_triangle", double(s.stored) / tris}};
  };
  nlohmann::json kinds = nlohmann::json::array();
  for (const auto& [kind, s] : by_kind) {
    nlohmann::json j = row(s);
    j["kind"] = kind;
    j["name"] = chunk_kind_name(kind);
    j["residency"] = is_resident(kind) ? "resident" : (kind >= 16 ? "on demand" : "unknown");
    kinds.push_back(j);
  }
  // The rest of the file: the header block, the table of contents, and zeros up to 4 KiB boundaries.
  const fmt::Header& h = c.r.header();
  const uint64_t toc_bytes = h.toc_count * h.toc_entry_size;
  const uint64_t padding = h.file_size - fmt::kAlignment - toc_bytes - resident.stored - demand.stored;
  return {{"by_kind", kinds},         {"resident", row(resident)},
          {"on_demand", row(demand)}, {"header_block_bytes", fmt::kAlignment},
          {"toc_bytes", toc_bytes},   {"alignment_padding_bytes", padding}};
}

nlohmann::json points_json(Ctx& c) {
  Histogram tris, bytes, inst;
  Spread n_inst, n_pieces, n_tris, n_bytes;
  uint64_t unique = 0, instanced = 0, instances = 0, pieces = 0;
  for (const fmt::BatchingPointDesc& d : c.res.descs) {
    const uint64_t t = d.unique_triangles + d.instanced_triangles;
    tris.add(t);
    n_tris.add(double(t));
    inst.add(d.instance_count);
    n_inst.add(d.instance_count);
    n_pieces.add(d.piece_count);
    unique += d.unique_triangles;
    instanced += d.instanced_triangles;
    instances += d.instance_count;
    pieces += d.piece_count;
    const int64_t i = c.r.find(ChunkKind::kBatchingPoint, d.chunk_id);
    if (i >= 0) {
      bytes.add(c.r.toc()[size_t(i)].stored_size);
      n_bytes.add(double(c.r.toc()[size_t(i)].stored_size));
    }
  }
  return {{"count", c.res.descs.size()},
          {"chunks_read", c.points_read},
          {"unique_triangles", unique},
          {"instanced_triangles", instanced},
          {"instances", instances},
          {"pieces", pieces},
          {"triangles", n_tris.json()},
          {"stored_bytes", n_bytes.json()},
          {"instances_per_point", n_inst.json()},
          {"pieces_per_point", n_pieces.json()},
          {"triangles_histogram", tris.json()},
          {"stored_bytes_histogram", bytes.json()},
          {"instances_histogram", inst.json()}};
}

nlohmann::json metadata_json(const Resident& res) {
  if (!res.meta_ok) return nullptr;
  const nlohmann::json& m = res.meta;
  nlohmann::json out = nlohmann::json::object();
  for (const char* k : {"format", "tool_version", "source", "options", "bvh_build", "chunk_target", "chunk_by", "batching_points",
                        "mesh_segments", "pieces", "dag"})
    if (m.contains(k)) out[k] = m[k];
  nlohmann::json cams = nlohmann::json::array();
  // The cameras the converter wrote (write_package.cpp): every field checked, named by its pointer.
  if (const nlohmann::json* cameras = jsonc::find(m, "cameras")) {
    if (!cameras->is_array()) fail_invalid(res.meta_label + ": /cameras: not an array");
    for (size_t i = 0; i < cameras->size(); ++i) {
      const nlohmann::json& cam = (*cameras)[i];
      const std::string cp = res.meta_label + ": /cameras/" + std::to_string(i);
      nlohmann::json j = {{"name", jsonc::get_string(cam, "name", cp)}, {"type", jsonc::get_string(cam, "type", cp)}};
      const nlohmann::json& world = jsonc::member(cam, "world", cp);
      if (!world.is_array() || world.size() != 12) fail_invalid(cp + "/world: needs 12 numbers");
      double m[12];
      for (size_t k = 0; k < 12; ++k) m[k] = jsonc::as_number(world[k], cp + "/world/" + std::to_string(k));
      check_camera_world(m, cp + "/world");
      j["position"] = {world[3], world[7], world[11]};
      for (const char* k : {"yfov", "aspect_ratio", "xmag", "ymag", "znear", "zfar"})
        if (jsonc::get_number(cam, k, 0.0, cp) != 0) j[k] = cam[k];
      cams.push_back(j);
    }
  }
  out["cameras"] = cams;
  out["meshes"] = m.contains("mesh_names") && m["mesh_names"].is_array() ? m["mesh_names"].size() : 0;
  return out;
}

}  // namespace

InspectResult inspect_package(const PackageReader& reader, const InspectOptions& options) {
  Ctx c(reader, options);
  const fmt::Header& h = reader.header();
  const auto& toc = reader.toc();
  for (size_t i = 0; i < toc.size(); ++i) {
    const fmt::TocEntry& e = toc[i];
    c.rows.push_back({{"index", i},
                      {"kind", chunk_kind_name(e.kind)},
                      {"id", e.id},
                      {"offset", e.offset},
                      {"compression", e.compression == 1 ? "zstd" : (e.compression == 0 ? "none" : "unknown")},
                      {"raw_bytes", e.raw_size},
                      {"stored_bytes", e.stored_size},
                      {"ratio", e.stored_size ? double(e.raw_size) / double(e.stored_size) : 1.0}});
  }
  read_resident(c);
  if (options.verify) c.ver = std::make_unique<Verifier>(reader, c.res, c.problems);
  const uint32_t w = h.bvh_width, b = h.leaf_width;
  if (w == 4 && b == 4)
    on_demand<4, 4>(c);
  else if (w == 8 && b == 8)
    on_demand<8, 8>(c);
  else if (w == 16 && b == 16)
    on_demand<16, 16>(c);
  else if (w == 8 && b == 4)
    on_demand<8, 4>(c);
  else if (w == 16 && b == 8)
    on_demand<16, 8>(c);
  else
    c.problems.add("header: unsupported BVH width " + std::to_string(w) + " / leaf width " + std::to_string(b));
  // Unknown kinds are skipped by readers, but their checksums and frames are still checked.
  for (size_t i = 0; i < toc.size(); ++i)
    if (!is_resident(toc[i].kind) && toc[i].kind != 16 && toc[i].kind != 17) {
      const std::optional<AlignedBytes> b = load(c, i);
      const bool attr =
          toc[i].kind == uint32_t(ChunkKind::kSegmentAttributes) || toc[i].kind == uint32_t(ChunkKind::kPointAttributes);
      if (b && attr && c.ver) c.ver->attributes(i, *b);
      if (b && attr && !c.ver)  // the chunk on its own, as the attribute lookup decodes it (--verify: and against its geometry)
        guarded(c, [&] {
          const ChunkView v(b->data(), b->size(), toc[i].kind, c.label(i));
          (void)decode_attributes(v, toc[i].kind);
        });
    }
  if (c.ver) c.ver->finish();

  for (size_t i = 0; i < toc.size(); ++i)
    if (toc[i].kind == uint32_t(ChunkKind::kMeshSegment)) {
      c.seg_stored.add(double(toc[i].stored_size));
      c.seg_raw.add(double(toc[i].raw_size));
    }
  const double tris = double(std::max<uint64_t>(1, h.unique_triangles));
  nlohmann::json j;
  j["package_bytes"] = h.file_size;
  nlohmann::json attrs = nlohmann::json::array();
  if (h.flags & fmt::kFlagNormals) attrs.push_back("normal");
  if (h.flags & fmt::kFlagUvs) attrs.push_back("uv");
  j["header"] = {
      {"version", std::to_string(h.version_major) + "." + std::to_string(h.version_minor)},
      {"attributes", attrs},
      {"bvh_width", w},
      {"leaf_width", b},
      {"unique_triangles", h.unique_triangles},
      {"instanced_triangles", h.instanced_triangles},
      {"toc_entries", h.toc_count},
      {"bounds",
       {{"min", {h.bounds_lo[0], h.bounds_lo[1], h.bounds_lo[2]}}, {"max", {h.bounds_hi[0], h.bounds_hi[1], h.bounds_hi[2]}}}}};
  j["sizes"] = sizes(c, tris);
  j["bytes_per_unique_triangle"] = double(h.file_size) / tris;
  j["dag"] = dag_report(reader, c.res, c.problems);
  j["dag_pool_bytes"] = j["dag"]["pool_bytes"];
  j["instances"] = c.res.instances.size();
  j["meshes"] = c.res.meshes.size();
  j["batching_points"] = points_json(c);
  uint64_t seg_tris = 0;
  for (const fmt::MeshInfo& m : c.res.meshes)
    if (m.segment != 0xFFFFFFFFu) seg_tris += m.triangles;
  j["mesh_segments"] = {{"count", c.seg_raw.n},
                        {"chunks_read", c.segments_read},
                        {"triangles", seg_tris},
                        {"meshes_per_segment", c.seg_meshes_n.json()},
                        {"triangles_per_segment", c.seg_tris.json()},
                        {"stored_bytes", c.seg_stored.json()},
                        {"raw_bytes", c.seg_raw.json()}};
  j["bvh"] = {
      {"segment meshes", c.seg_meshes.json()}, {"batching-point pieces", c.pieces.json()}, {"instance BVHs", c.inst_bvhs.json()}};
  uint32_t top_depth = 0;
  for (const fmt::TopNode& n : c.res.top) top_depth = std::max(top_depth, n.depth + 1);
  j["top_level"] = {{"nodes", c.res.top.size()}, {"max_depth", top_depth}};
  j["metadata"] = metadata_json(c.res);
  if (options.chunks) j["chunks"] = c.rows;
  j["verified"] = options.verify;
  j["problems"] = {{"count", c.problems.count()}, {"listed", c.problems.listed()}};
  InspectResult out;
  out.report = std::move(j);
  out.problems = c.problems.count();
  out.listed = c.problems.listed();
  return out;
}

}  // namespace rtp
