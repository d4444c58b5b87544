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
//          warm-up and the best of max(--reps, 30) of: voxelize_point (triangles -> grid -> DAG), the
//          triangle loop alone (voxelize_triangle over every piece triangle, world positions through
//          its instance transform computed once before timing, into a grid with the point's origin,
//          cell and margin) and build_dag alone.
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
#include "core/progress.h"
#include "formats/chunk.h"
#include "mesh/prepare.h"
#include "package/writer.h"
#include "reader/reader.h"
#include "trace/package_tracer.h"
#include "package/write_package.h"
#include "scene/import.h"
#include "voxel/point_voxels.h"
#include "voxel/voxel.h"
#include "bench_dag_parts.h"
#include "tool_version.h"

namespace rtp::bench {
namespace {

using namespace dag;
using nlohmann::json;

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
    } catch (...) {}
    return std::string("must be a power of two from 4 to 1024");
  };
  const auto pow2_or_0 = [pow2](const std::string& s) { return s == "0" ? std::string() : pow2(s); };
  app.add_option("--resolutions", cfg.resolutions,
                 "--dag sweep: grid resolutions (default 32,64,128,256,512); 0: the converter's default (a resolution "
                 "per point, instance boxes for points of 64 instances or more)")
      ->delimiter(',')
      ->check(pow2_or_0)
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
    for (auto& rec : out) rec.update(rtp::tools::json_stamp("rtpack-bench"));
    std::cout << out.dump(1) << "\n";
  }

  FILE* o = cfg.json ? stderr : stdout;
  std::fprintf(o, "\ncpu %s; %d of %d hardware threads; best of %d after a warm-up\n", cpu.c_str(), threads, hw, cfg.reps);
  if (!proxies.empty()) {
    std::fprintf(o, "\nDAG bytes at %u^3, each model one batching point (SVO = same grid, no sharing):\n", cfg.proxy_resolution);
    std::fprintf(o, "  %-28s %10s %7s %10s %12s %12s %12s | %12s %12s %12s\n", "model", "triangles", "points", "set cells",
                 "SVO B", "DAG alone B", "own pool B", "voxelize ms", "tri loop ms", "build_dag ms");
    for (const ProxyRecord& r : proxies)
      std::fprintf(o,
                   "  %-28s %10" PRIu64 " %7" PRIu64 " %10" PRIu64 " %12" PRIu64 " %12" PRIu64 " %12" PRIu64
                   " | %12.2f %12.2f %12.2f\n",
                   base_name(r.scene).c_str(), r.unique, r.points, r.set_cells, r.svo_bytes, r.dag_bytes, r.own_pool_bytes,
                   r.voxelize_s * 1e3, r.loop_s * 1e3, r.build_dag_s * 1e3);
    std::fprintf(o,
                 "  all %zu in one shared pool: %" PRIu64 " B (own pools summed %" PRIu64 " B, SVOs %" PRIu64
                 " B); sharing saves %" PRId64 " B (%.2f%%)\n",
                 proxies.size(), shared_bytes, alone_sum, svo_sum, int64_t(alone_sum) - int64_t(shared_bytes),
                 alone_sum ? 100.0 * (1.0 - double(shared_bytes) / double(alone_sum)) : 0.0);
    std::fprintf(o, "  (times: 1 thread, best of %d after a warm-up)\n", proxies.front().voxel_reps);
  }
  if (!sweeps.empty()) {
    std::fprintf(o, "\nresolution sweep (closest hit, %s, %s order; same package and rays, culling on vs off):\n",
                 isa_name(cfg.isa), cfg.order == TraversalOrder::kOctantStack ? "octant" : "active");
    std::fprintf(o, "  %-16s %5s %-7s %8s %12s %12s %10s %10s %8s %11s %11s %7s %s\n", "scene", "R", "kind", "rays", "pool B",
                 "package B", "visits", "culled", "cull %", "Mrays cull", "Mrays off", "ratio", "hits");
    for (const SweepRecord& s : sweeps)
      std::fprintf(o,
                   "  %-16s %5u %-7s %8zu %12" PRIu64 " %12" PRIu64 " %10" PRIu64 " %10" PRIu64 " %8.2f %11.3f %11.3f %7.3f %s\n",
                   base_name(s.scene).c_str(), s.resolution, ray_kind_name(s.kind), s.rays, s.pool_bytes, s.package_bytes,
                   s.visits_on, s.culled, 100 * s.cull_rate(), s.mrays_on, s.mrays_off, s.mrays_on / s.mrays_off,
                   s.mismatched ? "DIFFER" : "identical");
  }
  if (!converts.empty()) {
    std::fprintf(o, "\nconvert cost (write_package, best of %d; import/prepare/plan once):\n", cfg.reps);
    std::fprintf(o, "  %-22s %10s %7s %10s %10s %7s %12s %12s %7s %11s %11s  %s\n", "scene", "triangles", "points", "s DAG",
                 "s no DAG", "ratio", "B DAG", "B no DAG", "ratio", "pool B", "voxelize s", "resolutions");
    for (const ConvertCost& c : converts)
      std::fprintf(o,
                   "  %-22s %10" PRIu64 " %7" PRIu64 " %10.3f %10.3f %7.3f %12" PRIu64 " %12" PRIu64 " %7.4f %11" PRIu64
                   " %11.3f  %s\n",
                   base_name(c.scene).c_str(), c.instanced, c.points, c.with_s, c.without_s, c.with_s / c.without_s, c.with_bytes,
                   c.without_bytes, double(c.with_bytes) / double(c.without_bytes), c.pool_bytes, c.voxelize_s,
                   resolutions_text(c.resolutions).c_str());
  }
  if (mismatched) {
    std::fprintf(o,
                 "\nHITS DIFFER with culling on vs off on %" PRId64
                 " rays in total: the culling is wrong and these "
                 "numbers are worthless.\n",
                 mismatched);
    return int(ExitCode::kInternal);
  }
  return 0;
}

}  // namespace rtp::bench
