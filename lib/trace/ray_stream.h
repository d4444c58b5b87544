#pragma once
// A stream of rays through an out-of-core package, for renderers (Molenaar 2019 §4.1 batching, §4.3
// scheduling, §5.3 path tracing in waves): rays are submitted at any time with a 64-bit payload, batched
// at their batching points by the out-of-core tracer's scheduler (batch_scheduler.h), and handed back
// with their answers between the scheduler's tracing passes; rays submitted then (a path's next bounce,
// its shadow ray) meet the points of the round while those are still resident. The answers are those
// of the in-core tracer, bit for bit, whatever the budget, thread count, culling and order of arrival.
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "formats/ray_file.h"
#include "trace/package_tracer.h"
#include "trace/tracer.h"

namespace rtp {

struct StreamRay {
  fmt::Ray ray;
  uint64_t payload = 0;  // handed back with the answer
  uint32_t any = 0;      // 1: any hit (occlusion) in [tnear, tfar]; 0: closest hit
  uint32_t reserved = 0;
};
static_assert(sizeof(StreamRay) == 48);

struct StreamResult {
  fmt::Hit hit;       // closest hit (scene instance, triangle in its mesh); t = +inf on a miss and for any hits
  float normal[3];    // unit geometric normal of the hit triangle (hit_normal.h); zeros on a miss / any hit
  uint32_t occluded;  // any hit: 1 when occluded; closest: 1 when hit
  uint64_t payload;
};
static_assert(sizeof(StreamResult) == 48);

struct StreamOptions {
  PackageTraceOptions trace;          // ISA, traversal order, culling (`cull`)
  uint32_t max_in_flight = 1u << 16;  // rays traced at once; the rest wait in submit()'s buffer
  uint32_t speculation = kDefaultSpeculation;
};

class RayStream {
 public:
  virtual ~RayStream() = default;
  // Buffers n rays (copied). From any one thread at a time: before flush(), or from its callback.
  virtual void submit(const StreamRay* rays, size_t n) = 0;
  // Called with the answered rays between tracing passes, on flush()'s thread, one batch at a time; it
  // may submit() rays, which join the current round.
  using Deliver = std::function<void(const StreamResult* results, size_t n)>;
  // Traces until every submitted ray, and every ray submitted from `deliver`, is answered. The stats are
  // those of this flush (TracerStats with rays = rays traced).
  virtual TracerStats flush(const Deliver& deliver) = 0;
};

}  // namespace rtp
