#pragma once
// rtpack-validate's path workload (--kinds path): what a renderer does, traced through the out-of-core
// tracer's ray stream (lib/trace/ray_stream.h) in waves under the budget (Molenaar 2019 §5.3): camera
// rays, at each closest hit a shadow ray toward a sun and a cosine-weighted bounce off the hit's
// geometric normal, submitted from the stream's callback while the round's points are resident. Every
// ray and its answer is kept, so rtpack-validate judges them like any other kind.
#include <cstdint>
#include <vector>

#include "formats/ray_file.h"
#include "reader/reader.h"
#include "trace/out_of_core.h"

namespace rtp::tools {

struct PathWorkload {
  std::vector<fmt::Ray> closest_rays;  // camera rays and bounces, by (path, depth)
  std::vector<fmt::Hit> closest_hits;  // the stream's answers
  std::vector<fmt::Ray> shadow_rays;   // any-hit rays toward the sun, by (path, depth)
  std::vector<uint8_t> occluded;       // the stream's answers
  size_t paths = 0;                    // camera rays
  uint32_t waves = 0;
  TracerStats stats;  // of all waves
};

struct PathWorkloadOptions {
  size_t paths = 10000;       // camera rays of a grid about this size
  uint32_t bounces = 2;       // bounce rays per path at most
  uint32_t waves = 4;         // paths are traced in this many flushes
  uint64_t seed = 1;          // bounce directions
  PackageTraceOptions trace;  // ISA, culling
};

// Adds the counts of s to total; the peaks are the larger of the two.
void accumulate(TracerStats& total, const TracerStats& s);

PathWorkload trace_path_workload(const PackageReader& reader, OutOfCoreTracer& tracer, const PathWorkloadOptions& options);

}  // namespace rtp::tools
