// rtpack-bench --dag: helpers shared by its parts (tools/bench_dag_parts.h).
#include <cstdarg>
#include <cstdio>

#include "bench_dag_parts.h"
#include "core/error.h"
#include "core/utf8.h"
#include "mesh/prepare.h"
#include "scene/import.h"

namespace rtp::bench::dag {

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

Prepared load(const std::string& path, uint64_t chunk_target, const std::vector<std::string>& allow_paths) {
  Prepared p;
  auto t0 = Clock::now();
  ImportOptions io;
  io.allowed_dirs = allow_paths;
  p.scene = import_gltf(path, io);
  p.import_s = since(t0);
  t0 = Clock::now();
  PrepareOptions prep;  // rtpack-convert's defaults: no weld, no subdivision, no half-edge analysis
  prep.clean.topology = false;
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
  cv.zstd_level = kDefaultZstdLevel;
  cv.dag = dag;
  cv.voxel.resolution = resolution;
  cv.metadata = {{"tool_version", "rtpack " RTP_VERSION " (rtpack-bench --dag)"}, {"source", base_name(scene_path)}};
  return cv;
}

}  // namespace rtp::bench::dag
