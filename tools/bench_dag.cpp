// rtpack-bench --dag: the occlusion-culling DAGs of issue 8 (Molenaar 2019 §3.2–3.3, §4.2, §5.2),
// measured through the library in one process. Three parts, each over every SCENE given (--parts):
//
// proxy    Each scene planned as ONE batching point (chunk target 2^40: a single model stays whole)
//          and voxelized at --proxy-resolution (default 128^3, the seed's resolution), as
//          write_package does it (voxel::MeshProxies + voxel::voxelize_point). Reports per scene:
//          set cells, the SVO-equivalent bytes (the same grid in the DAG's node layout, formats/dag.h,
//          with no subtree shared), the DAG built alone (LocalDag) and in a pool of its own (what a
//          package of that model stores), then every scene's DAG in ONE shared voxel::DagPool (in the
//          order given) and the saving from sharing. Then, in a tbb::task_arena of ONE thread, one
//          warm-up and the best of max(--reps, 5) of: voxelize_point (triangles -> grid -> DAG), the
//          triangle loop alone (voxelize_triangle over every piece triangle through its instance
//          transform into a grid with the point's origin, cell and margin) and build_dag alone.
// sweep    The scene converted as rtpack-convert converts it (default chunk target, W=8, B=8,
//          zstd 9) once per --resolutions value (every batching point at that resolution), then
//          loaded in core (PackageReader + load_package_in_core). Rays are generated once per scene
//          (lib/oracle/rays.h, --kinds, default bounce and random, --rays per kind, seeded), the
//          closest-hit callback being the package tracer with culling off. Per resolution and kind,
//          untimed: the hits with culling on and off are compared byte for byte (memcmp) -- any
//          difference is reported loudly and the exit code is 5 -- and the batching-point visits and
//          culled visits counted; timed: closest hit with culling on and off on the SAME package and
//          rays, one warm-up of each, then --reps interleaved repetitions (on, off, on, ...), best of
//          each, in a tbb::task_arena of --threads threads (256 rays per task, as rtpack-trace).
// convert  The scene imported, prepared and planned once, then write_package with DAGs (default
//          resolution choice) and without (--no-dag), interleaved, one warm-up of each then the best
//          of --reps: chunk-stage seconds and package bytes on disk, with the DAG pool's bytes.
//
// Progress lines go to stderr as each scene / resolution finishes; the tables go to stdout (stderr
// with --json, which prints the records as one JSON array on stdout).
#include "bench_dag.h"

#include <CLI/CLI.hpp>
#include <tbb/blocked_range.h>
#include <tbb/global_control.h>
#include <tbb/info.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>

#include "bench_convert.h"
#include "cluster/cluster.h"
#include "core/error.h"
#include "core/utf8.h"
#include "core/progress.h"
#include "formats/chunk.h"
#include "mesh/prepare.h"
#include "package/package.h"
#include "package/package_tracer.h"
#include "package/write_package.h"
#include "scene/import.h"
#include "voxel/point_voxels.h"
#include "voxel/voxel.h"

