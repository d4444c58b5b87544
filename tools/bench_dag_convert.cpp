// rtpack-bench --dag, part "convert" (tools/bench_dag.cpp describes it): the cost of the feature.
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

// ---------------------------------------------------------------------------------------------
// convert: the cost of the feature

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
    note("convert %s: %" PRIu64 " points; write_package %.3f s with DAGs vs %.3f s without (x%.2f); %" PRIu64 " vs %" PRIu64
         " B (+%.1f%%) [%.1f s]",
         base_name(path).c_str(), c.points, c.with_s, c.without_s, c.with_s / c.without_s, c.with_bytes, c.without_bytes,
         100.0 * (double(c.with_bytes) - double(c.without_bytes)) / double(c.without_bytes), since(t_scene));
    out.push_back(std::move(c));
  }
}

}  // namespace rtp::bench::dag
