#pragma once
// rtpack-bench SCENE --multi-hit 1,2,...,64: the N closest hits per ray, same rays, same run: rtpack's
// node-culling traversal (Gribble 2016 §2.1) against its naive collect-all baseline and against
// Embree 3's reject-intersection filter that gathers every hit (Gribble 2016 §2.2). Node culling must
// equal collect-all bit for bit; agreement with Embree is counted per ray.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

#include "bench_mode.h"

namespace rtp::bench {

struct MultiHitBenchConfig : ModeConfig {
  MultiHitBenchConfig() { kinds = {RayKind::kRandom, RayKind::kBounce}; }
  std::string ks_text;  // --multi-hit as given
  std::vector<uint32_t> ks;
};

// Registers --multi-hit LIST (returned, for the caller's excludes).
CLI::Option* add_multi_hit_options(CLI::App& app, MultiHitBenchConfig& cfg);

// Prints the table (stdout, or stderr with --json and the records on stdout). Returns kInternal when
// node culling and collect-all differ on some ray; throws Error(kUsage) for a bad list.
int run_multi_hit_bench(MultiHitBenchConfig cfg);

}  // namespace rtp::bench
