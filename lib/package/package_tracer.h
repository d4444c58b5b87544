#pragma once
// Tracing through a package in core: every chunk loaded and checked, the 4-wide top level over
// batching points traversed front to back, each batching point's two-level wide BVH traced with
// lib/trace. (The batched out-of-core tracer reuses the same chunk views under a memory budget.)
#include <memory>
#include <string>
#include <vector>

#include "formats/ray_file.h"
#include "package/package.h"
#include "trace/trace.h"

namespace rtp {

class PackageTracer {
 public:
  virtual ~PackageTracer() = default;
  // hits[i].instance is the scene instance index, hits[i].prim the triangle in its mesh.
  virtual TraceStats closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n, const TraceOptions& options) const = 0;
  virtual TraceStats any(const fmt::Ray* rays, uint8_t* occluded, size_t n, const TraceOptions& options) const = 0;
  virtual uint64_t batching_points() const = 0;
};

// Reads and checks every chunk of the package (throws rtp::Error naming a bad chunk).
std::unique_ptr<PackageTracer> load_package_in_core(const PackageReader& reader);

// The validity rule of formats/ray_file.h (NaN/Inf, tnear > tfar, tnear = +inf are invalid).
bool ray_is_valid(const fmt::Ray& r);

}  // namespace rtp
