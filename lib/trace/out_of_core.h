#pragma once
// The batched out-of-core package tracer (Molenaar 2019 §4.1 batching, §4.3 scheduling): the top
// level, the batching-point descriptors and the DAG pool stay resident; batching points and mesh
// segments come through a ChunkCache under a byte budget. A ray walks the top level (parent pointers,
// no stack) to its next batching point, is culled there by the point's DAG or queued at it, and
// resumes its walk after the point has been traced. Points are processed in rounds, most rays first,
// as many as the budget holds at once, all threads tracing them. A ray is queued at its next few points
// at once (set_speculation) and the answers are merged in walk order, so the hits are byte-identical to
// load_package_in_core()'s for every budget, thread count, ray order and depth.
#include <cstdint>
#include <memory>
#include <string>

#include "formats/ray_file.h"
#include "reader/chunk_cache.h"
#include "reader/reader.h"
#include "trace/package_tracer.h"
#include "trace/ray_stream.h"
#include "trace/tracer.h"

namespace rtp {

// The stats of an out-of-core call are TracerStats (tracer.h), all of their fields filled.
using OutOfCoreStats = TracerStats;

// The out-of-core implementation of Tracer (tracer.h): same results as the in-core tracer's closest /
// any / multi on all n rays at once. Parallel inside (TBB). The cache persists across calls. Multi-hit:
// a ray's N-th hit so far is its tfar when it resumes its walk, so later batching points beyond it are
// never queued.
class OutOfCoreTracer : public Tracer {
 public:
  bool out_of_core() const override { return true; }
  PackageLoadStats load_stats() const override { return {}; }
  // Reading the next round's likely chunks on a background I/O thread while a round traces, a quarter of
  // the budget kept for them (default off: every chunk is read, in parallel, when its round starts; on
  // this project's 2-core machine reading ahead was slower, docs/trace/budget.md). Same hits either way.
  virtual void set_prefetch(bool on) = 0;
  // How many batching points ahead a ray is queued at once for closest and any hits (1 .. 64, default
  // kDefaultSpeculation): each traced with the tfar the ray had when queued, the answers merged by (t,
  // walk order), so the hits are the same for every depth while the points of a round serve the rays
  // that reach them later in their walks too (fewer reloads). Depth 1 is the one-point-at-a-time walk.
  // Multi-hit always walks one point at a time.
  virtual void set_speculation(uint32_t depth) = 0;
  // A stream of rays for a renderer (ray_stream.h) over this tracer's cache; the tracer must outlive
  // it, and one call at a time runs on the tracer (a flush, or closest / any / multi).
  virtual std::unique_ptr<RayStream> open_stream(const StreamOptions& options) = 0;
};

// on_demand_bytes, minimum_budget, parse_memory_budget: tracer.h.

// Reads and checks the resident chunks; throws Error(kUsage) when budget_bytes < minimum_budget(),
// naming the minimum, and Error(kInputInvalid) naming a bad chunk (here or when a round loads it).
std::unique_ptr<OutOfCoreTracer> open_out_of_core(const PackageReader& reader, uint64_t budget_bytes);

}  // namespace rtp
