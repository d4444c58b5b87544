// The converter's back end: per chunk (independent, in parallel) BVH build -> section payload ->
// zstd; in order: append to the package. Resident sections last.
#include "package/write_package.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_group.h>
#include <tbb/task_arena.h>

#include <cmath>

#include <atomic>
#include <deque>
#include <memory>

#include "core/parallel.h"
#include "formats/dag.h"
#include "layout/chunk_io.h"
#include "package/writer.h"
#include "package/write_attributes.h"
#include "voxel/instance_boxes.h"

namespace rtp {
namespace {

using fmt::ChunkKind;
using fmt::SectionType;

Box3f box_of(const Aabb& a) {
  Box3f b;
  if (a.empty()) return b;
  for (int k = 0; k < 3; ++k) {
    b.lo[k] = float_down(float(a.lo[k]));
    b.hi[k] = float_up(float(a.hi[k]));
  }
  return b;
}

// A chunk's mesh entries and, borrowed from the pieces' BVHs (which must outlive the ChunkBuilder's
// finish), their nodes and leaf blocks as one section each: gathered by finish into the chunk, not
// concatenated here first (ChunkParts::append was 4.5 % of a FlightHelmet convert in memmove).
template <int W, int B>
struct ChunkParts {
  std::vector<fmt::MeshEntry> entries;
  std::vector<const MeshBvh<W, B>*> bvhs;
  uint64_t node_count = 0, block_count = 0;
  void append(const MeshBvh<W, B>& bvh, uint32_t id, uint64_t triangles) {
    fmt::MeshEntry e{};
    e.id = id;
    e.root = bvh.root;
    e.node_first = uint32_t(node_count);
    e.node_count = uint32_t(bvh.nodes.size());
    e.block_first = uint32_t(block_count);
    e.block_count = uint32_t(bvh.blocks.size());
    e.triangles = triangles;
    node_count += bvh.nodes.size();
    block_count += bvh.blocks.size();
    entries.push_back(e);
    bvhs.push_back(&bvh);
  }
  void add_to(ChunkBuilder& cb) const {
    cb.add(SectionType::kMeshEntries, entries);
    cb.begin_section(SectionType::kNodes, sizeof(fmt::WideNode<W>));
    for (const MeshBvh<W, B>* b : bvhs) cb.append_to_section(b->nodes.data(), b->nodes.size());
    cb.begin_section(SectionType::kBlocks, sizeof(fmt::LeafBlock<B>));
    for (const MeshBvh<W, B>* b : bvhs) cb.append_to_section(b->blocks.data(), b->blocks.size());
  }
};

struct Job {
  ChunkKind kind;
  uint64_t id;
  AlignedBytes raw;  // resident chunks; a geometry chunk is sealed (compressed) at once, see seal()
  uint64_t raw_size = 0;
  AlignedBytes stored{};
  fmt::Compression comp{};
  uint64_t node_bytes = 0, block_bytes = 0, triangles = 0;
  AlignedBytes attr_raw{};  // the chunk's attribute stream (SPEC §4.4); empty when it has none
  uint64_t attr_flags = 0;
  void set_attributes(const AttributeChunkBuilder& ab, ChunkKind attr_kind) {
    if (ab.empty()) return;
    attr_raw = ab.finish(attr_kind);
    attr_flags = (ab.has_normals() ? fmt::kFlagNormals : 0) | (ab.has_uvs() ? fmt::kFlagUvs : 0);
  }
};

// Compression settings of the geometry chunks (write_t).
struct SealOptions {
  int level;
  bool raw_literals;
  int leaf_min_match;
};

// A geometry chunk laid out into a per-thread buffer and compressed from it at once (no TBB wait in
// between, so no other chunk's task can run on this thread and reuse the buffer meanwhile): the
// buffer keeps its pages chunk after chunk instead of faulting in fresh ones for each.
void seal(const ChunkBuilder& cb, const SealOptions& so, Job& job) {
  thread_local AlignedBytes raw;
  cb.finish_into(raw);
  job.raw_size = raw.size();
  // Raw literals where leaf blocks are most of the chunk: their floats are what Huffman coding barely
  // shrinks and slowly decodes.
  const bool leafy = 2 * job.block_bytes > raw.size();
  // A large chunk by zstd's own threads too (same bytes for any number of them): forest-2k's 8 MB
  // segment of its largest tree was 28 ms of one thread at the end while the other had nothing left.
  job.stored = PackageWriter::compress(raw.data(), raw.size(), so.level, job.comp, so.raw_literals && leafy,
                                       leafy ? so.leaf_min_match : 0, tbb::this_task_arena::max_concurrency());
}

// A mesh segment: several instanced meshes, each with its BVH in local space (SPEC §4.3).
template <int W, int B>
void build_segment(const Scene& scene, const MeshSegment& seg, const BuildOptions& bo, const SealOptions& so, Job& job) {
  ChunkParts<W, B> parts;
  AttributeChunkBuilder attrs;
  // Each mesh's BVH is independent of the others: built in parallel, each the same for any thread
  // count (a segment of forest-2k's 12 meshes was one thread's work while the other thread idled).
  std::vector<MeshBvh<W, B>> bvhs(seg.meshes.size());
  parallel_for_lowest_error(seg.meshes.size(),
                            [&](size_t k) { bvhs[k] = build_mesh_bvh<W, B>(scene.meshes[seg.meshes[k]], bo); });
  for (size_t k = 0; k < seg.meshes.size(); ++k) {
    const uint32_t m = seg.meshes[k];
    parts.append(bvhs[k], m, scene.meshes[m].triangle_count());
    attrs.add(m, m, scene.meshes[m], nullptr);
    job.triangles += scene.meshes[m].triangle_count();
  }
  job.set_attributes(attrs, ChunkKind::kSegmentAttributes);
  ChunkBuilder cb{uint32_t(ChunkKind::kMeshSegment)};
  parts.add_to(cb);
  job.node_bytes = parts.node_count * sizeof(fmt::WideNode<W>);
  job.block_bytes = parts.block_count * sizeof(fmt::LeafBlock<B>);
  seal(cb, so, job);
}

// A batching point: its pieces (local space) with their BVHs, its local instance table and an
// instance BVH over pieces and instances (SPEC §4.2).
// before_seal runs once the point's trees are built (and its instance-box proxy quantized), before zstd.
template <int W, int B, class BeforeSeal>
void build_point(const Scene& scene, const Plan& plan, const fmt::InstanceRecord* table, const std::vector<Box3f>& mesh_box,
                 const BatchingPoint& bp, const BuildOptions& bo, const SealOptions& so, Job& job,
                 std::vector<fmt::CullNode<W>>* cull_nodes, BeforeSeal&& before_seal) {
  ChunkParts<W, B> parts;
  AttributeChunkBuilder attrs;
  std::vector<fmt::InstanceRecord> records;
  std::vector<uint32_t> global_ids, slots;
  std::vector<Box3f> boxes;
  std::vector<MeshBvh<W, B>> bvhs(bp.pieces.size());  // independent: in parallel, as a segment's
  parallel_for_lowest_error(bp.pieces.size(), [&](size_t j) {
    const UniquePiece& piece = plan.pieces[bp.pieces[j]];
    bvhs[j] = build_mesh_bvh<W, B>(piece.mesh, bo);
    for (auto& blk : bvhs[j].blocks)  // leaves report the triangle's index in the original mesh
      for (int l = 0; l < B; ++l) blk.prim[l] = piece.prim[blk.prim[l]];
  });
  for (size_t j = 0; j < bp.pieces.size(); ++j) {
    const uint32_t k = bp.pieces[j];
    const UniquePiece& piece = plan.pieces[k];
    const uint32_t entry = uint32_t(parts.entries.size());
    parts.append(bvhs[j], k, piece.mesh.triangle_count());
    attrs.add(k, scene.instances[piece.instance].mesh, piece.mesh, &piece.prim);
    job.triangles += piece.mesh.triangle_count();
    const Instance& src = scene.instances[piece.instance];
    fmt::InstanceRecord r = table[piece.instance];  // pieces keep their mesh's local space
    r.mesh = uint32_t(slots.size());
    slots.push_back(fmt::kPieceBit | entry);
    records.push_back(r);
    global_ids.push_back(piece.instance);
    const Box3f local = box_of(piece.bounds);
    boxes.push_back(transform_bounds(src.transform, &local, 1));
  }
  std::map<uint32_t, uint32_t> mesh_slot;
  for (uint32_t i : bp.instances) {
    const Instance& in = scene.instances[i];
    auto [it, fresh] = mesh_slot.emplace(in.mesh, uint32_t(slots.size()));
    if (fresh) slots.push_back(in.mesh);
    fmt::InstanceRecord r = table[i];
    r.mesh = it->second;
    records.push_back(r);
    global_ids.push_back(i);
    boxes.push_back(transform_bounds(in.transform, &mesh_box[in.mesh], 1));
  }
  job.set_attributes(attrs, ChunkKind::kPointAttributes);
  const BoxBvh<W> top = build_box_bvh<W>(boxes, bo, "batching point instance BVH");
  // The culling proxy of an instance-heavy point (SPEC §4.5, 7.0): these nodes with 8-bit boxes (root first).
  if (cull_nodes && top.root == fmt::ChildRef::inner(0)) voxel::quantize_instance_bvh<W>(top.nodes, *cull_nodes);
  fmt::MeshEntry te{};
  te.id = 0xFFFFFFFFu;
  te.root = top.root;
  te.node_count = uint32_t(top.nodes.size());
  te.block_count = uint32_t(top.items.size());
  te.triangles = bp.unique_triangles + bp.instanced_triangles;
  const std::vector<fmt::MeshEntry> top_entry{te};
  ChunkBuilder cb{uint32_t(ChunkKind::kBatchingPoint)};
  cb.add(SectionType::kInstanceBvh, top_entry);
  cb.add(SectionType::kInstanceNodes, top.nodes);
  cb.add(SectionType::kInstanceIds, top.items);
  cb.add(SectionType::kInstances, records);
  cb.add(SectionType::kGlobalIds, global_ids);
  cb.add(SectionType::kMeshSlots, slots);
  parts.add_to(cb);
  job.node_bytes = (parts.node_count + top.nodes.size()) * sizeof(fmt::WideNode<W>);
  job.block_bytes = parts.block_count * sizeof(fmt::LeafBlock<B>);
  before_seal();
  seal(cb, so, job);
}

// Resident sections, in file order: metadata, top level, descriptors (+ culling grids), DAG pool,
// instances, meshes, source map (SPEC §4.1, §4.5), in two groups. early_resident_jobs: the five that
// need no batching point (built and compressed while the points are, e.g. a 10^6-record instance
// table), of which the first kResidentBeforePoints precede the other group in the file;
// point_resident_jobs: the two that need every point's culling grid and the finished DAG pool.
constexpr size_t kResidentBeforePoints = 2;

Job resident_job(ChunkKind kind, ChunkBuilder& cb) { return Job{kind, 0, cb.finish()}; }

// The instance table chunk (SPEC §4.1 kind 4, §2.5): per scene instance its mesh, source and where its
// record is: the batching point and local index build_point gives it (pieces first, in bp.pieces order,
// then bp.instances), a unique mesh's instance at its first piece.
AlignedBytes instance_table_chunk(const Scene& scene, const Plan& plan) {
  ChunkBuilder ic{uint32_t(ChunkKind::kInstances)};
  ic.add_reserved(SectionType::kInstanceRefs, scene.instances.size(), sizeof(fmt::InstanceRef));
  AlignedBytes raw = ic.finish();
  auto* refs = reinterpret_cast<fmt::InstanceRef*>(ChunkBuilder::section_data(raw, 0));
  tbb::parallel_for(tbb::blocked_range<size_t>(0, scene.instances.size(), 16384), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const Instance& in = scene.instances[i];
      refs[i] = {in.mesh, fmt::InstanceRef::kNoPoint, 0, in.node, in.gpu_instance};
    }
  });
  for (size_t p = 0; p < plan.points.size(); ++p) {
    const BatchingPoint& bp = plan.points[p];
    uint32_t local = 0;
    for (uint32_t k : bp.pieces) {
      fmt::InstanceRef& ref = refs[plan.pieces[k].instance];
      if (ref.point == fmt::InstanceRef::kNoPoint) ref.point = uint32_t(p), ref.local = local;
      ++local;
    }
    for (uint32_t i : bp.instances) refs[i].point = uint32_t(p), refs[i].local = local++;
  }
  return raw;
}

