#pragma once
// A minimal path tracer on the public streaming API (rtpack/rtpack.h RayStream), as a renderer writes
// one: the example render_paths.cpp built against the installed library, and rtpack-trace --path-trace. Lambert surfaces (an albedo per instance), a sky and a sun with
// shadow rays; paths in waves of `paths_in_flight`, each wave one flush whose callback submits every
// path's next bounce and shadow ray (Molenaar 2019 §5.3), or (refill) a new path whenever one ends. Each path's random numbers come from (seed,
// path, bounce) and its radiance is summed in a fixed order, so the image bytes depend on nothing but the
// package and these options: not on the budget, the threads, culling, or in core vs out of core.
#include <cstdint>
#include <string>
#include <vector>

#include "rtpack/rtpack.h"

namespace pathtracer {

struct PathTraceOptions {
  int width = 512, height = 512, camera = -1;
  uint32_t spp = 1, bounces = 2;
  uint32_t paths_in_flight = 16384;
  uint64_t seed = 1;
  rtpack::StreamOptions stream;  // cull, threads, ISA; max_in_flight is set from paths_in_flight
  // Start a new path as soon as one ends, keeping paths_in_flight paths live and the whole render one
  // flush, instead of waves that drain before the next starts. Same image.
  bool refill = false;
  bool progress = false;  // one line per wave (per tenth of the paths with refill) on stderr
};

struct PathTraceResult {
  std::vector<uint8_t> rgb;                // width * height * 3, top row first
  std::vector<rtpack::StreamStats> waves;  // one per flush
  rtpack::StreamStats total;
  uint64_t paths = 0;
  double seconds = 0;  // the whole render
};

PathTraceResult path_trace(const rtpack::Package& package, const PathTraceOptions& options);

}  // namespace pathtracer
