#pragma once
// One interface for tracing rays through a package, whole arrays at a time, in core or out of core:
// tools and the public API open one with open_tracer() and call it; neither loops over ray blocks or
// threads itself. Both implementations give the same answers bit for bit (the out-of-core tracer's
// hits are byte-identical to the in-core one's for every budget, thread count and ray order).
#include <cstdint>
#include <memory>
#include <string>

#include "formats/ray_file.h"
#include "reader/chunk_cache.h"
#include "reader/reader.h"
#include "trace/package_tracer.h"

namespace rtp {

inline constexpr uint32_t kDefaultSpeculation = 16;

// The stats of one call. The in-core tracer fills the PackageTraceStats part; the out-of-core tracer
// (out_of_core.h) fills its rounds, cache and peak-memory fields too.
struct TracerStats : PackageTraceStats {
  uint64_t rounds = 0;               // scheduling rounds (a set of batching points made resident)
  uint64_t passes = 0;               // tracing passes over them (rays moving between points of a round)
  uint64_t dag_tests = 0;            // rays tested against a point's culling DAG before it was loaded
  ChunkCacheStats cache;             // chunks loaded, bytes read, hit rate, peak resident cache bytes
  uint64_t budget_bytes = 0;         // the cache's budget
  uint64_t fixed_bytes = 0;          // resident always: top level, descriptors, DAG pool
  uint64_t peak_ray_bytes = 0;       // per-ray state and ray queues at their largest
  uint64_t peak_resident_bytes = 0;  // fixed + cache + rays, at the largest moment
  double walk_seconds = 0;           // top-level walks and DAG culling (between rounds, in parallel)
  double trace_seconds = 0;          // batching-point BVH traversal
  double load_seconds = 0;           // reading, decompressing and checking chunks
  double total_seconds = 0;
};

class Tracer {
 public:
  virtual ~Tracer() = default;
  // All n rays at once, parallel inside (TBB, in the caller's arena: a tbb::task_arena or
  // tbb::global_control around the call sets the threads). One call at a time per out-of-core
  // tracer (its cache is its state); the in-core tracer takes concurrent calls.
  // hits[i].instance is the scene instance index, hits[i].prim the triangle in its mesh.
  virtual TracerStats closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n, const PackageTraceOptions& o) = 0;
  virtual TracerStats any(const fmt::Ray* rays, uint8_t* occluded, size_t n, const PackageTraceOptions& o) = 0;
  // The N closest hits per ray, trace_multi's layout (trace.h).
  virtual TracerStats multi(const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits, uint32_t* counts,
                            const PackageTraceOptions& o) = 0;
  virtual bool has_dags() const = 0;
  virtual bool out_of_core() const = 0;
  // What loading every chunk cost (in core); zeros out of core, whose loads are in each call's stats.
  virtual PackageLoadStats load_stats() const = 0;
};

// The decompressed bytes of the chunks tracing reads on demand (batching points and mesh segments):
// what "--memory-budget 10%" is a percentage of.
uint64_t on_demand_bytes(const PackageReader& reader);
// The smallest budget the tracer accepts: the largest batching point with its mesh segments.
uint64_t minimum_budget(const PackageReader& reader);
// "268435456", "256MiB", "1.5GiB", "64MB", "512KiB", "10%" (of on_demand) -> bytes; throws
// Error(kUsage) naming the text when it is none of these.
uint64_t parse_memory_budget(const std::string& text, uint64_t on_demand);

struct TracerConfig {
  // 0: every chunk loaded and checked up front (in core). Otherwise the out-of-core batched tracer's
  // cache budget in bytes (at least minimum_budget(reader), or open_tracer throws Error(kUsage)).
  uint64_t memory_budget = 0;
  bool prefetch = false;                       // OutOfCoreTracer::set_prefetch (out_of_core.h)
  uint32_t speculation = kDefaultSpeculation;  // OutOfCoreTracer::set_speculation
};

// `reader` must outlive the tracer. Throws Error(kInputInvalid) naming a bad chunk.
std::unique_ptr<Tracer> open_tracer(const PackageReader& reader, const TracerConfig& config = {});
// The in-core tracer over an already loaded PackageTracer (which must outlive it): for callers that also
// use the loaded package's per-point calls (trace_point, test_point_dag).
std::unique_ptr<Tracer> in_core_tracer(const PackageTracer& loaded);

}  // namespace rtp
