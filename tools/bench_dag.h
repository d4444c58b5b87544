#pragma once
// rtpack-bench --dag: what the occlusion-culling DAGs (issue 8, Molenaar 2019 §3.2–3.3, §4.2, §5.2)
// cost and buy, measured in one process: DAG bytes of single models alone and in one shared pool,
// single-thread voxelization time, the resolution sweep (pool bytes, cull rate, in-core tracing with
// culling on vs off on the same package and rays, hits checked identical), and the convert cost
// (time and package bytes with and without DAGs). tools/bench_dag.cpp describes each part.
#include <cstdint>
#include <string>
#include <vector>

#include "oracle/rays.h"
#include "trace/trace.h"

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace rtp::bench {

struct DagBenchConfig {
  std::vector<std::string> scenes;                                 // the first comes from rtpack-bench's SCENE positional
  std::vector<std::string> allow_paths;                            // --allow-path: further directories for external buffers
  std::vector<std::string> parts{"proxy", "sweep", "convert"};     // --parts
  std::vector<uint32_t> resolutions{32, 64, 128, 256, 512};        // --resolutions (sweep)
  uint32_t proxy_resolution = 128;                                 // --proxy-resolution (proxy part)
  size_t rays = size_t(1) << 17;                                   // per kind (rtpack-bench --rays)
  std::vector<RayKind> kinds{RayKind::kBounce, RayKind::kRandom};  // rtpack-bench --kinds
  uint64_t seed = 1;
  Isa isa = Isa::kScalar;
  TraversalOrder order = TraversalOrder::kOctantStack;
  int threads = 0;  // 0 = all hardware threads (tracing and converting)
  int reps = 3;     // best of reps after one warm-up
  bool json = false;
};

// Adds --dag, its own options (--parts, --resolutions, --proxy-resolution) and the positional list of
// further scenes to rtpack-bench's command line; returns the --dag flag.
CLI::Option* add_dag_options(CLI::App& app, DagBenchConfig& cfg);

// Runs the benchmark. Returns 0, or 5 (ExitCode::kInternal) when the hits with culling on differ from
// the hits with culling off on any ray (the numbers are printed, but they are worth nothing).
int run_dag_bench(const DagBenchConfig& cfg);

}  // namespace rtp::bench
