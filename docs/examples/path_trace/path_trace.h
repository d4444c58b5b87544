#pragma once
// A minimal path tracer on the public streaming API (rtpack/rtpack.h RayStream), as a renderer writes
// one: the example render_paths.cpp, built against the installed library, and rtpack-trace --path-trace.
// Lambert surfaces (an albedo per instance), a sky and a sun with shadow rays; paths in waves of
// `paths_in_flight`, each wave one flush whose callback submits every path's next bounce and shadow ray
// (Molenaar 2019 §5.3), or (refill) a new path whenever one ends. Each path's random numbers come from
// (seed, path, bounce) and its radiance is summed in a fixed order, so the image bytes depend on nothing
// but the package and these options: not on the budget, the threads, culling, or in core vs out of core.
#include <cstdint>
#include <functional>
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

// What the paths are traced with: the contract of rtpack::RayStream (submit, and a flush whose callback
// may submit). rtpack-bench drives Embree in core through one, to time the same paths.
class RayTracer {
 public:
  virtual ~RayTracer() = default;
  virtual void submit(const rtpack::StreamRay* rays, size_t count) = 0;
  virtual rtpack::StreamStats flush(const std::function<void(const rtpack::StreamHit*, size_t)>& on_hits) = 0;
};

// Renders `camera` (width x height rays, row-major, from Package::camera_rays) of a scene within `bounds`.
PathTraceResult path_trace(RayTracer& tracer, const std::vector<rtpack::Ray>& camera, const rtpack::Bounds& bounds,
                           const PathTraceOptions& options);
// The package's camera through a RayStream of the package (options.stream; its max_in_flight is
// 2 paths_in_flight, at least 1024).
PathTraceResult path_trace(const rtpack::Package& package, const PathTraceOptions& options);

}  // namespace pathtracer
