#pragma once
// rtpack-bench --dag: what the occlusion-culling DAGs (issue 8, Molenaar 2019 §3.2–3.3, §4.2, §5.2)
// cost and buy, measured in one process: DAG bytes of single models alone and in one shared pool,
// single-thread voxelization time, the resolution sweep (pool bytes, cull rate, in-core tracing with
// culling on vs off on the same package and rays, hits checked identical), and the convert cost
// (time and package bytes with and without DAGs). tools/bench_dag.cpp describes each part.
#include <cstdint>
#include <string>
#include <vector>

#include "bench_mode.h"

namespace CLI {
class App;
class Option;
}  // namespace CLI

namespace rtp::bench {

struct DagBenchConfig : ModeConfig {
  DagBenchConfig() {
    kinds = {RayKind::kBounce, RayKind::kRandom};
    rays = size_t(1) << 17;
  }
  std::vector<std::string> scenes;                              // scene_path first, then the positional list of further scenes
  std::vector<std::string> parts{"proxy", "sweep", "convert"};  // --parts
  std::vector<uint32_t> resolutions{32, 64, 128, 256, 512};     // --resolutions (sweep)
  uint32_t proxy_resolution = 128;                              // --proxy-resolution (proxy part)
  TraversalOrder order = TraversalOrder::kOctantStack;
};

// Adds --dag, its own options (--parts, --resolutions, --proxy-resolution) and the positional list of
// further scenes to rtpack-bench's command line; returns the --dag flag.
CLI::Option* add_dag_options(CLI::App& app, DagBenchConfig& cfg);

// Runs the benchmark. Returns 0, or 5 (ExitCode::kInternal) when the hits with culling on differ from
// the hits with culling off on any ray (the numbers are printed, but they are worth nothing).
int run_dag_bench(const DagBenchConfig& cfg);

}  // namespace rtp::bench
