#pragma once
// What every rtpack-bench mode (--out-of-core, --multi-hit, --packets, --dag) takes from the main command
// line: the scene, --allow-path, --kinds, --rays, --seed, --threads, --reps, --json and --isa. Each mode's
// config derives from it with its own defaults (set in its constructor) and its own options.
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "oracle/rays.h"
#include "trace/trace.h"

namespace rtp::bench {

struct ModeConfig {
  std::string scene_path;
  std::vector<std::string> allow_paths;  // --allow-path: further directories for external buffers
  std::vector<RayKind> kinds;            // per mode: its constructor sets the default
  size_t rays = size_t(1) << 16;         // per kind
  uint64_t seed = 1;
  int threads = 0;  // 0: all hardware threads
  int reps = 3;     // best of reps after one warm-up
  bool json = false;
  Isa isa = Isa::kScalar;
};

}  // namespace rtp::bench