std::vector<Job> early_resident_jobs(const Scene& scene, const Plan& plan, const ConvertOptions& o) {
  std::vector<Job> jobs;
  auto add = [&](ChunkKind kind, ChunkBuilder& cb) { jobs.push_back(resident_job(kind, cb)); };
  nlohmann::json meta = o.metadata;
  meta["format"] = "rtpack";
  meta["bvh_width"] = o.width;
  meta["leaf_width"] = o.leaf_width;
  meta["bvh_build"] = method_name(o.bvh.method);
  meta["chunk_target"] = plan.chunk_target;
  meta["chunk_by"] = plan.chunk_by == ChunkBy::kInstanced ? "instanced" : "unique";
  meta["batching_points"] = plan.points.size();
  meta["mesh_segments"] = plan.segments.size();
  meta["pieces"] = plan.pieces.size();
  meta["dag"] = o.dag && !plan.points.empty();  // a grid per point, as write_t makes them
  nlohmann::json cams = nlohmann::json::array();
  for (const Camera& c : scene.cameras)
    cams.push_back({{"name", c.name},
                    {"type", c.type == Camera::Type::kPerspective ? "perspective" : "orthographic"},
                    {"yfov", c.yfov},
                    {"aspect_ratio", c.aspect_ratio},
                    {"xmag", c.xmag},
                    {"ymag", c.ymag},
                    {"znear", c.znear},
                    {"zfar", c.zfar},
                    {"world", c.world.m}});
  meta["cameras"] = cams;
  nlohmann::json names = nlohmann::json::array();
  for (const Mesh& m : scene.meshes) names.push_back(m.name);
  meta["mesh_names"] = names;
  const std::string text = meta.dump();
  ChunkBuilder mc{uint32_t(ChunkKind::kMetadata)};
  mc.add_raw(SectionType::kJson, text.data(), text.size(), 1);
  add(ChunkKind::kMetadata, mc);

  ChunkBuilder tc{uint32_t(ChunkKind::kTopLevelBvh)};
  tc.add(SectionType::kTopNodes, plan.top);
  add(ChunkKind::kTopLevelBvh, tc);

  jobs.push_back(Job{ChunkKind::kInstances, 0, instance_table_chunk(scene, plan)});

  std::vector<fmt::MeshInfo> infos;
  std::vector<SourcePrimitive> prims;
  std::vector<TriangleSource> tris;
  for (size_t m = 0; m < scene.meshes.size(); ++m) {
    const Mesh& mesh = scene.meshes[m];
    fmt::MeshInfo mi{};
    mi.segment = plan.mesh_segment[m];
    mi.flags = (plan.mesh_instanced[m] ? fmt::kMeshInstanced : 0u) | (mesh.normals.empty() ? 0u : fmt::kMeshNormals) |
               (mesh.uvs.empty() ? 0u : fmt::kMeshUvs);
    mi.triangles = mesh.triangle_count();
    mi.source_prim_first = uint32_t(prims.size());
    mi.source_prim_count = uint32_t(mesh.primitives.size());
    mi.source_tri_first = tris.size();
    prims.insert(prims.end(), mesh.primitives.begin(), mesh.primitives.end());
    tris.insert(tris.end(), mesh.source.begin(), mesh.source.end());
    infos.push_back(mi);
  }
  ChunkBuilder meshc{uint32_t(ChunkKind::kMeshes)};
  meshc.add(SectionType::kMeshTable, infos);
  add(ChunkKind::kMeshes, meshc);
  static_assert(sizeof(SourcePrimitive) == 8 && sizeof(TriangleSource) == 8);
  ChunkBuilder sc{uint32_t(ChunkKind::kSourceMap)};
  sc.add(SectionType::kSourcePrims, prims);
  sc.add(SectionType::kSourceTris, tris);
  add(ChunkKind::kSourceMap, sc);
  return jobs;
}

