// In-core package tracing: chunk views -> per batching point SceneView; top level traversed front to
// back in double precision (Molenaar 2019 §4.1 top-level BVH over batching points).
#include "core/clock.h"
#include "core/math.h"
#include "trace/package_tracer.h"

#include <xmmintrin.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <utility>
#include <vector>

#include "core/error.h"
#include "formats/chunk.h"
#include "formats/dag.h"
#include "formats/top_level.h"
#include "reader/check_chunks.h"
#include "reader/check_culling.h"
#include "reader/scene_tables.h"
#include "layout/chunk_io.h"
#include "layout/dag_query.h"
#include "trace/top_level_walk.h"

namespace rtp {

bool ray_is_valid(const fmt::Ray& r) {
  for (int k = 0; k < 3; ++k)
    if (!std::isfinite(r.org[k]) || !std::isfinite(r.dir[k])) return false;
  if (std::isnan(r.tnear) || std::isnan(r.tfar) || r.tnear > r.tfar || r.tnear == std::numeric_limits<float>::infinity())
    return false;
  return true;
}

namespace {

template <int W, int B>
struct Point {
  SceneView<W, B> view;
  std::vector<MeshBvhView<W, B>> meshes;  // by local slot
  std::vector<AxisMove> moves;            // axis_moves of the point's records, for the view
  const uint32_t* global_ids = nullptr;
  uint64_t instance_count = 0;
};

template <int W, int B>
class InCoreTracer final : public PackageTracer {
 public:
  explicit InCoreTracer(const PackageReader& r) {
    const auto t_start = Clock::now();
    const auto& toc = r.toc();
    auto load = [&](fmt::ChunkKind kind, uint64_t id) -> const AlignedBytes& {
      const int64_t i = r.find(kind, id);
      if (i < 0) fail_invalid(std::string("missing ") + chunk_kind_name(uint32_t(kind)) + " " + std::to_string(id));
      const auto t0 = Clock::now();
      chunks_.push_back(r.read(size_t(i)));
      load_.read_seconds += seconds_since(t0);
      ++load_.chunks;
      load_.raw_bytes += chunks_.back().size();
      load_.stored_bytes += toc[size_t(i)].stored_size;
      labels_.push_back(chunk_label(toc[size_t(i)], size_t(i)));
      return chunks_.back();
    };
    // The structural checks, timed apart from the reads (they are always on: the load cost is printed).
    auto checked = [&](auto&& f) {
      const auto t0 = Clock::now();
      auto out = f();
      load_.check_seconds += seconds_since(t0);
      return out;
    };
    chunks_.reserve(toc.size());
    {
      const AlignedBytes& b = load(fmt::ChunkKind::kTopLevelBvh, 0);
      ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kTopLevelBvh), labels_.back());
      top_ = v.get<fmt::TopNode>(fmt::SectionType::kTopNodes, top_count_, true);
    }
    uint64_t n_points = 0, n_refs = 0;
    const fmt::BatchingPointDesc* descs;
    const AlignedBytes& db = load(fmt::ChunkKind::kBatchingPoints, 0);
    ChunkView dv(db.data(), db.size(), uint32_t(fmt::ChunkKind::kBatchingPoints), labels_.back());
    descs = dv.get<fmt::BatchingPointDesc>(fmt::SectionType::kPointDescs, n_points);
    dv.get<uint32_t>(fmt::SectionType::kSegmentRefs, n_refs);
    checked([&] {
      check_point_descs(descs, n_points, n_refs, dv.label());
      check_top_level(top_, top_count_, n_points, labels_[0]);
      return 0;
    });
    load_dags(r, dv, n_points, load, checked);
    // Every geometry chunk is checked against the instance and mesh tables (hits report scene instance ids).
    {
      const auto t0 = Clock::now();
      tables_ = read_resident_tables(r);
      load_.read_seconds += seconds_since(t0);
      for (fmt::ChunkKind k : {fmt::ChunkKind::kInstances, fmt::ChunkKind::kMeshes}) {
        ++load_.chunks;
        load_.stored_bytes += toc[size_t(r.find(k, 0))].stored_size;
      }
      load_.raw_bytes += tables_.bytes();
    }
    checked([&] {
      check_resident_tables(tables_, n_points);
      return 0;
    });
    // Segments: mesh id -> view.
    std::map<uint32_t, MeshBvhView<W, B>> segment_meshes;
    for (size_t i = 0; i < toc.size(); ++i) {
      if (toc[i].kind != uint32_t(fmt::ChunkKind::kMeshSegment)) continue;
      const AlignedBytes& b = load(fmt::ChunkKind::kMeshSegment, toc[i].id);
      ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kMeshSegment), labels_.back());
      const GeometrySections<W, B> g = checked([&] { return decode_segment<W, B>(v, tables_.view, toc[i].id); });
      for (uint64_t k = 0; k < g.n_entries; ++k) {
        const fmt::MeshEntry& e = g.entries[k];
        segment_meshes[e.id] = {g.nodes + e.node_first, g.blocks + e.block_first, e.root};
      }
    }
    points_.resize(n_points);
    for (uint64_t p = 0; p < n_points; ++p) {
      const AlignedBytes& b = load(fmt::ChunkKind::kBatchingPoint, descs[p].chunk_id);
      const std::string& label = labels_.back();
      ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kBatchingPoint), label);
      Point<W, B>& pt = points_[p];
      const PointSections<W, B> s = checked([&] {
        const PointSections<W, B> d = decode_point<W, B>(v, tables_.view, p);
        if (grids_) check_instance_boxes<W>(grids_[p], dag_, d.instance_nodes, d.n_instance_nodes, label);
        return d;
      });
      pt.global_ids = s.global_ids;
      pt.meshes.resize(s.n_slots);
      for (uint64_t k = 0; k < s.n_slots; ++k) {
        if (s.slots[k] & fmt::kPieceBit) {
          const fmt::MeshEntry& e = s.entries[s.slots[k] & ~fmt::kPieceBit];
          pt.meshes[k] = {s.nodes + e.node_first, s.blocks + e.block_first, e.root};
        } else {
          auto it = segment_meshes.find(s.slots[k]);
          if (it == segment_meshes.end())
            fail_invalid(label + ": mesh slot " + std::to_string(k) + ": mesh " + std::to_string(s.slots[k]) +
                         " is in no segment");
          pt.meshes[k] = it->second;
        }
      }
      pt.moves = axis_moves(s.records, s.n_records);
      pt.view = {s.instance_nodes, s.instance_bvh[0].root, s.instance_ids,
                 s.records,        pt.meshes.data(),       direct_instance(s.records, s.n_records),
                 pt.moves.data()};
      pt.instance_count = s.n_records;
    }
    load_.total_seconds = seconds_since(t_start);
  }

  PackageLoadStats load_stats() const override { return load_; }

  uint64_t batching_points() const override { return points_.size(); }
  bool has_dags() const override { return grids_ != nullptr; }

  fmt::Hit trace_point(size_t p, const fmt::Ray& ray, const TraceOptions& o) const override {
    fmt::Hit h{kInf, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0};
    if (p >= points_.size() || !ray_is_valid(ray)) return h;
    trace_closest<W, B>(points_[p].view, &ray, &h, 1, o);
    if (h.t < kInf) h.instance = points_[p].global_ids[h.instance];
    return h;
  }

  voxel::DagHit test_point_dag(size_t p, const fmt::Ray& ray) const override {
    if (!grids_ || p >= points_.size()) return {false, double(ray.tnear)};
    const double org[3] = {ray.org[0], ray.org[1], ray.org[2]}, dir[3] = {ray.dir[0], ray.dir[1], ray.dir[2]};
    return voxel::dag_first_entry(grids_[p], dag_, org, dir, ray.tnear, ray.tfar);
  }

  PackageTraceStats closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n, const PackageTraceOptions& o) const override {
    std::fill(hits, hits + n, fmt::Hit{kInf, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0});
    if (o.packet && packet_size_ok(o.packet) && o.isa != Isa::kScalar) return closest_packets(rays, hits, n, o);
    return closest_single(rays, hits, n, o);
  }

  PackageTraceStats any(const fmt::Ray* rays, uint8_t* occluded, size_t n, const PackageTraceOptions& o) const override {
    std::fill(occluded, occluded + n, uint8_t(0));
    return each_ray(rays, n, o, [&](size_t i, const Point<W, B>& pt, const fmt::Ray& local, fmt::Ray&) {
      trace_any<W, B>(pt.view, &local, occluded + i, 1, o);
      return occluded[i] != 0;
    });
  }

  PackageTraceStats multi(const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits, uint32_t* counts,
                          const PackageTraceOptions& o) const override {
    check_multi_hit_count(max_hits);
    std::fill(hits, hits + n * max_hits, fmt::Hit{kInf, fmt::Hit::kNone, fmt::Hit::kNone, 0, 0});
    std::fill(counts, counts + n, 0u);
    std::vector<fmt::Hit> point_hits(max_hits), scratch;
    return each_ray(rays, n, o, [&](size_t i, const Point<W, B>& pt, const fmt::Ray& local, fmt::Ray& ray) {
      uint32_t c = 0;
      trace_multi<W, B>(pt.view, &local, 1, max_hits, point_hits.data(), &c, o);
      fmt::Hit* out = hits + i * max_hits;
      counts[i] = merge_point_hits(out, counts[i], max_hits, point_hits.data(), c, pt.global_ids, scratch);
      if (counts[i] == max_hits) ray.tfar = out[max_hits - 1].t;  // later points must beat the N-th hit
      return false;
    });
  }

 private:
  // The DAG pool and per-point grids (SPEC §4.5), when the package has them; every grid's DAG passes
  // voxel::check_dag() before any ray reads it.
  template <class Load, class Checked>
  void load_dags(const PackageReader& r, const ChunkView& dv, uint64_t n_points, Load&& load, Checked&& checked) {
    uint64_t n_grids = 0;
    grids_ = dv.get<fmt::DagGrid>(fmt::SectionType::kPointGrids, n_grids, false);
    if (!grids_) return;
    const std::string& desc_label = dv.label();
    if (n_grids != n_points)
      fail_invalid(desc_label + ": " + std::to_string(n_grids) + " culling grids for " + std::to_string(n_points) +
                   " batching points");
    if (r.find(fmt::ChunkKind::kDagPool, 0) < 0) fail_invalid(desc_label + ": culling grids but no DAG pool chunk");
    const AlignedBytes& b = load(fmt::ChunkKind::kDagPool, 0);
    ChunkView v(b.data(), b.size(), uint32_t(fmt::ChunkKind::kDagPool), labels_.back());
    dag_.words = v.get<uint32_t>(fmt::SectionType::kDagNodes, dag_.word_count);
    dag_.leaves = v.get<uint64_t>(fmt::SectionType::kDagLeaves, dag_.leaf_count);
    dag_.cull = v.get<fmt::CullNode<W>>(fmt::SectionType::kCullNodes, dag_.cull_count, false);
    dag_.cull_width = uint32_t(W);
    const std::string e = checked([&] { return voxel::check_dags(grids_, n_grids, dag_); });
    if (!e.empty()) fail_invalid(labels_.back() + ": culling DAG of " + e);
    uint64_t n_descs = 0;
    const auto* descs = dv.get<fmt::BatchingPointDesc>(fmt::SectionType::kPointDescs, n_descs);
    checked([&] {
      check_grids_cover_points(grids_, descs, n_grids, desc_label);
      return 0;
    });
  }

  // Molenaar 2019 §4.2: before a batching point's BVH is walked, its DAG is tested along the ray's
  // interval; false = culled. Otherwise the walk starts at the first set cell's entry distance
  // (rounded down to float; no hit of the point's geometry lies before it).
  bool enter(size_t p, fmt::Ray& ray, const PackageTraceOptions& o, PackageTraceStats& st) const {
    ++st.point_visits;
    if (!o.cull || !grids_) return true;
    if (voxel::dag_enter(grids_[p], dag_, ray)) return true;
    ++st.culled_visits;
    return false;
  }

  PackageTraceStats closest_single(const fmt::Ray* rays, fmt::Hit* hits, size_t n, const PackageTraceOptions& o) const {
    PackageTraceOptions one = o;
    one.packet = 0;
    return each_ray(rays, n, one, [&](size_t i, const Point<W, B>& pt, const fmt::Ray& local, fmt::Ray& ray) {
      fmt::Hit h;
      trace_closest<W, B>(pt.view, &local, &h, 1, one);
      if (h.t < hits[i].t) {
        hits[i] = h;
        hits[i].instance = pt.global_ids[h.instance];
        ray.tfar = h.t;  // later batching points only need to beat this hit
      }
      return false;
    });
  }

  // Wu 2016 §3.4.1 packets through the package: each valid ray of a run of P consecutive rays lists the
  // batching points it enters front to back (traverse()); the lists are merged into one order in which
  // every ray still meets its own points in its own order (merge_visits), and at each point of it the rays
  // that list it and still enter it (its entry within their closest hit so far, not culled by its DAG) are
  // traced as one packet (trace.h). The answers are closest_single's bit for bit: each ray meets the same
  // points in the same order with the same tfar, and a packet's hits equal single rays'. A run whose
  // lists cannot be merged (two rays meet two points in opposite orders) goes ray by ray.
  PackageTraceStats closest_packets(const fmt::Ray* rays, fmt::Hit* hits, size_t n, const PackageTraceOptions& o) const {
    const size_t P = o.packet;
    PackageTraceStats st;
    st.rays = n;
    thread_local Visits v;
    v.pending.resize(std::max(v.pending.size(), points_.size()), 0);
    for (size_t base = 0; base < n; base += P) {
      const size_t count = std::min(P, n - base);
      uint32_t valid = 0;
      for (size_t i = 0; i < count; ++i) {
        v.seq[i].clear();
        if (!ray_is_valid(rays[base + i])) continue;
        valid |= 1u << i;
        traverse(rays[base + i], [&](const Point<W, B>&, size_t p, double t) {
          v.seq[i].push_back({uint32_t(p), t});
          return false;
        });
      }
      if (__builtin_popcount(valid) < 2 || !merge_visits(v, valid)) {
        add_stats(st, closest_single(rays + base, hits + base, count, o));
        continue;
      }
      st.invalid_rays += count - size_t(__builtin_popcount(valid));
      fmt::Ray ray[kMaxPacket], local[kMaxPacket];
      size_t cur[kMaxPacket] = {};
      for (size_t i = 0; i < count; ++i) ray[i] = rays[base + i];
      for (const uint32_t p : v.order) {
        uint32_t lane[kMaxPacket];
        size_t m = 0;
        for (uint32_t bits = valid; bits; bits &= bits - 1) {
          const uint32_t i = uint32_t(__builtin_ctz(bits));
          if (cur[i] == v.seq[i].size() || v.seq[i][cur[i]].first != p) continue;  // not one of its points
          if (v.seq[i][cur[i]++].second > double(ray[i].tfar)) continue;           // beyond its closest hit so far
          local[m] = ray[i];
          if (enter(p, local[m], o, st)) lane[m++] = i;
        }
        if (m == 0) continue;
        fmt::Hit h[kMaxPacket];
        const TraceStats ts = trace_closest<W, B>(points_[p].view, local, h, m, o);
        st.packets += ts.packets, st.packet_rays += ts.packet_rays, st.packet_node_tests += ts.packet_node_tests;
        st.packet_active_lanes += ts.packet_active_lanes, st.packet_single_walks += ts.packet_single_walks;
        st.packet_triangle_tests += ts.packet_triangle_tests;
        for (size_t j = 0; j < m; ++j) {
          fmt::Hit& out = hits[base + lane[j]];
          if (h[j].t < out.t) {
            out = h[j];
            out.instance = points_[p].global_ids[h[j].instance];
            ray[lane[j]].tfar = h[j].t;
          }
        }
      }
    }
    return st;
  }

  static constexpr size_t kMaxPacket = 16;
  // Per thread: each lane's batching points with entry distances, their merged order, and per point how
  // many lanes still have it ahead (all zero between runs).
  struct Visits {
    std::vector<std::pair<uint32_t, double>> seq[kMaxPacket];
    std::vector<uint32_t> order;
    std::vector<uint8_t> pending;
  };

  // v.order := the points of the lanes in `valid`, each once, in an order that keeps every lane's own order:
  // repeatedly the nearest lane head that no lane has further ahead (a point is in a lane's list at most
  // once: a top-level leaf has one parent). False when no head qualifies: the lists order two points
  // both ways.
  static bool merge_visits(Visits& v, uint32_t valid) {
    size_t cur[kMaxPacket] = {};
    v.order.clear();
    for (uint32_t bits = valid; bits; bits &= bits - 1)
      for (const auto& e : v.seq[__builtin_ctz(bits)]) ++v.pending[e.first];
    for (;;) {
      int best = -1;
      double best_t = 0;
      bool left = false;
      for (uint32_t bits = valid; bits; bits &= bits - 1) {
        const uint32_t i = uint32_t(__builtin_ctz(bits));
        if (cur[i] == v.seq[i].size()) continue;
        left = true;
        const auto& head = v.seq[i][cur[i]];
        if (best >= 0 && head.second >= best_t) continue;
        unsigned heads = 0;
        for (uint32_t b2 = valid; b2; b2 &= b2 - 1) {
          const uint32_t j = uint32_t(__builtin_ctz(b2));
          heads += cur[j] < v.seq[j].size() && v.seq[j][cur[j]].first == head.first;
        }
        if (v.pending[head.first] == heads) best = int(head.first), best_t = head.second;
      }
      if (!left) return true;
      if (best < 0) {  // a cycle: clear what is still pending
        for (uint32_t bits = valid; bits; bits &= bits - 1) {
          const uint32_t i = uint32_t(__builtin_ctz(bits));
          for (size_t k = cur[i]; k < v.seq[i].size(); ++k) v.pending[v.seq[i][k].first] = 0;
        }
        return false;
      }
      v.order.push_back(uint32_t(best));
      for (uint32_t bits = valid; bits; bits &= bits - 1) {
        const uint32_t i = uint32_t(__builtin_ctz(bits));
        if (cur[i] < v.seq[i].size() && v.seq[i][cur[i]].first == uint32_t(best)) ++cur[i], --v.pending[best];
      }
    }
  }

  static void add_stats(PackageTraceStats& to, const PackageTraceStats& from) {
    to.add(from);
    to.rays -= from.rays;  // the caller counted every ray once
    to.point_visits += from.point_visits, to.culled_visits += from.culled_visits;
  }

  // Every valid ray (invalid ones are counted and left as the caller set them) front to back over the
  // batching points it may hit: visit(i, point, local, ray) traces the point with `local` (the ray
  // narrowed by the point's DAG), may shrink ray.tfar to cull later points, and returns true to stop.
  template <class Visit>
  PackageTraceStats each_ray(const fmt::Ray* rays, size_t n, const PackageTraceOptions& o, Visit&& visit) const {
    PackageTraceStats st;
    st.rays = n;
    for (size_t i = 0; i < n; ++i) {
      if (!ray_is_valid(rays[i])) {
        ++st.invalid_rays;
        continue;
      }
      fmt::Ray ray = rays[i];
      traverse(ray, [&](const Point<W, B>& pt, size_t p, double) {
        // Copied as two 16-byte rows, the halves the kernels' loads read (ray_is_valid): field by field,
        // those loads waited for a failed store forward.
        fmt::Ray local;
        _mm_storeu_ps(local.org, _mm_loadu_ps(ray.org));  // org, tnear
        _mm_storeu_ps(local.dir, _mm_loadu_ps(ray.dir));  // dir, tfar
        return enter(p, local, o, st) && visit(i, pt, local, ray);
      });
    }
    return st;
  }

  // Front-to-back over the top level: lanes sorted by entry distance, skipped once beyond ray.tfar
  // (which the visitor may shrink). visit(point, p, entry distance) returns true to stop (any hit).
  template <class Visit>
  void traverse(const fmt::Ray& ray, Visit&& visit) const {
    if (top_count_ == 0) return;
    // The top level has no depth limit: the stack grows when it must (per thread, reused, so the
    // steady state allocates nothing). References and entry distances are kept apart and moved field by
    // field: an {ref, t} entry written by a 4- and an 8-byte store and copied by one 16-byte load waited
    // for a failed store forward (issue 11: a tenth of an in-core package trace, perf).
    thread_local std::vector<uint32_t> refs;
    thread_local std::vector<double> ts;
    refs.clear();
    ts.clear();
    double inv[3];
    top_inverse(ray, inv);
    uint32_t ref = 0;  // the root
    double t = double(ray.tnear);
    for (;;) {
      if (!(t > double(ray.tfar))) {
        if (ref & fmt::TopNode::kLeafBit) {
          const size_t p = ref & ~fmt::TopNode::kLeafBit;
          if (visit(points_[p], p, t)) return;
        } else {
          const fmt::TopNode& node = top_[ref];
          uint32_t kid_ref[4];
          double kid_t[4];
          int nk = 0;
          const TopLanes lanes = top_lanes(node, ray, inv);
          for (int l = 0; l < 4; ++l)
            if (node.child[l] != fmt::TopNode::kEmpty && ((lanes.hit >> l) & 1u))
              kid_ref[nk] = node.child[l], kid_t[nk] = lanes.t0[l], ++nk;
          for (int a = 1; a < nk; ++a)  // insertion sort, farthest first: the nearest ends on top
            for (int b = a; b > 0 && kid_t[b - 1] < kid_t[b]; --b)
              std::swap(kid_t[b - 1], kid_t[b]), std::swap(kid_ref[b - 1], kid_ref[b]);
          for (int k = 0; k < nk; ++k) refs.push_back(kid_ref[k]), ts.push_back(kid_t[k]);
        }
      }
      if (refs.empty()) return;
      ref = refs.back(), t = ts.back();
      refs.pop_back(), ts.pop_back();
    }
  }

  std::vector<AlignedBytes> chunks_;
  std::vector<std::string> labels_;
  ResidentTables tables_;
  const fmt::TopNode* top_ = nullptr;
  uint64_t top_count_ = 0;
  std::vector<Point<W, B>> points_;
  const fmt::DagGrid* grids_ = nullptr;  // one per batching point, or null: no culling
  voxel::DagView dag_;
  PackageLoadStats load_;
};

}  // namespace

