// rtpack-bench --dag, part "sweep" (tools/bench_dag.cpp describes it): resolution vs bytes, cull rate, tracing.
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

}  // namespace

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
                      100 * s.cull_rate(), s.mrays_on, s.mrays_off, s.mrays_on / s.mrays_off, s.mismatched ? " HITS DIFFER" : "");
        line += buf;
      }
      const std::string at =
          res ? std::to_string(res) + "^3" : "default (voxels; instance boxes for " + std::to_string(rep.box_points) + " points)";
      note("sweep %s %s: pool %" PRIu64 " B, convert %.2f s%s [%.1f s]", base_name(path).c_str(), at.c_str(), rep.dag_pool_bytes,
           convert_s, line.c_str(), since(t_res));
    }
  }
  return total_mismatch;
}

}  // namespace rtp::bench::dag
