// The batched out-of-core tracer (Molenaar 2019 §4.1, §4.3); see out_of_core.h.
#include "core/clock.h"
#include "core/math.h"
#include "trace/out_of_core.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <limits>
#include <numeric>
#include <thread>

#include "core/error.h"
#include "formats/chunk.h"
#include "formats/dag.h"
#include "formats/top_level.h"
#include "reader/check_chunks.h"
#include "reader/check_culling.h"
#include "reader/scene_tables.h"
#include "layout/chunk_io.h"
#include "layout/dag_query.h"
#include "trace/batch_scheduler.h"
#include "trace/stream_feed.h"
#include "trace/top_level_walk.h"
#include "trace/trace.h"

namespace rtp {
namespace {

using batched::kBlock;
using batched::kNone;
using batched::RayLocks;
using batched::Visit;
std::string format_mib(uint64_t b) {
  char t[32];
  std::snprintf(t, sizeof t, "%.1f MiB", double(b) / 1048576.0);
  return t;
}

// What the tracer needs of the file beside the cache: chunk indices per batching point and segment.
struct Layout {
  std::vector<uint32_t> point_chunk;                  // TOC index of batching point p
  std::vector<std::vector<uint32_t>> point_segments;  // segment ids point p needs
  std::vector<uint32_t> segment_chunk;                // TOC index of mesh segment s (kNone: absent)
};

Layout read_layout(const PackageReader& r, const fmt::BatchingPointDesc* descs, uint64_t n_points, const uint32_t* refs,
                   const std::string& label) {
  Layout l;
  const auto& toc = r.toc();
  l.point_chunk.assign(n_points, kNone);
  for (size_t i = 0; i < toc.size(); ++i) {
    if (toc[i].kind == uint32_t(fmt::ChunkKind::kBatchingPoint) && toc[i].id < n_points && l.point_chunk[toc[i].id] == kNone)
      l.point_chunk[toc[i].id] = uint32_t(i);
    if (toc[i].kind == uint32_t(fmt::ChunkKind::kMeshSegment) && toc[i].id < toc.size()) {
      if (l.segment_chunk.size() <= toc[i].id) l.segment_chunk.resize(toc[i].id + 1, kNone);
      if (l.segment_chunk[toc[i].id] == kNone) l.segment_chunk[toc[i].id] = uint32_t(i);
    }
  }
  l.point_segments.resize(n_points);
  for (uint64_t p = 0; p < n_points; ++p) {
    if (l.point_chunk[p] == kNone) fail_invalid(label + ": batching point " + std::to_string(p) + " has no chunk");
    for (uint32_t k = 0; k < descs[p].segment_count; ++k) {
      const uint32_t s = refs[descs[p].segment_first + k];
      if (s >= l.segment_chunk.size() || l.segment_chunk[s] == kNone)
        fail_invalid(label + ": batching point " + std::to_string(p) + " needs mesh segment " + std::to_string(s) +
                     ", which the package does not hold");
      l.point_segments[p].push_back(s);
    }
  }
  return l;
}

uint64_t point_cost(const PackageReader& r, const Layout& l, uint64_t p) {
  uint64_t c = r.toc()[l.point_chunk[p]].raw_size;
  for (uint32_t s : l.point_segments[p]) c += r.toc()[l.segment_chunk[s]].raw_size;
  return c;
}

// The resident part: top level, descriptors (with segment refs and DAG grids), DAG pool.
struct Resident {
  AlignedBytes top_bytes, desc_bytes, dag_bytes;
  const fmt::TopNode* top = nullptr;
  uint64_t top_count = 0, n_points = 0;
  ResidentTables tables;  // instance and mesh tables: every geometry chunk is checked against them
  const fmt::DagGrid* grids = nullptr;
  voxel::DagView dag;
  Layout layout;
  uint64_t bytes() const { return top_bytes.size() + desc_bytes.size() + dag_bytes.size() + tables.bytes(); }
};

const AlignedBytes& must_read(const PackageReader& r, fmt::ChunkKind kind, AlignedBytes& out) {
  const int64_t i = r.find(kind, 0);
  if (i < 0) fail_invalid(std::string("missing ") + chunk_kind_name(uint32_t(kind)) + " 0");
  out = r.read(size_t(i));
  return out;
}

Resident read_resident(const PackageReader& r) {
  Resident s;
  const auto& toc = r.toc();
  const AlignedBytes& tb = must_read(r, fmt::ChunkKind::kTopLevelBvh, s.top_bytes);
  const int64_t ti = r.find(fmt::ChunkKind::kTopLevelBvh, 0);
  ChunkView tv(tb.data(), tb.size(), uint32_t(fmt::ChunkKind::kTopLevelBvh), chunk_label(toc[size_t(ti)], size_t(ti)));
  s.top = tv.get<fmt::TopNode>(fmt::SectionType::kTopNodes, s.top_count, true);
  const int64_t di = r.find(fmt::ChunkKind::kBatchingPoints, 0);
  const AlignedBytes& db = must_read(r, fmt::ChunkKind::kBatchingPoints, s.desc_bytes);
  ChunkView dv(db.data(), db.size(), uint32_t(fmt::ChunkKind::kBatchingPoints), chunk_label(toc[size_t(di)], size_t(di)));
  uint64_t n_refs = 0;
  const auto* descs = dv.get<fmt::BatchingPointDesc>(fmt::SectionType::kPointDescs, s.n_points);
  const uint32_t* refs = dv.get<uint32_t>(fmt::SectionType::kSegmentRefs, n_refs);
  check_point_descs(descs, s.n_points, n_refs, dv.label());
  check_top_level(s.top, s.top_count, s.n_points, tv.label());
  s.layout = read_layout(r, descs, s.n_points, refs, dv.label());
  uint64_t n_grids = 0;
  s.grids = dv.get<fmt::DagGrid>(fmt::SectionType::kPointGrids, n_grids, false);
  if (s.grids) {
    if (n_grids != s.n_points)
      fail_invalid(dv.label() + ": " + std::to_string(n_grids) + " culling grids for " + std::to_string(s.n_points) +
                   " batching points");
    const int64_t pi = r.find(fmt::ChunkKind::kDagPool, 0);
    if (pi < 0) fail_invalid(dv.label() + ": culling grids but no DAG pool chunk");
    const AlignedBytes& b = must_read(r, fmt::ChunkKind::kDagPool, s.dag_bytes);
    ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kDagPool), chunk_label(toc[size_t(pi)], size_t(pi)));
    s.dag.words = v.get<uint32_t>(fmt::SectionType::kDagNodes, s.dag.word_count);
    s.dag.leaves = v.get<uint64_t>(fmt::SectionType::kDagLeaves, s.dag.leaf_count);
    s.dag.cull_width = r.header().bvh_width;
    s.dag.cull = v.get_raw(fmt::SectionType::kCullNodes, fmt::cull_node_bytes(s.dag.cull_width), s.dag.cull_count, false);
    const std::string e = voxel::check_dags(s.grids, n_grids, s.dag);
    if (!e.empty()) fail_invalid(v.label() + ": culling DAG of " + e);
    check_grids_cover_points(s.grids, descs, n_grids, dv.label());
  }
  s.tables = read_resident_tables(r);
  check_resident_tables(s.tables, s.n_points);
  return s;
}

