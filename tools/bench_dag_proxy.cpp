// rtpack-bench --dag, part "proxy" (tools/bench_dag.cpp describes it): DAG bytes and 1-thread voxelization time.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cinttypes>
#include <cmath>
#include <cstring>
#include <optional>

#include "bench_dag_parts.h"
#include "bvh/bvh.h"
#include "core/error.h"
#include "formats/chunk.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "trace/package_tracer.h"
#include "voxel/point_voxels.h"
#include "voxel/voxel.h"

namespace rtp::bench::dag {
namespace {

// ---------------------------------------------------------------------------------------------
// proxy: single models at one resolution

// Bytes of the grid stored as a sparse voxel octree in the DAG's node layout (formats/dag.h 3.0: a
// head word plus one word per non-full child; a level-1 node holds its partial 4^3 leaves inline, 8
// bytes each, as the converter stores a leaf used once), with no subtree shared.
struct SvoCount {
  const voxel::Grid& g;
  uint64_t bytes = 0;
  enum State { kEmpty, kFull, kPartial };
  State leaf(uint32_t bx, uint32_t by, uint32_t bz) {
    const uint64_t m = g.block(bx, by, bz);
    if (m == 0) return kEmpty;
    if (m == ~uint64_t(0)) return kFull;
    return kPartial;
  }
  State node(int level, uint32_t x, uint32_t y, uint32_t z) {
    if (g.region_empty(x << level, y << level, z << level, 1u << level)) return kEmpty;
    int empty = 0, full = 0, partial = 0;
    for (uint32_t c = 0; c < 8; ++c) {
      const uint32_t cx = 2 * x + (c & 1), cy = 2 * y + ((c >> 1) & 1), cz = 2 * z + (c >> 2);
      const State s = level == 1 ? leaf(cx, cy, cz) : node(level - 1, cx, cy, cz);
      (s == kEmpty ? empty : s == kFull ? full : partial) += 1;
    }
    if (empty == 8) return kEmpty;
    if (full == 8) return kFull;
    bytes += 4 + (level == 1 ? 8 : 4) * uint64_t(partial);
    return kPartial;
  }
  uint64_t run() {
    const int levels = std::countr_zero(g.resolution / 4);
    if (levels == 0)
      bytes = leaf(0, 0, 0) == kPartial ? 8 : 0;  // R = 4: the root is a pooled leaf
    else
      node(levels, 0, 0, 0);
    return bytes;
  }
};

}  // namespace

void run_proxy(const DagBenchConfig& cfg, std::vector<ProxyRecord>& out, uint64_t& shared_bytes) {
  voxel::DagPool shared;
  for (const std::string& path : cfg.scenes) {
    const auto t0 = Clock::now();
    const Prepared p = load(path, uint64_t(1) << 40, cfg.allow_paths);  // one batching point per model
    const voxel::MeshProxies meshes(p.scene, p.plan);
    const std::vector<fmt::InstanceRecord> records = make_instance_records(p.scene.instances);
    voxel::VoxelOptions vo;
    vo.resolution = cfg.proxy_resolution;
    ProxyRecord r;
    r.scene = path;
    r.unique = p.scene.unique_triangles();
    r.instanced = p.scene.instanced_triangles();
    r.points = p.plan.points.size();
    r.resolution = cfg.proxy_resolution;
    voxel::DagPool own;
    std::vector<voxel::PointProxy> proxies;
    for (const BatchingPoint& bp : p.plan.points) {
      voxel::PointProxy px = voxel::voxelize_point(p.scene, p.plan, meshes, records.data(), bp, vo);
      r.set_cells += px.set_cells;
      r.dag_bytes += px.dag.bytes();
      fmt::DagGrid g = px.grid;
      g.root = px.dag.root;
      const voxel::DagView local{px.dag.words.data(), px.dag.words.size(), px.dag.leaves.data(), px.dag.leaves.size()};
      r.svo_bytes += SvoCount{voxel::decode_dag(g, local)}.run();
      own.add(px.dag);
      shared.add(px.dag);
      proxies.push_back(std::move(px));
    }
    r.own_pool_bytes = own.bytes();

    // Single-thread timings.
    r.voxel_reps = std::max(cfg.reps, 30);  // milliseconds each: many reps cost little and tame a shared machine's noise
    std::vector<voxel::Grid> grids;
    tbb::task_arena one(1);
    one.execute([&] {
      r.voxelize_s = best_of(r.voxel_reps, [&] {
        for (const BatchingPoint& bp : p.plan.points)
          (void)voxel::voxelize_point(p.scene, p.plan, meshes, records.data(), bp, vo);
      });
      r.loop_triangles = 0;
      for (const BatchingPoint& bp : p.plan.points)
        for (uint32_t pi : bp.pieces) r.loop_triangles += p.plan.pieces[pi].mesh.triangle_count();
      // World positions once per piece, untimed (voxelize_point moves each vertex once too).
      std::vector<std::vector<Vec3d>> world;
      for (const BatchingPoint& bp : p.plan.points)
        for (uint32_t pi : bp.pieces) {
          const UniquePiece& pc = p.plan.pieces[pi];
          const Affine3x4& m = p.scene.instances[pc.instance].transform;
          std::vector<Vec3d>& w = world.emplace_back();
          for (const Vec3f& v : pc.mesh.positions) w.push_back(m.apply(to_d(v)));
        }
      r.loop_s = best_of(r.voxel_reps, [&] {
        grids.clear();
        size_t piece = 0;
        for (size_t k = 0; k < p.plan.points.size(); ++k) {
          const fmt::DagGrid& dg = proxies[k].grid;
          voxel::Grid g({dg.origin[0], dg.origin[1], dg.origin[2]}, dg.cell, dg.resolution);
          for (uint32_t pi : p.plan.points[k].pieces) {
            const std::vector<uint32_t>& idx = p.plan.pieces[pi].mesh.indices;
            const std::vector<Vec3d>& w = world[piece++];
            for (size_t t = 0; t + 2 < idx.size(); t += 3)
              voxel::voxelize_triangle(g, w[idx[t]], w[idx[t + 1]], w[idx[t + 2]], dg.margin);
          }
          grids.push_back(std::move(g));
        }
      });
      r.build_dag_s = best_of(r.voxel_reps, [&] {
        for (const voxel::Grid& g : grids) (void)voxel::build_dag(g);
      });
    });
    note("proxy %s: %" PRIu64 " triangles, %" PRIu64 " point(s) at %u^3: SVO %" PRIu64 " B, DAG alone %" PRIu64
         " B (own pool %" PRIu64 " B); 1 thread: voxelize_point %.2f ms (triangle loop %.2f ms, build_dag %.2f ms) [%.1f s]",
         base_name(path).c_str(), r.unique, r.points, r.resolution, r.svo_bytes, r.dag_bytes, r.own_pool_bytes,
         r.voxelize_s * 1e3, r.loop_s * 1e3, r.build_dag_s * 1e3, since(t0));
    out.push_back(r);
  }
  shared_bytes = shared.bytes();
}

}  // namespace rtp::bench::dag
