#pragma once
// rtpack-bench --dag, shared by its parts (tools/bench_dag.cpp describes them): timing helpers, the
// scene as rtpack-convert prepares it, and the records each part fills.
#include <chrono>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <map>
#include <string>
#include <system_error>
#include <unistd.h>
#include <vector>

#include "bench_dag.h"
#include "bench_timing.h"
#include "cluster/cluster.h"
#include "package/write_package.h"
#include "scene/scene.h"

namespace rtp::bench::dag {

namespace fs = std::filesystem;
inline constexpr size_t kGrain = 256;  // rays per TBB task (rtpack-trace's grain)

inline double since(Clock::time_point t0) { return seconds_since(t0); }

// A progress line on stderr, "[dag] ..."
void note(const char* fmt_, ...) __attribute__((format(printf, 1, 2)));
std::string base_name(const std::string& path);

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

// Imported (buffers also from allow_paths), prepared (rtpack-convert's defaults) and planned with this
// chunk target (0 = derived).
Prepared load(const std::string& path, uint64_t chunk_target, const std::vector<std::string>& allow_paths);
// rtpack-convert's defaults (W=8, B=8, collapse, zstd 9) with DAGs on or off at this resolution (0 = chosen).
ConvertOptions convert_options(const std::string& scene_path, bool dag, uint32_t resolution);

struct ProxyRecord {
  std::string scene;
  uint64_t unique = 0, instanced = 0, points = 0;
  uint32_t resolution = 0;
  uint64_t set_cells = 0, svo_bytes = 0, dag_bytes = 0, own_pool_bytes = 0;
  uint64_t loop_triangles = 0;  // piece triangles the triangle loop voxelizes (instances go through MeshProxies)
  double voxelize_s = 0, loop_s = 0, build_dag_s = 0;
  int voxel_reps = 0;
};

// proxy: each scene as one batching point at cfg.proxy_resolution; shared_bytes = every scene in one pool.
void run_proxy(const DagBenchConfig& cfg, std::vector<ProxyRecord>& out, uint64_t& shared_bytes);

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

// sweep: returns the number of rays whose hits differ with culling on and off (must be 0).
int64_t run_sweep(const DagBenchConfig& cfg, int threads, std::vector<SweepRecord>& out);

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

void run_convert(const DagBenchConfig& cfg, int threads, std::vector<ConvertCost>& out);

}  // namespace rtp::bench::dag
