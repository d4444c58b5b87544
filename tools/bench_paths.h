#pragma once
// rtpack-bench SCENE --out-of-core PKG --kinds path: the renderer's workload (Molenaar 2019 §5.3, Figures
// 9 and 12: render time and bytes read against the geometry budget, culling on and off). The path tracer
// of docs/examples/path_trace through the public API's RayStream, per budget x culling x paths in flight,
// against the same paths in core (the package resident, after a warm-up render) and through Embree in
// core (its faster path of one call per ray and 1M streams, same run). Every out-of-core image must be the
// in-core one byte for byte.
#include <cstdint>
#include <string>
#include <vector>

#include "bench_budget.h"

namespace rtp::bench {

struct PathBenchConfig {
  std::vector<uint32_t> paths_in_flight = {4096, 16384};
  std::string paths_text;  // --paths-in-flight as given
  std::string size = "512x512";
  uint32_t spp = 1, bounces = 2;
  int camera = -1;  // the package's glTF camera (-1: the first, or one framing the scene)
  bool refill = false;
};

// Registers --paths-in-flight, --path-size, --path-camera, --spp, --bounces and --refill (each needs `ooc`).
void add_path_options(CLI::App& app, PathBenchConfig& cfg, CLI::Option* ooc);

// Prints the table (stdout, or stderr with --json, the records then on stdout). Returns kInternal when an
// out-of-core image differs from the in-core one.
int run_path_bench(BudgetBenchConfig budget, PathBenchConfig cfg);

}  // namespace rtp::bench
