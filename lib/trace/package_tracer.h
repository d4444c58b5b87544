#pragma once
// Tracing through a package in core: every chunk loaded and checked, the 4-wide top level over
// batching points traversed front to back, each batching point's two-level wide BVH traced with
// lib/trace. (The batched out-of-core tracer reuses the same chunk views under a memory budget.)
#include <memory>
#include <string>
#include <vector>

#include "formats/ray_file.h"
#include "reader/reader.h"
#include "trace/trace.h"
#include "layout/dag_query.h"

namespace rtp {

struct PackageTraceOptions : TraceOptions {
  // Test each ray against a batching point's culling DAG before walking its BVH (Molenaar 2019 §3.2),
  // when the package has DAGs; the BVH walk then starts at the DAG's entry distance. The hits are the
  // same either way (rtpack-trace --no-cull).
  bool cull = true;
};

struct PackageTraceStats : TraceStats {
  uint64_t point_visits = 0;   // batching points whose box a ray entered within its interval
  uint64_t culled_visits = 0;  // of those, skipped because the DAG is empty along the ray
};

// What loading cost (rtpack-trace prints it): chunk reads with decompression, and the structural
// checks of check_chunks.h / voxel::check_dags that run on every chunk before any ray does.
struct PackageLoadStats {
  double total_seconds = 0, read_seconds = 0, check_seconds = 0;
  uint64_t chunks = 0, raw_bytes = 0, stored_bytes = 0;  // stored: bytes read from the file
};

class PackageTracer {
 public:
  virtual PackageLoadStats load_stats() const = 0;
  virtual ~PackageTracer() = default;
  // hits[i].instance is the scene instance index, hits[i].prim the triangle in its mesh.
  virtual PackageTraceStats closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n, const PackageTraceOptions& options) const = 0;
  virtual PackageTraceStats any(const fmt::Ray* rays, uint8_t* occluded, size_t n, const PackageTraceOptions& options) const = 0;
  // The N closest hits per ray across batching points, in trace_multi's layout (trace.h) with scene
  // instance indices: points front to back, each entered only while its entry distance is within the
  // N-th hit found so far (Gribble 2016 §2.1 node culling at the top level too). Ties at exactly the
  // N-th t across instances of one point are ordered by the point's local instance order.
  virtual PackageTraceStats multi(const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits, uint32_t* counts,
                                  const PackageTraceOptions& options) const = 0;
  virtual uint64_t batching_points() const = 0;
  virtual bool has_dags() const = 0;
  // One batching point on its own (for tests of culling): the closest hit of point p's geometry within
  // the ray's interval, no culling (hit.instance = scene instance; t = +inf on a miss) ...
  virtual fmt::Hit trace_point(size_t p, const fmt::Ray& ray, const TraceOptions& options) const = 0;
  // ... and the DAG test the tracer would apply to the ray at point p (culled = false without DAGs).
  virtual voxel::DagHit test_point_dag(size_t p, const fmt::Ray& ray) const = 0;
};

// Merges one batching point's sorted hits (`add`, local instance ids mapped through `global_ids`) into a
// ray's list of at most max_hits (hit_order_less, each triangle being in one point); returns the new
// count. `scratch` is reused. check_multi_hit_count throws Error(kUsage) for N outside [1, kMaxMultiHit].
uint32_t merge_point_hits(fmt::Hit* list, uint32_t count, uint32_t max_hits, const fmt::Hit* add, uint32_t n_add,
                          const uint32_t* global_ids, std::vector<fmt::Hit>& scratch);
void check_multi_hit_count(uint32_t max_hits);

// Reads and checks every chunk of the package (throws rtp::Error naming a bad chunk).
std::unique_ptr<PackageTracer> load_package_in_core(const PackageReader& reader);

// The validity rule of formats/ray_file.h (NaN/Inf, tnear > tfar, tnear = +inf are invalid).
bool ray_is_valid(const fmt::Ray& r);

}  // namespace rtp