namespace rtp::bench {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;
using nlohmann::json;

constexpr size_t kGrain = 256;  // rays per TBB task (rtpack-trace's grain)

double since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

// One warm-up, then the best of `reps`.
template <class F>
double best_of(int reps, F&& f) {
  f();
  double best = std::numeric_limits<double>::infinity();
  for (int r = 0; r < reps; ++r) {
    const auto t0 = Clock::now();
    f();
    best = std::min(best, since(t0));
  }
  return best;
}

void note(const char* fmt_, ...) __attribute__((format(printf, 1, 2)));
void note(const char* fmt_, ...) {
  va_list ap;
  va_start(ap, fmt_);
  std::fprintf(stderr, "[dag] ");
  std::vfprintf(stderr, fmt_, ap);
  std::fprintf(stderr, "\n");
  std::fflush(stderr);
  va_end(ap);
}

std::string base_name(const std::string& path) { return utf8_display(fs::path(path).filename().string()); }

// Removes the temporary packages on every way out.
struct TempFile {
  std::string path;
  explicit TempFile(const std::string& tag)
      : path((fs::temp_directory_path() / ("rtpack-bench-dag-" + std::to_string(::getpid()) + "-" + tag + ".rtp")).string()) {}
  ~TempFile() {
    std::error_code ec;
    fs::remove(path, ec);
  }
};

// A scene imported, prepared and planned as rtpack-convert does it by default.
struct Prepared {
  Scene scene;
  Plan plan;
  double import_s = 0, prepare_s = 0, plan_s = 0;
};

Prepared load(const std::string& path, uint64_t chunk_target, const std::vector<std::string>& allow_paths) {
  Prepared p;
  auto t0 = Clock::now();
  ImportOptions io;
  io.allowed_dirs = allow_paths;
  p.scene = import_gltf(path, io);
  p.import_s = since(t0);
  t0 = Clock::now();
  PrepareOptions prep;  // rtpack-convert's defaults: no weld, no subdivision
  prep.clean.weld_eps = -1;
  (void)prepare_scene(p.scene, prep);
  p.prepare_s = since(t0);
  if (p.scene.instanced_triangles() == 0) throw Error(ExitCode::kInputInvalid, "the scene has no triangles");
  t0 = Clock::now();
  ClusterOptions co;
  co.chunk_target = chunk_target;
  co.chunk_by = ChunkBy::kInstanced;
  p.plan = plan_batching_points(p.scene, co);
  p.plan_s = since(t0);
  return p;
}

ConvertOptions convert_options(const std::string& scene_path, bool dag, uint32_t resolution) {
  ConvertOptions cv;  // rtpack-convert's defaults: W=8, B=8, collapse, zstd 9
  cv.width = 8;
  cv.leaf_width = 8;
  cv.bvh.method = BuildMethod::kCollapse;
  cv.zstd_level = 9;
  cv.dag = dag;
  cv.voxel.resolution = resolution;
  cv.metadata = {{"tool_version", "rtpack " RTP_VERSION " (rtpack-bench --dag)"},
                 {"source", base_name(scene_path)}};
  return cv;
}

// ---------------------------------------------------------------------------------------------
// proxy: single models at one resolution

// Bytes of the grid stored as a sparse voxel octree in the DAG's node layout (formats/dag.h: a head
// word plus one word per non-full child, 8 bytes per partial 4^3 leaf), with no subtree shared.
struct SvoCount {
  const voxel::Grid& g;
  uint64_t bytes = 0;
  enum State { kEmpty, kFull, kPartial };
  State leaf(uint32_t bx, uint32_t by, uint32_t bz) {
    const uint64_t m = g.block(bx, by, bz);
    if (m == 0) return kEmpty;
    if (m == ~uint64_t(0)) return kFull;
    bytes += 8;
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
    bytes += 4 + 4 * uint64_t(partial);
    return kPartial;
  }
  uint64_t run() {
    const int levels = std::countr_zero(g.resolution / 4);
    if (levels == 0) leaf(0, 0, 0);
    else node(levels, 0, 0, 0);
    return bytes;
  }
};

struct ProxyRecord {
  std::string scene;
  uint64_t unique = 0, instanced = 0, points = 0;
  uint32_t resolution = 0;
  uint64_t set_cells = 0, svo_bytes = 0, dag_bytes = 0, own_pool_bytes = 0;
  uint64_t loop_triangles = 0;  // piece triangles the triangle loop voxelizes (instances go through MeshProxies)
  double voxelize_s = 0, loop_s = 0, build_dag_s = 0;
  int voxel_reps = 0;
};

void run_proxy(const DagBenchConfig& cfg, std::vector<ProxyRecord>& out, uint64_t& shared_bytes) {
  voxel::DagPool shared;
  for (const std::string& path : cfg.scenes) {
    const auto t0 = Clock::now();
    const Prepared p = load(path, uint64_t(1) << 40, cfg.allow_paths);  // one batching point per model
    const voxel::MeshProxies meshes(p.scene, p.plan);
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
      voxel::PointProxy px = voxel::voxelize_point(p.scene, p.plan, meshes, bp, vo);
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
    r.voxel_reps = std::max(cfg.reps, 5);
    std::vector<voxel::Grid> grids;
    tbb::task_arena one(1);
    one.execute([&] {
      r.voxelize_s = best_of(r.voxel_reps, [&] {
        for (const BatchingPoint& bp : p.plan.points) (void)voxel::voxelize_point(p.scene, p.plan, meshes, bp, vo);
      });
      r.loop_triangles = 0;
      for (const BatchingPoint& bp : p.plan.points)
        for (uint32_t pi : bp.pieces) r.loop_triangles += p.plan.pieces[pi].mesh.triangle_count();
      r.loop_s = best_of(r.voxel_reps, [&] {
        grids.clear();
        for (size_t k = 0; k < p.plan.points.size(); ++k) {
          const fmt::DagGrid& dg = proxies[k].grid;
          voxel::Grid g({dg.origin[0], dg.origin[1], dg.origin[2]}, dg.cell, dg.resolution);
          for (uint32_t pi : p.plan.points[k].pieces) {
            const UniquePiece& pc = p.plan.pieces[pi];
            const Affine3x4& m = p.scene.instances[pc.instance].transform;
            const Mesh& mesh = pc.mesh;
            for (size_t t = 0; t + 2 < mesh.indices.size(); t += 3)
              voxel::voxelize_triangle(g, m.apply(to_d(mesh.positions[mesh.indices[t]])),
                                       m.apply(to_d(mesh.positions[mesh.indices[t + 1]])),
                                       m.apply(to_d(mesh.positions[mesh.indices[t + 2]])), dg.margin);
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

// ---------------------------------------------------------------------------------------------
// sweep: resolution vs bytes, cull rate and tracing speed

struct TraceCounts {
  uint64_t visits = 0, culled = 0;
};

TraceCounts trace_all(const PackageTracer& tracer, const std::vector<fmt::Ray>& rays, fmt::Hit* hits,
                      const PackageTraceOptions& o) {
  std::atomic<uint64_t> visits{0}, culled{0};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, rays.size(), kGrain), [&](const tbb::blocked_range<size_t>& r) {
    const PackageTraceStats st = tracer.closest(rays.data() + r.begin(), hits + r.begin(), r.size(), o);
    visits += st.point_visits;
    culled += st.culled_visits;
  });
  return {visits.load(), culled.load()};
}

struct SweepRecord {
  std::string scene;
  uint32_t resolution = 0;
  RayKind kind{};
  size_t rays = 0, fallback = 0;
  uint64_t points = 0, package_bytes = 0, pool_bytes = 0, separate_bytes = 0, set_cells = 0;
  double convert_s = 0, voxelize_s = 0, load_s = 0;
  uint64_t visits_on = 0, visits_off = 0, culled = 0, hits = 0, mismatched = 0;
  double mrays_on = 0, mrays_off = 0;
  double cull_rate() const { return visits_on ? double(culled) / double(visits_on) : 0.0; }
};

int64_t run_sweep(const DagBenchConfig& cfg, int threads, std::vector<SweepRecord>& out) {
  int64_t total_mismatch = 0;
  tbb::task_arena arena(threads);
  for (const std::string& path : cfg.scenes) {
    const auto t_scene = Clock::now();
    std::optional<Prepared> p;
    arena.execute([&] { p.emplace(load(path, 0, cfg.allow_paths)); });
    note("sweep %s: %" PRIu64 " unique / %" PRIu64 " instanced triangles, %zu batching points (load %.1f s)",
         base_name(path).c_str(), p->scene.unique_triangles(), p->scene.instanced_triangles(), p->plan.points.size(),
         since(t_scene));
    struct KindRays {
      RayKind kind;
      std::vector<fmt::Ray> rays;
      RayGenInfo info;
    };
    std::vector<KindRays> kinds;
    for (uint32_t res : cfg.resolutions) {
      const auto t_res = Clock::now();
      TempFile tmp(std::to_string(res));
      ConvertReport rep;
      double convert_s = 0;
      arena.execute([&] {
        const auto t0 = Clock::now();
        rep = write_package(p->scene, p->plan, tmp.path, convert_options(path, true, res));
        convert_s = since(t0);
      });
      const auto t_load = Clock::now();
      PackageReader reader(tmp.path);
      std::unique_ptr<PackageTracer> tracer;
      arena.execute([&] { tracer = load_package_in_core(reader); });
      const double load_s = since(t_load);
      if (!tracer->has_dags()) throw Error(ExitCode::kInternal, "the package written with DAGs has none");
      PackageTraceOptions on, off;
      on.isa = off.isa = cfg.isa;
      on.order = off.order = cfg.order;
      on.cull = true;
      off.cull = false;
      if (kinds.empty()) {  // once per scene: the geometry (and so every hit) is the same at every resolution
        for (RayKind kind : cfg.kinds) {
          KindRays k{kind, {}, {}};
          RayGenOptions gen;
          gen.seed = cfg.seed;
          gen.closest = [&](const fmt::Ray* r, fmt::Hit* h, size_t n) {
            tbb::parallel_for(tbb::blocked_range<size_t>(0, n, kGrain), [&](const tbb::blocked_range<size_t>& b) {
              tracer->closest(r + b.begin(), h + b.begin(), b.size(), off);
            });
          };
          arena.execute([&] { k.rays = generate_rays(p->scene, kind, cfg.rays, gen, &k.info); });
          kinds.push_back(std::move(k));
        }
      }
      for (const KindRays& k : kinds) {
        const size_t n = k.rays.size();
        SweepRecord s;
        s.scene = path;
        s.resolution = res;
        s.kind = k.kind;
        s.rays = n;
        s.fallback = k.info.fallback;
        s.points = p->plan.points.size();
        s.package_bytes = fs::file_size(tmp.path);
        s.pool_bytes = rep.dag_pool_bytes;
        s.separate_bytes = rep.dag_separate_bytes;
        s.set_cells = rep.dag_set_cells;
        s.convert_s = convert_s;
        s.voxelize_s = rep.voxelize_seconds;
        s.load_s = load_s;
        std::vector<fmt::Hit> hits_on(n), hits_off(n);
        double secs_on = std::numeric_limits<double>::infinity(), secs_off = secs_on;
        arena.execute([&] {
          // Untimed: the same answers with culling on and off, and the visit counts.
          const TraceCounts c_on = trace_all(*tracer, k.rays, hits_on.data(), on);
          const TraceCounts c_off = trace_all(*tracer, k.rays, hits_off.data(), off);
          s.visits_on = c_on.visits;
          s.culled = c_on.culled;
          s.visits_off = c_off.visits;
          if (std::memcmp(hits_on.data(), hits_off.data(), n * sizeof(fmt::Hit)) != 0)
            for (size_t i = 0; i < n; ++i) s.mismatched += std::memcmp(&hits_on[i], &hits_off[i], sizeof(fmt::Hit)) != 0;
          for (const fmt::Hit& h : hits_off) s.hits += h.t < std::numeric_limits<float>::infinity();
          // Timed: one warm-up of each, then interleaved repetitions, best of each.
          for (int r = 0; r <= cfg.reps; ++r) {
            auto t0 = Clock::now();
            trace_all(*tracer, k.rays, hits_on.data(), on);
            if (r > 0) secs_on = std::min(secs_on, since(t0));
            t0 = Clock::now();
            trace_all(*tracer, k.rays, hits_off.data(), off);
            if (r > 0) secs_off = std::min(secs_off, since(t0));
          }
        });
        s.mrays_on = double(n) / secs_on * 1e-6;
        s.mrays_off = double(n) / secs_off * 1e-6;
        if (s.mismatched) {
          total_mismatch += int64_t(s.mismatched);
          std::fprintf(stderr,
                       "\n!!! HITS DIFFER: %s at %u^3, %s rays: culling on and off give different hits on %" PRIu64
                       " of %zu rays. The culling is WRONG; these numbers are worthless. !!!\n\n",
                       base_name(path).c_str(), res, ray_kind_name(k.kind), s.mismatched, n);
        }
        out.push_back(s);
      }
      std::string line;
      for (size_t i = out.size() - kinds.size(); i < out.size(); ++i) {
        const SweepRecord& s = out[i];
        char buf[200];
        std::snprintf(buf, sizeof buf, "; %s cull %.1f%% %.2f/%.2f Mrays/s on/off (x%.2f)%s", ray_kind_name(s.kind),
                      100 * s.cull_rate(), s.mrays_on, s.mrays_off, s.mrays_on / s.mrays_off,
                      s.mismatched ? " HITS DIFFER" : "");
        line += buf;
      }
      note("sweep %s %u^3: pool %" PRIu64 " B, convert %.2f s%s [%.1f s]", base_name(path).c_str(), res, rep.dag_pool_bytes,
           convert_s, line.c_str(), since(t_res));
    }
  }
  return total_mismatch;
}

// ---------------------------------------------------------------------------------------------
// convert: the cost of the feature

struct ConvertCost {
  std::string scene;
  uint64_t unique = 0, instanced = 0, points = 0, segments = 0;
  double import_s = 0, prepare_s = 0, plan_s = 0;
  double with_s = 0, without_s = 0;  // write_package, best of reps
  uint64_t with_bytes = 0, without_bytes = 0;
  uint64_t pool_bytes = 0, pool_stored = 0, separate_bytes = 0, set_cells = 0;
  double voxelize_s = 0;  // summed over threads, in the best run with DAGs
  std::map<uint32_t, uint64_t> resolutions;
};

void run_convert(const DagBenchConfig& cfg, int threads, std::vector<ConvertCost>& out) {
  tbb::task_arena arena(threads);
  for (const std::string& path : cfg.scenes) {
    const auto t_scene = Clock::now();
    std::optional<Prepared> p;
    arena.execute([&] { p.emplace(load(path, 0, cfg.allow_paths)); });
    ConvertCost c;
    c.scene = path;
    c.unique = p->scene.unique_triangles();
    c.instanced = p->scene.instanced_triangles();
    c.points = p->plan.points.size();
    c.segments = p->plan.segments.size();
    c.import_s = p->import_s;
    c.prepare_s = p->prepare_s;
    c.plan_s = p->plan_s;
    c.with_s = c.without_s = std::numeric_limits<double>::infinity();
    TempFile with("with"), without("without");
    const ConvertOptions o_with = convert_options(path, true, 0), o_without = convert_options(path, false, 0);
    arena.execute([&] {
      for (int r = 0; r <= cfg.reps; ++r) {
        auto t0 = Clock::now();
        const ConvertReport rep = write_package(p->scene, p->plan, with.path, o_with);
        const double s_with = since(t0);
        t0 = Clock::now();
        (void)write_package(p->scene, p->plan, without.path, o_without);
        const double s_without = since(t0);
        if (r == 0) continue;
        c.without_s = std::min(c.without_s, s_without);
        if (s_with < c.with_s) {
          c.with_s = s_with;
          c.pool_bytes = rep.dag_pool_bytes;
          c.separate_bytes = rep.dag_separate_bytes;
          c.set_cells = rep.dag_set_cells;
          c.voxelize_s = rep.voxelize_seconds;
          c.resolutions = rep.dag_resolutions;
          const auto it = rep.by_kind.find(chunk_kind_name(uint32_t(fmt::ChunkKind::kDagPool)));
          c.pool_stored = it == rep.by_kind.end() ? 0 : it->second.stored;
        }
      }
    });
    c.with_bytes = fs::file_size(with.path);
    c.without_bytes = fs::file_size(without.path);
    note("convert %s: %" PRIu64 " points; write_package %.3f s with DAGs vs %.3f s without (x%.2f); %" PRIu64
         " vs %" PRIu64 " B (+%.1f%%) [%.1f s]",
         base_name(path).c_str(), c.points, c.with_s, c.without_s, c.with_s / c.without_s, c.with_bytes, c.without_bytes,
         100.0 * (double(c.with_bytes) - double(c.without_bytes)) / double(c.without_bytes), since(t_scene));
    out.push_back(std::move(c));
  }
}

std::string resolutions_text(const std::map<uint32_t, uint64_t>& m) {
  std::string s;
  for (const auto& [r, n] : m) s += (s.empty() ? "" : ", ") + std::to_string(n) + "x" + std::to_string(r);
  return s;
}

}  // namespace

CLI::Option* add_dag_options(CLI::App& app, DagBenchConfig& cfg) {
  static const std::string kHelp =
      "instead of Embree: the occlusion-culling DAGs (tools/bench_dag.cpp): DAG bytes of single models alone and "
      "in one shared pool and their 1-thread voxelization time (proxy), resolution vs pool bytes / cull rate / "
      "Mrays/s with culling on and off (sweep; --rays default 131072, --kinds default bounce,random), convert "
      "time and bytes with and without DAGs (convert); every SCENE given";
  auto* flag = app.add_flag("--dag", kHelp);
  app.add_option("more_scenes", cfg.scenes, "--dag: further scenes")->needs(flag);
  app.add_option("--parts", cfg.parts, "--dag: proxy, sweep, convert (comma-separated; default all)")
      ->delimiter(',')
      ->check(CLI::IsMember({"proxy", "sweep", "convert"}))
      ->needs(flag);
  auto pow2 = [](const std::string& s) {
    try {
      const unsigned long v = std::stoul(s);
      if (v >= 4 && v <= 1024 && (v & (v - 1)) == 0) return std::string();
    } catch (...) {
    }
    return std::string("must be a power of two from 4 to 1024");
  };
  app.add_option("--resolutions", cfg.resolutions, "--dag sweep: grid resolutions (default 32,64,128,256,512)")
      ->delimiter(',')
      ->check(pow2)
      ->needs(flag);
  app.add_option("--proxy-resolution", cfg.proxy_resolution, "--dag proxy: grid resolution (default 128)")
      ->check(pow2)
      ->needs(flag);
  return flag;
}

int run_dag_bench(const DagBenchConfig& cfg) {
  const int hw = std::max(1, tbb::info::default_concurrency());
  const int threads = cfg.threads > 0 ? cfg.threads : hw;
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
  auto has = [&](const char* part) { return std::find(cfg.parts.begin(), cfg.parts.end(), part) != cfg.parts.end(); };
  const std::string cpu = cpu_model();
  note("cpu %s; %d of %d hardware threads; %zu scene(s); parts:%s%s%s", cpu.c_str(), threads, hw, cfg.scenes.size(),
       has("proxy") ? " proxy" : "", has("sweep") ? " sweep" : "", has("convert") ? " convert" : "");

  std::vector<ProxyRecord> proxies;
  uint64_t shared_bytes = 0;
  std::vector<SweepRecord> sweeps;
  std::vector<ConvertCost> converts;
  int64_t mismatched = 0;
  if (has("proxy")) run_proxy(cfg, proxies, shared_bytes);
  if (has("sweep")) mismatched = run_sweep(cfg, threads, sweeps);
  if (has("convert")) run_convert(cfg, threads, converts);

  uint64_t alone_sum = 0, svo_sum = 0;
  for (const ProxyRecord& r : proxies) alone_sum += r.own_pool_bytes, svo_sum += r.svo_bytes;

  if (cfg.json) {
    json out = json::array();
    for (const ProxyRecord& r : proxies)
      out.push_back({{"type", "dag_model"},
                     {"scene", r.scene},
                     {"unique_triangles", r.unique},
                     {"instanced_triangles", r.instanced},
                     {"batching_points", r.points},
                     {"resolution", r.resolution},
                     {"set_cells", r.set_cells},
                     {"svo_bytes", r.svo_bytes},
                     {"dag_bytes", r.dag_bytes},
                     {"own_pool_bytes", r.own_pool_bytes},
                     {"voxelize_ms", r.voxelize_s * 1e3},
                     {"triangle_loop_ms", r.loop_s * 1e3},
                     {"build_dag_ms", r.build_dag_s * 1e3},
                     {"triangle_loop_triangles", r.loop_triangles},
                     {"voxelize_threads", 1},
                     {"voxelize_reps", r.voxel_reps},
                     {"cpu", cpu}});
    if (!proxies.empty()) {
      json scenes = json::array();
      for (const ProxyRecord& r : proxies) scenes.push_back(r.scene);
      out.push_back({{"type", "dag_shared_pool"},
                     {"scenes", scenes},
                     {"resolution", cfg.proxy_resolution},
                     {"svo_bytes", svo_sum},
                     {"alone_bytes", alone_sum},
                     {"shared_bytes", shared_bytes},
                     {"saving_bytes", int64_t(alone_sum) - int64_t(shared_bytes)},
                     {"saving_fraction", alone_sum ? 1.0 - double(shared_bytes) / double(alone_sum) : 0.0},
                     {"cpu", cpu}});
    }
    for (const SweepRecord& s : sweeps)
      out.push_back({{"type", "dag_sweep"},
                     {"scene", s.scene},
                     {"resolution", s.resolution},
                     {"kind", ray_kind_name(s.kind)},
                     {"query", "closest"},
                     {"rays", s.rays},
                     {"ray_fallback", s.fallback},
                     {"seed", cfg.seed},
                     {"batching_points", s.points},
                     {"package_bytes", s.package_bytes},
                     {"pool_bytes", s.pool_bytes},
                     {"separate_bytes", s.separate_bytes},
                     {"set_cells", s.set_cells},
                     {"convert_s", s.convert_s},
                     {"voxelize_thread_s", s.voxelize_s},
                     {"load_s", s.load_s},
                     {"point_visits", s.visits_on},
                     {"point_visits_no_cull", s.visits_off},
                     {"culled_visits", s.culled},
                     {"cull_rate", s.cull_rate()},
                     {"hits", s.hits},
                     {"hits_identical", s.mismatched == 0},
                     {"mismatched_rays", s.mismatched},
                     {"mrays_cull", s.mrays_on},
                     {"mrays_no_cull", s.mrays_off},
                     {"ratio", s.mrays_on / s.mrays_off},
                     {"isa", isa_name(cfg.isa)},
                     {"order", cfg.order == TraversalOrder::kOctantStack ? "octant" : "active"},
                     {"threads", threads},
                     {"reps", cfg.reps},
                     {"cpu", cpu}});
    for (const ConvertCost& c : converts) {
      json hist = json::object();
      for (const auto& [r, n] : c.resolutions) hist[std::to_string(r)] = n;
      out.push_back({{"type", "dag_convert"},
                     {"scene", c.scene},
                     {"unique_triangles", c.unique},
                     {"instanced_triangles", c.instanced},
                     {"batching_points", c.points},
                     {"mesh_segments", c.segments},
                     {"import_s", c.import_s},
                     {"prepare_s", c.prepare_s},
                     {"plan_s", c.plan_s},
                     {"write_s_dag", c.with_s},
                     {"write_s_no_dag", c.without_s},
                     {"time_ratio", c.with_s / c.without_s},
                     {"package_bytes_dag", c.with_bytes},
                     {"package_bytes_no_dag", c.without_bytes},
                     {"bytes_ratio", double(c.with_bytes) / double(c.without_bytes)},
                     {"pool_bytes", c.pool_bytes},
                     {"pool_stored_bytes", c.pool_stored},
                     {"separate_bytes", c.separate_bytes},
                     {"set_cells", c.set_cells},
                     {"voxelize_thread_s", c.voxelize_s},
                     {"resolutions", hist},
                     {"threads", threads},
                     {"reps", cfg.reps},
                     {"cpu", cpu}});
    }
    std::cout << out.dump(1) << "\n";
  }

  FILE* o = cfg.json ? stderr : stdout;
  std::fprintf(o, "\ncpu %s; %d of %d hardware threads; best of %d after a warm-up\n", cpu.c_str(), threads, hw, cfg.reps);
  if (!proxies.empty()) {
    std::fprintf(o, "\nDAG bytes at %u^3, each model one batching point (SVO = same grid, no sharing):\n", cfg.proxy_resolution);
    std::fprintf(o, "  %-28s %10s %7s %10s %12s %12s %12s | %12s %12s %12s\n", "model", "triangles", "points", "set cells",
                 "SVO B", "DAG alone B", "own pool B", "voxelize ms", "tri loop ms", "build_dag ms");
    for (const ProxyRecord& r : proxies)
      std::fprintf(o, "  %-28s %10" PRIu64 " %7" PRIu64 " %10" PRIu64 " %12" PRIu64 " %12" PRIu64 " %12" PRIu64
                   " | %12.2f %12.2f %12.2f\n",
                   base_name(r.scene).c_str(), r.unique, r.points, r.set_cells, r.svo_bytes, r.dag_bytes, r.own_pool_bytes,
                   r.voxelize_s * 1e3, r.loop_s * 1e3, r.build_dag_s * 1e3);
    std::fprintf(o, "  all %zu in one shared pool: %" PRIu64 " B (own pools summed %" PRIu64 " B, SVOs %" PRIu64
                 " B); sharing saves %" PRId64 " B (%.2f%%)\n",
                 proxies.size(), shared_bytes, alone_sum, svo_sum, int64_t(alone_sum) - int64_t(shared_bytes),
                 alone_sum ? 100.0 * (1.0 - double(shared_bytes) / double(alone_sum)) : 0.0);
    std::fprintf(o, "  (times: 1 thread, best of %d after a warm-up)\n", proxies.front().voxel_reps);
  }
  if (!sweeps.empty()) {
    std::fprintf(o, "\nresolution sweep (closest hit, %s, %s order; same package and rays, culling on vs off):\n",
                 isa_name(cfg.isa), cfg.order == TraversalOrder::kOctantStack ? "octant" : "active");
    std::fprintf(o, "  %-16s %5s %-7s %8s %12s %12s %10s %10s %8s %11s %11s %7s %s\n", "scene", "R", "kind", "rays",
                 "pool B", "package B", "visits", "culled", "cull %", "Mrays cull", "Mrays off", "ratio", "hits");
    for (const SweepRecord& s : sweeps)
      std::fprintf(o, "  %-16s %5u %-7s %8zu %12" PRIu64 " %12" PRIu64 " %10" PRIu64 " %10" PRIu64
                   " %8.2f %11.3f %11.3f %7.3f %s\n",
                   base_name(s.scene).c_str(), s.resolution, ray_kind_name(s.kind), s.rays, s.pool_bytes, s.package_bytes,
                   s.visits_on, s.culled, 100 * s.cull_rate(), s.mrays_on, s.mrays_off, s.mrays_on / s.mrays_off,
                   s.mismatched ? "DIFFER" : "identical");
  }
  if (!converts.empty()) {
    std::fprintf(o, "\nconvert cost (write_package, best of %d; import/prepare/plan once):\n", cfg.reps);
    std::fprintf(o, "  %-22s %10s %7s %10s %10s %7s %12s %12s %7s %11s %11s  %s\n", "scene", "triangles", "points", "s DAG",
                 "s no DAG", "ratio", "B DAG", "B no DAG", "ratio", "pool B", "voxelize s", "resolutions");
    for (const ConvertCost& c : converts)
      std::fprintf(o, "  %-22s %10" PRIu64 " %7" PRIu64 " %10.3f %10.3f %7.3f %12" PRIu64 " %12" PRIu64
                   " %7.4f %11" PRIu64 " %11.3f  %s\n",
                   base_name(c.scene).c_str(), c.instanced, c.points, c.with_s, c.without_s, c.with_s / c.without_s,
                   c.with_bytes, c.without_bytes, double(c.with_bytes) / double(c.without_bytes), c.pool_bytes,
                   c.voxelize_s, resolutions_text(c.resolutions).c_str());
  }
  if (mismatched) {
    std::fprintf(o, "\nHITS DIFFER with culling on vs off on %" PRId64 " rays in total: the culling is wrong and these "
                 "numbers are worthless.\n", mismatched);
    return int(ExitCode::kInternal);
  }
  return 0;
}

}  // namespace rtp::bench
