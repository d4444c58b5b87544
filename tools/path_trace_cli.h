#pragma once
// rtpack-trace --path-trace: the command around path_trace.h (options checked by rtpack-trace, the
// package opened through the public API, the PNG written whole or not at all, the per-wave report).
#include <cstdint>
#include <string>

namespace rtp::tools {

struct PathTraceCommand {
  std::string package, image, budget_text, isa = "best";
  int width = 512, height = 512, camera = -1, threads = 0;
  uint32_t spp = 1, bounces = 2, paths_in_flight = 16384;
  uint64_t seed = 1;
  bool no_cull = false, direct = false, json = false, refill = false;
};

int run_path_trace(const PathTraceCommand& c);

}  // namespace rtp::tools