// The descriptors (+ culling grids) and the DAG pool. `grids` is empty without DAGs.
template <int W>
std::vector<Job> point_resident_jobs(const Scene& scene, const Plan& plan, const std::vector<fmt::DagGrid>& grids,
                                     const voxel::DagPool& pool, const std::vector<fmt::CullNode<W>>& cull_nodes) {
  std::vector<Job> jobs;
  auto add = [&](ChunkKind kind, ChunkBuilder& cb) { jobs.push_back(resident_job(kind, cb)); };
  std::vector<fmt::BatchingPointDesc> descs;
  std::vector<uint32_t> seg_refs;
  for (size_t p = 0; p < plan.points.size(); ++p) {
    const BatchingPoint& bp = plan.points[p];
    fmt::BatchingPointDesc d{};
    const Box3f b = box_of(bp.bounds);
    for (int k = 0; k < 3; ++k) d.lo[k] = b.lo[k], d.hi[k] = b.hi[k];
    d.unique_triangles = bp.unique_triangles;
    d.instanced_triangles = bp.instanced_triangles;
    d.instance_count = uint32_t(bp.instances.size());
    d.piece_count = uint32_t(bp.pieces.size());
    std::vector<uint32_t> segs;
    for (uint32_t i : bp.instances) segs.push_back(plan.mesh_segment[scene.instances[i].mesh]);
    std::sort(segs.begin(), segs.end());
    segs.erase(std::unique(segs.begin(), segs.end()), segs.end());
    d.segment_first = uint32_t(seg_refs.size());
    d.segment_count = uint32_t(segs.size());
    seg_refs.insert(seg_refs.end(), segs.begin(), segs.end());
    d.chunk_id = uint32_t(p);
    descs.push_back(d);
  }
  ChunkBuilder dc{uint32_t(ChunkKind::kBatchingPoints)};
  dc.add(SectionType::kPointDescs, descs);
  dc.add(SectionType::kSegmentRefs, seg_refs);
  if (!grids.empty()) dc.add(SectionType::kPointGrids, grids);
  add(ChunkKind::kBatchingPoints, dc);
  if (!grids.empty()) {
    ChunkBuilder pc{uint32_t(ChunkKind::kDagPool)};
    pc.add(SectionType::kDagNodes, pool.words());
    pc.add(SectionType::kDagLeaves, pool.leaves());
    if (!cull_nodes.empty()) pc.add(SectionType::kCullNodes, cull_nodes);
    add(ChunkKind::kDagPool, pc);
  }
  return jobs;
}