// A decoded batching point (valid while its chunk is resident) and a decoded mesh segment.
template <int W, int B>
struct PointSlot {
  PointSections<W, B> s;
  std::vector<MeshBvhView<W, B>> meshes;  // by local slot, rebuilt each round it is traced
  std::vector<AxisMove> moves;            // axis_moves of the point's records, for the view
  SceneView<W, B> view;
};
template <int W, int B>
struct SegmentSlot {
  std::vector<std::pair<uint32_t, MeshBvhView<W, B>>> meshes;  // sorted by scene mesh id
};

template <int W, int B>
class Batched final : public OutOfCoreTracer {
 public:
  Batched(const PackageReader& r, Resident res, uint64_t budget)
      : r_(r), res_(std::move(res)), cache_(r, budget), points_(res_.n_points), segments_(res_.layout.segment_chunk.size()) {}

  bool has_dags() const override { return res_.grids != nullptr; }
  void set_prefetch(bool on) override { prefetch_ = on; }
  void set_speculation(uint32_t depth) override {
    if (depth < 1 || depth > 64) throw Error(ExitCode::kUsage, "speculation depth " + std::to_string(depth) + ": must be 1..64");
    speculate_ = depth;
  }

  OutOfCoreStats closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n, const PackageTraceOptions& o) override {
    for (size_t i = 0; i < n; ++i) hits[i] = {kInf, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
    std::vector<uint32_t> best_walk(n, kNone);  // walk index of the point that gave hits[i]
    return run(
        rays, n, o, speculate_,
        [&](const SceneView<W, B>& view, const uint32_t* global_ids, const Visit* visits, const fmt::Ray* local, size_t k,
            RayLocks& locks) {
          fmt::Hit h[kBlock];
          trace_closest<W, B>(view, local, h, k, o);
          for (size_t j = 0; j < k; ++j) {
            if (!(h[j].t < kInf)) continue;
            const uint32_t i = visits[j].ray;
            // Nearer wins; at equal t the earlier point in walk order, as when the points are visited one by one.
            auto lock = locks.hold(i);
            fmt::Hit& best = hits[i];
            if (h[j].t < best.t || (h[j].t == best.t && visits[j].walk < best_walk[i])) {
              best = h[j];
              best.instance = global_ids[h[j].instance];
              best_walk[i] = visits[j].walk;
            }
          }
        },
        [&](size_t i) { return hits[i].t < kInf ? hits[i].t : rays[i].tfar; }, [](size_t) { return false; });
  }

  OutOfCoreStats any(const fmt::Ray* rays, uint8_t* occluded, size_t n, const PackageTraceOptions& o) override {
    std::fill(occluded, occluded + n, uint8_t(0));
    return run(
        rays, n, o, speculate_,
        [&](const SceneView<W, B>& view, const uint32_t*, const Visit* visits, const fmt::Ray* local, size_t k, RayLocks&) {
          uint8_t occ[kBlock];
          trace_any<W, B>(view, local, occ, k, o);
          for (size_t j = 0; j < k; ++j)
            if (occ[j]) std::atomic_ref<uint8_t>(occluded[visits[j].ray]).store(1, std::memory_order_relaxed);
        },
        [&](size_t i) { return rays[i].tfar; },
        [&](size_t i) { return std::atomic_ref<uint8_t>(occluded[i]).load(std::memory_order_relaxed) != 0; });
  }

  OutOfCoreStats multi(const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits, uint32_t* counts,
                       const PackageTraceOptions& o) override {
    check_multi_hit_count(max_hits);
    std::fill(hits, hits + n * max_hits, fmt::Hit{kInf, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0});
    std::fill(counts, counts + n, 0u);
    // One point at a time (depth 1): a ray's list is merged in walk order, its N-th hit bounding the next.
    return run(
        rays, n, o, 1,
        [&](const SceneView<W, B>& view, const uint32_t* global_ids, const Visit* visits, const fmt::Ray* local, size_t k,
            RayLocks&) {
          thread_local std::vector<fmt::Hit> point_hits, scratch;
          uint32_t c[kBlock];
          point_hits.resize(k * max_hits);
          trace_multi<W, B>(view, local, k, max_hits, point_hits.data(), c, o);
          for (size_t j = 0; j < k; ++j) {  // depth 1: a ray waits at one point at a time, its list is this task's
            const uint32_t i = visits[j].ray;
            counts[i] = merge_point_hits(hits + size_t(i) * max_hits, counts[i], max_hits, point_hits.data() + j * max_hits, c[j],
                                         global_ids, scratch);
          }
        },
        [&](size_t i) { return counts[i] == max_hits ? hits[i * max_hits + max_hits - 1].t : rays[i].tfar; },
        [](size_t) { return false; });
  }

  std::unique_ptr<RayStream> open_stream(const StreamOptions& o) override {
    return std::make_unique<batched::HostStream<W, B, Batched>>(*this, o);
  }

 private:
  // One ray's walk to its next unculled batching point (kNone: finished). `tfar` is its current one.
  uint32_t advance(const fmt::Ray& ray, float tfar, TopPosition& pos, float& tstart, bool cull, PackageTraceStats& st) const {
    if (res_.top_count == 0) return kNone;
    fmt::Ray cur = ray;
    cur.tfar = tfar;
    double inv[3];
    top_inverse(cur, inv);
    for (;;) {
      const uint32_t p = top_next(res_.top, cur, inv, pos);
      if (p == kTopNone) return kNone;
      ++st.point_visits;
      fmt::Ray local = cur;
      if (cull && res_.grids && !voxel::dag_enter(res_.grids[p], res_.dag, local)) {
        ++st.culled_visits;
        continue;
      }
      tstart = local.tnear;
      return p;
    }
  }

  template <class, class, class, class, class>
  friend class batched::Scheduler;
  template <class TraceBlock, class CurrentTfar, class Stopped>
  OutOfCoreStats run(const fmt::Ray* rays, size_t n, const PackageTraceOptions& o, uint32_t depth, TraceBlock&& trace_block,
                     CurrentTfar&& current_tfar, Stopped&& stopped) {
    if (n >= kNone) throw Error(ExitCode::kUsage, std::to_string(n) + " rays in one call: at most 2^32 - 2");
    batched::Scheduler<Batched, TraceBlock, CurrentTfar, Stopped> s(*this, rays, n, o.cull, depth, trace_block, current_tfar,
                                                                    stopped);
    return s.run();
  }

  // What the scheduler asks of the tracer (batch_scheduler.h).
  uint32_t n_points() const { return uint32_t(res_.n_points); }
  size_t toc_size() const { return r_.toc().size(); }
  uint64_t fixed_bytes() const { return res_.bytes(); }
  bool has_grids() const { return res_.grids != nullptr; }
  bool dag_enter(uint32_t p, fmt::Ray& local) const { return voxel::dag_enter(res_.grids[p], res_.dag, local); }
  uint32_t point_chunk(uint32_t p) const { return res_.layout.point_chunk[p]; }
  // The TOC indices of point p's mesh segments, in the order the point names them.
  struct SegmentChunks {
    const Layout& l;
    const std::vector<uint32_t>& segs;
    struct It {
      const Layout& l;
      std::vector<uint32_t>::const_iterator i;
      uint32_t operator*() const { return l.segment_chunk[*i]; }
      It& operator++() { return ++i, *this; }
      bool operator!=(const It& o) const { return i != o.i; }
    };
    It begin() const { return {l, segs.begin()}; }
    It end() const { return {l, segs.end()}; }
  };
  SegmentChunks point_segment_chunks(uint32_t p) const { return {res_.layout, res_.layout.point_segments[p]}; }
  ChunkCache& cache() { return cache_; }
  bool prefetch() const { return prefetch_; }
  const PointSlot<W, B>& point(uint32_t p) const { return points_[p]; }
  // Reads, checks and decodes the chunks (the cache keeps them until release()), then binds the points.
  void load(const std::vector<uint32_t>& chunks, const std::vector<uint32_t>& points) {
    cache_.acquire(chunks, [&](uint32_t index, const AlignedBytes& b) { decode(index, b); });
    for (uint32_t p : points) bind_meshes(p);
  }

  // The raw bytes loading point p would read now: its chunk and mesh segments not resident.
  uint64_t point_load_bytes(uint32_t p) const {
    uint64_t b = cache_.resident(res_.layout.point_chunk[p]) ? 0 : cache_.cost(res_.layout.point_chunk[p]);
    for (uint32_t s : res_.layout.point_segments[p])
      if (!cache_.resident(res_.layout.segment_chunk[s])) b += cache_.cost(res_.layout.segment_chunk[s]);
    return b;
  }

  // True when the point's chunk and its mesh segments are in the cache (tracing it reads nothing).
  bool point_resident(uint32_t p) const {
    if (!cache_.resident(res_.layout.point_chunk[p])) return false;
    for (uint32_t s : res_.layout.point_segments[p])
      if (!cache_.resident(res_.layout.segment_chunk[s])) return false;
    return true;
  }

  // Every chunk the cache loads passes the structural checks (check_chunks.h) before a ray reads it.
  void decode(uint32_t index, const AlignedBytes& b) {
    const fmt::TocEntry& e = r_.toc()[index];
    const std::string label = chunk_label(e, index);
    if (e.kind == uint32_t(fmt::ChunkKind::kBatchingPoint)) {
      ChunkView v(b.data(), b.size(), e.kind, label);
      const PointSections<W, B>& d = points_[e.id].s = decode_point<W, B>(v, res_.tables.view, e.id);
      if (res_.grids) check_instance_boxes<W>(res_.grids[e.id], res_.dag, d.instance_nodes, d.n_instance_nodes, label);
      return;
    }
    ChunkView v(b.data(), b.size(), e.kind, label);
    const GeometrySections<W, B> g = decode_segment<W, B>(v, res_.tables.view, e.id);
    SegmentSlot<W, B>& seg = segments_[e.id];
    seg.meshes.clear();
    for (uint64_t k = 0; k < g.n_entries; ++k) {
      const fmt::MeshEntry& m = g.entries[k];
      seg.meshes.push_back({m.id, {g.nodes + m.node_first, g.blocks + m.block_first, m.root}});
    }
    std::stable_sort(seg.meshes.begin(), seg.meshes.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  }

  // A point's mesh slots -> the views of its pieces and of the meshes in its own segments (resident now).
  void bind_meshes(uint32_t p) {
    PointSlot<W, B>& pt = points_[p];
    const PointSections<W, B>& s = pt.s;
    pt.meshes.resize(s.n_slots);
    for (uint64_t k = 0; k < s.n_slots; ++k) {
      if (s.slots[k] & fmt::kPieceBit) {
        const fmt::MeshEntry& e = s.entries[s.slots[k] & ~fmt::kPieceBit];
        pt.meshes[k] = {s.nodes + e.node_first, s.blocks + e.block_first, e.root};
        continue;
      }
      const MeshBvhView<W, B>* found = nullptr;
      for (uint32_t seg : res_.layout.point_segments[p]) {
        const auto& ms = segments_[seg].meshes;
        auto it = std::lower_bound(ms.begin(), ms.end(), s.slots[k], [](const auto& a, uint32_t id) { return a.first < id; });
        if (it != ms.end() && it->first == s.slots[k]) {
          found = &it->second;
          break;
        }
      }
      if (!found)
        fail_invalid(chunk_label(r_.toc()[res_.layout.point_chunk[p]], res_.layout.point_chunk[p]) + ": mesh slot " +
                     std::to_string(k) + ": mesh " + std::to_string(s.slots[k]) + " is in none of the point's mesh segments");
      pt.meshes[k] = *found;
    }
    pt.moves = axis_moves(s.records, s.n_records);
    pt.view = {s.instance_nodes, s.instance_bvh[0].root, s.instance_ids,
               s.records,        pt.meshes.data(),       direct_instance(s.records, s.n_records),
               pt.moves.data()};
  }

  const PackageReader& r_;
  Resident res_;
  ChunkCache cache_;
  std::vector<PointSlot<W, B>> points_;
  std::vector<SegmentSlot<W, B>> segments_;
  uint32_t speculate_ = kDefaultSpeculation;
  bool prefetch_ = false;  // measured slower on 2 cores (docs/trace/budget.md): opt in
};

}  // namespace

