#pragma once
// rtpack-bench: the untimed check that every timed rtpack answer agrees with Embree ray by ray
// (lib/oracle/compare.h, TESTING.md), for closest and any hits.
#include <cstdint>
#include <string>
#include <vector>

#include "formats/ray_file.h"
#include "oracle/embree_oracle.h"
#include "oracle/rays.h"
#include "scene/scene.h"

namespace rtp::bench {

struct KindData {
  RayKind kind;
  bool any = false;  // timed as any-hit
  std::vector<fmt::Ray> rays;
  std::vector<fmt::Hit> ref_hits;                      // Embree closest hits (reference for both query types)
  std::vector<uint8_t> skip;                           // rays Embree cannot take: no reference
  RayCoherence coherence = RayCoherence::kIncoherent;  // how Embree is timed on these rays
  RayGenInfo info;
  uint64_t embree_timed_failures = 0;  // timed Embree answers (packets for primary) vs the stream reference
  size_t distinct_rays = 0;            // rays that differ in some byte (fewer than rays.size() with --hot-rays)
};

struct Agreement {
  uint64_t agree = 0, edge_ties = 0, precision_ties = 0, failures = 0, skipped = 0;
  std::string first_failure;
  // Rays where Embree disagrees and the double reference sides with rtpack (not in the counts above).
  uint64_t embree_errors = 0;
};

// Closest hits against Embree's (edge and precision ties classified on the scene).
Agreement agreement_closest(const Scene& scene, const KindData& k, const std::vector<fmt::Hit>& got);
// Any hit: against Embree's closest hit (ties classified through rtpack's own closest hit, computed
// untimed), and against rtpack's own closest hit (no ties allowed beyond edges).
Agreement agreement_any(const Scene& scene, const KindData& k, const std::vector<uint8_t>& occ,
                        const std::vector<fmt::Hit>& own_closest);

}  // namespace rtp::bench