// Resident jobs compressed, ready to append (PackageWriter::compress is thread-safe). workers > 0:
// large ones by zstd's own threads (see compress), for the late jobs that nothing else runs beside:
// forest-1m's 27 MB DAG pool was 0.1 s of one thread while the other idled.
// The source map (per triangle its glTF primitive and index: runs of consecutive integers) at level 3
// when levels 1 and 2 are asked for: zstd's dfast matches whole runs, both faster and smaller there
// (FlightHelmet's map 16.6x at 536 MB/s against 7.5x at 284; docs/notes/2026-12-07-writer-measurements.md §4).
int resident_level(ChunkKind kind, int level) { return kind == ChunkKind::kSourceMap && (level == 1 || level == 2) ? 3 : level; }

std::vector<Job> compress_all(std::vector<Job> jobs, int level, int workers = 0) {
  tbb::parallel_for(size_t(0), jobs.size(), [&](size_t i) {
    Job& j = jobs[i];
    const AlignedBytes& raw = j.raw;
    j.raw_size = raw.size();
    j.stored = PackageWriter::compress(raw.data(), raw.size(), resident_level(j.kind, level), j.comp, false, 0, workers);
    j.raw = AlignedBytes();
  });
  return jobs;
}

template <int W, int B>
ConvertReport write_t(const Scene& scene, const Plan& plan, const std::string& path, const ConvertOptions& o) {
  PackageWriter writer(path, o.zstd_level);
  ConvertReport rep;
  std::vector<Box3f> mesh_box(scene.meshes.size());  // once per mesh, not per instance
  for (size_t m = 0; m < scene.meshes.size(); ++m) mesh_box[m] = box_of(plan.mesh_bounds[m]);
  const uint64_t n_seg = plan.segments.size(), n_pts = plan.points.size();
  // Progress in work units, not chunks: a chunk weighs its triangles, instances and 1, so a few large
  // chunks at the end do not hold the bar at 99 %. Resident chunks weigh 1 each.
  auto work_of = [&](ChunkKind kind, uint64_t id) -> uint64_t {
    if (kind == ChunkKind::kMeshSegment) return plan.segments[id].triangles + 1;
    if (kind == ChunkKind::kBatchingPoint) return plan.points[id].unique_triangles + plan.points[id].instances.size() + 1;
    return 1;
  };
  uint64_t total = 6 + (o.dag ? 1 : 0);
  for (uint64_t k = 0; k < n_seg; ++k) total += work_of(ChunkKind::kMeshSegment, k);
  for (uint64_t k = 0; k < n_pts; ++k) total += work_of(ChunkKind::kBatchingPoint, k);
  uint64_t next = 0, written = 0;
  // Culling proxies (Molenaar 2019 §4.2): voxelized beside each point's zstd (ProxySlot below), joined to
  // the one shared pool in point order (deterministic bytes) by the serial stage or after the pipeline.
  std::unique_ptr<voxel::MeshProxies> mesh_proxies;
  if (o.dag) mesh_proxies = std::make_unique<voxel::MeshProxies>(scene, plan);
  std::vector<fmt::DagGrid> grids(o.dag ? n_pts : 0);
  voxel::DagPool pool;
  std::vector<fmt::CullNode<W>> cull_nodes;  // the instance-box proxies' nodes, point after point
  // Instance boxes instead of voxels (SPEC §4.5, 7.0) for points of instances only, at least this many:
  // there each instance spans a few cells of the point's grid, and its box culls more than its voxels
  // (forest-1m: 55.6 % of random-ray visits culled against 41.1 %; docs/notes/2026-12-07-writer-measurements.md
  // §5). An explicit --dag-resolution keeps voxels everywhere.
  auto box_proxy = [&](const BatchingPoint& bp) {
    return o.dag && o.voxel.resolution == 0 && bp.pieces.empty() && bp.instances.size() >= kBoxProxyMinInstances;
  };
  // Every instance's record, computed once (in parallel: 10^6 records one by one were 5 % of a forest-1m
  // convert's samples), copied by the batching points and the culling proxies; not stored as such.
  std::unique_ptr<fmt::InstanceRecord[]> record_buf(new fmt::InstanceRecord[scene.instances.size()]);
  make_instance_records(scene.instances, record_buf.get());
  const fmt::InstanceRecord* records = record_buf.get();
  // The resident chunks that need no batching point are built and compressed beside the pipeline.
  std::vector<Job> early;
  tbb::task_group beside;
  beside.run([&] { early = compress_all(early_resident_jobs(scene, plan, o), o.zstd_level); });
  std::atomic<int64_t> voxel_ns{0};
  // A batching point's culling proxy: voxelized beside the point's zstd, once its trees are built (not
  // beside the trees: a thread that stole the voxels of a large point then left its tree to one thread),
  // and joined to the pool in point order after the geometry is written, so the geometry reaches the
  // disk while the voxels are made (FlightHelmet at 2 threads: its 2.8 MB point was written last and
  // the final fsync waited 6-9 ms for it).
  struct ProxySlot {
    // Isolated: the task outlives the pipeline's filter (and its context) that starts it.
    tbb::task_group_context context{tbb::task_group_context::isolated};
    std::atomic<bool> ready{false};
    voxel::PointProxy proxy;  // written by the task
    bool boxes = false;       // proxy unused: cull holds the point's instance BVH
    std::vector<fmt::CullNode<W>> cull;
    tbb::task_group voxelizing{context};
    // On an error (the pipeline unwinding) the task may still run: it must end before `proxy` goes (an
    // ASan run caught a convert refused for its zstd minimum match whose task wrote into a destroyed
    // proxy). Its own error is moot then: the first one is on its way out.
    ~ProxySlot() {
      try {
        voxelizing.wait();
      } catch (...) {}
    }
  };
  // Declared after everything the voxelizing tasks read: on an error, each slot waits for its task as
  // the slots are destroyed, before those go.
  std::vector<std::unique_ptr<ProxySlot>> slots(o.dag ? n_pts : 0);
  struct Packed {
    Job job;
    AlignedBytes attr_stored;
    fmt::Compression attr_comp;
  };
  const SealOptions seal_opt{o.zstd_level, o.zstd_raw_literals, o.zstd_leaf_min_match};
  uint64_t header_flags = 0;
  auto record = [&](const Job& job, const fmt::TocEntry& e) {
    SectionBytes& s = rep.by_kind[chunk_kind_name(e.kind)];
    ++s.chunks;
    s.raw += e.raw_size;
    s.stored += e.stored_size;
    rep.node_bytes += job.node_bytes;
    rep.block_bytes += job.block_bytes;
    rep.unique_triangles += job.triangles;
    ++rep.chunks;
    written += work_of(ChunkKind(e.kind), job.id);
    if (o.progress) o.progress(std::min(written, total), total);
  };
  // The proxies of the points written so far join the pool in point order (deterministic bytes): those
  // ready while the pipeline runs, then (all) the rest after it.
  std::deque<uint64_t> pending;
  auto join_proxies = [&](bool all) {
    while (!pending.empty() && (all || slots[pending.front()]->ready.load(std::memory_order_acquire))) {
      const uint64_t id = pending.front();
      pending.pop_front();
      ProxySlot& s = *slots[id];
      s.voxelizing.wait();  // rethrows the voxelization's error
      if (s.boxes) {
        fmt::DagGrid g{};
        g.resolution = fmt::kDagBoxes;
        g.root = uint32_t(cull_nodes.size());
        cull_nodes.insert(cull_nodes.end(), s.cull.begin(), s.cull.end());
        grids[id] = g;
        rep.box_node_bytes += s.cull.size() * sizeof(fmt::CullNode<W>);
        ++rep.box_points;
      } else {
        fmt::DagGrid g = s.proxy.grid;
        g.root = pool.add(s.proxy.dag);
        grids[id] = g;
        rep.dag_separate_bytes += s.proxy.dag.bytes();
        rep.dag_set_cells += s.proxy.set_cells;
        ++rep.dag_resolutions[g.resolution];
      }
      slots[id].reset();
    }
  };
  // Ordered pipeline: ids in order -> build + compress in parallel -> append in order.
  const size_t tokens = 2 * size_t(tbb::this_task_arena::max_concurrency());
  tbb::parallel_pipeline(
      tokens, tbb::make_filter<void, uint64_t>(tbb::filter_mode::serial_in_order, [&](tbb::flow_control& fc) -> uint64_t {
                if (next == n_seg + n_pts) {
                  fc.stop();
                  return 0;
                }
                return next++;
              }) & tbb::make_filter<uint64_t, Packed>(tbb::filter_mode::parallel, [&](uint64_t k) {
                Packed p;
                if (k < n_seg) {
                  p.job = {ChunkKind::kMeshSegment, k, {}};
                  build_segment<W, B>(scene, plan.segments[k], o.bvh, seal_opt, p.job);
                } else {
                  const uint64_t id = k - n_seg;
                  p.job = {ChunkKind::kBatchingPoint, id, {}};
                  const BatchingPoint& bp = plan.points[id];
                  ProxySlot* slot = nullptr;
                  if (o.dag) {
                    slots[id] = std::make_unique<ProxySlot>();
                    slot = slots[id].get();
                    slot->boxes = box_proxy(bp);
                  }
                  auto before_seal = [&] {
                    if (!slot) return;
                    if (slot->boxes && !slot->cull.empty()) {
                      slot->ready.store(true, std::memory_order_release);
                      return;
                    }
                    slot->boxes = false;                  // root not a node: voxels after all
                    slot->voxelizing.run([&, slot, id] {  // runs past this filter: no local by reference
                      try {
                        slot->proxy = voxel::voxelize_point(scene, plan, *mesh_proxies, records, plan.points[id], o.voxel);
                      } catch (...) {  // ready too: the serial stage's wait rethrows at once
                        slot->ready.store(true, std::memory_order_release);
                        throw;
                      }
                      voxel_ns += int64_t(slot->proxy.work_seconds * 1e9);
                      slot->ready.store(true, std::memory_order_release);
                    });
                  };
                  build_point<W, B>(scene, plan, records, mesh_box, bp, o.bvh, seal_opt, p.job,
                                    slot && slot->boxes ? &slot->cull : nullptr, before_seal);
                }
                if (!p.job.attr_raw.empty())
                  p.attr_stored =
                      PackageWriter::compress(p.job.attr_raw.data(), p.job.attr_raw.size(), o.zstd_level, p.attr_comp);
                return p;
              }) & tbb::make_filter<Packed, void>(tbb::filter_mode::serial_in_order, [&](Packed p) {
                const fmt::TocEntry& e = writer.add_packed(p.job.kind, p.job.id, p.job.stored, p.job.comp, p.job.raw_size);
                record(p.job, e);
                if (!p.job.attr_raw.empty()) {  // right after its geometry: one sequential read for both
                  const ChunkKind ak =
                      p.job.kind == ChunkKind::kMeshSegment ? ChunkKind::kSegmentAttributes : ChunkKind::kPointAttributes;
                  const fmt::TocEntry& ae = writer.add_packed(ak, p.job.id, p.attr_stored, p.attr_comp, p.job.attr_raw.size());
                  SectionBytes& s = rep.by_kind[chunk_kind_name(ae.kind)];
                  ++s.chunks;
                  s.raw += ae.raw_size;
                  s.stored += ae.stored_size;
                  ++rep.chunks;
                  header_flags |= p.job.attr_flags;
                }
                if (o.dag && p.job.kind == ChunkKind::kBatchingPoint) {
                  pending.push_back(p.job.id);
                  join_proxies(false);
                }
              }));
  join_proxies(true);
  rep.dag_pool_bytes = pool.bytes();
  rep.voxelize_seconds = double(voxel_ns.load()) * 1e-9;
  if (o.dag && n_pts > 0) header_flags |= fmt::kFlagDag;  // no point, no grid and no pool (metadata "dag" alike)
  beside.wait();
  record_buf.reset();  // no batching point reads the records any more: 112 MB back before the late stage
  std::vector<Job> late = compress_all(point_resident_jobs<W>(scene, plan, grids, pool, cull_nodes), o.zstd_level,
                                       tbb::this_task_arena::max_concurrency());
  std::vector<Job*> order;  // file order (SPEC §4.1): metadata, top level, descriptors, DAG pool, the rest
  for (size_t i = 0; i < kResidentBeforePoints; ++i) order.push_back(&early[i]);
  for (Job& j : late) order.push_back(&j);
  for (size_t i = kResidentBeforePoints; i < early.size(); ++i) order.push_back(&early[i]);
  for (Job* j : order) record(*j, writer.add_packed(j->kind, j->id, j->stored, j->comp, j->raw_size));
  fmt::Header h{};
  h.flags = header_flags;
  h.unique_triangles = scene.unique_triangles();
  h.instanced_triangles = scene.instanced_triangles();
  const Box3f b = box_of(scene.bounds);
  for (int k = 0; k < 3; ++k) h.bounds_lo[k] = b.lo[k], h.bounds_hi[k] = b.hi[k];
  h.bvh_width = uint32_t(W);
  h.leaf_width = uint32_t(B);
  writer.finish(h);
  rep.package_bytes = writer.bytes_written();
  return rep;
}

}  // namespace

bool supported_widths(int w, int b) {
  return (w == 4 && b == 4) || (w == 8 && b == 8) || (w == 16 && b == 16) || (w == 8 && b == 4) || (w == 16 && b == 8);
}

ConvertReport write_package(const Scene& scene, const Plan& plan, const std::string& path, const ConvertOptions& o) {
  if (o.width == 4 && o.leaf_width == 4) return write_t<4, 4>(scene, plan, path, o);
  if (o.width == 8 && o.leaf_width == 8) return write_t<8, 8>(scene, plan, path, o);
  if (o.width == 16 && o.leaf_width == 16) return write_t<16, 16>(scene, plan, path, o);
  if (o.width == 8 && o.leaf_width == 4) return write_t<8, 4>(scene, plan, path, o);
  if (o.width == 16 && o.leaf_width == 8) return write_t<16, 8>(scene, plan, path, o);
  throw Error(ExitCode::kUsage, "--bvh-width " + std::to_string(o.width) + " with leaf width " + std::to_string(o.leaf_width) +
                                    ": unsupported (use 4/4, 8/8, 16/16, 8/4 or 16/8)");
}

}  // namespace rtp