uint64_t on_demand_bytes(const PackageReader& reader) {
  uint64_t b = 0;
  for (const fmt::TocEntry& e : reader.toc())
    if (e.kind == uint32_t(fmt::ChunkKind::kBatchingPoint) || e.kind == uint32_t(fmt::ChunkKind::kMeshSegment)) b += e.raw_size;
  return b;
}

uint64_t minimum_budget(const PackageReader& reader) {
  const Resident res = read_resident(reader);
  uint64_t m = 0;
  for (uint64_t p = 0; p < res.n_points; ++p) m = std::max(m, point_cost(reader, res.layout, p));
  return m;
}

std::unique_ptr<OutOfCoreTracer> open_out_of_core(const PackageReader& r, uint64_t budget) {
  Resident res = read_resident(r);
  uint64_t need = 0, worst = 0;
  for (uint64_t p = 0; p < res.n_points; ++p) {
    const uint64_t c = point_cost(r, res.layout, p);
    if (c > need) need = c, worst = p;
  }
  if (budget < need)
    throw Error(ExitCode::kUsage, "memory budget " + std::to_string(budget) + " bytes is below the minimum of " +
                                      std::to_string(need) + " bytes (" + format_mib(need) + "): batching point " +
                                      std::to_string(worst) + " needs that much with its mesh segments");
  const uint32_t w = r.header().bvh_width, b = r.header().leaf_width;
  if (w == 4 && b == 4) return std::make_unique<Batched<4, 4>>(r, std::move(res), budget);
  if (w == 8 && b == 8) return std::make_unique<Batched<8, 8>>(r, std::move(res), budget);
  if (w == 16 && b == 16) return std::make_unique<Batched<16, 16>>(r, std::move(res), budget);
  if (w == 8 && b == 4) return std::make_unique<Batched<8, 4>>(r, std::move(res), budget);
  if (w == 16 && b == 8) return std::make_unique<Batched<16, 8>>(r, std::move(res), budget);
  fail_invalid("header: unsupported BVH width " + std::to_string(w) + " / leaf width " + std::to_string(b));
}

}  // namespace rtp