void check_multi_hit_count(uint32_t max_hits) {
  if (max_hits < 1 || max_hits > kMaxMultiHit)
    throw Error(ExitCode::kUsage,
                "multi-hit: N = " + std::to_string(max_hits) + " is outside [1, " + std::to_string(kMaxMultiHit) + "]");
}

uint32_t merge_point_hits(fmt::Hit* list, uint32_t count, uint32_t max_hits, const fmt::Hit* add, uint32_t n_add,
                          const uint32_t* global_ids, std::vector<fmt::Hit>& scratch) {
  if (n_add == 0) return count;
  scratch.assign(list, list + count);
  for (uint32_t k = 0; k < n_add; ++k) {
    scratch.push_back(add[k]);
    scratch.back().instance = global_ids[add[k].instance];
  }
  std::sort(scratch.begin(), scratch.end(), hit_order_less);
  const uint32_t c = uint32_t(std::min<size_t>(max_hits, scratch.size()));
  std::copy(scratch.begin(), scratch.begin() + c, list);
  return c;
}

std::unique_ptr<PackageTracer> load_package_in_core(const PackageReader& r) {
  const uint32_t w = r.header().bvh_width, b = r.header().leaf_width;
  if (w == 4 && b == 4) return std::make_unique<InCoreTracer<4, 4>>(r);
  if (w == 8 && b == 8) return std::make_unique<InCoreTracer<8, 8>>(r);
  if (w == 16 && b == 16) return std::make_unique<InCoreTracer<16, 16>>(r);
  if (w == 8 && b == 4) return std::make_unique<InCoreTracer<8, 4>>(r);
  if (w == 16 && b == 8) return std::make_unique<InCoreTracer<16, 8>>(r);
  fail_invalid("header: unsupported BVH width " + std::to_string(w) + " / leaf width " + std::to_string(b));
}

}  // namespace rtp
