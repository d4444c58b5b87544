#pragma once
// The double judge for scenes too large for BruteForceReference (TESTING.md "The oracle": the double
// reference decides disputed rays; forest-2k has 10^8 instanced triangles). Nothing is flattened: per ray,
// each instance whose double world box the ray may pass, each run of 32 of its mesh's triangles whose
// box (its local corners moved to world space in double) the ray may pass, and each triangle moved to
// world space in double and tested as BruteForceReference tests it (Moller-Trumbore in double, the same
// tie rule). The boxes are conservative, so the answers are BruteForceReference's; the time goes with
// the instances a ray passes, so it judges a few disputed rays, not a ray set.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "oracle/reference.h"

namespace rtp {

class InstanceReference final : public ExactReference {
 public:
  /// Keeps a reference to `scene`, which must outlive it.
  explicit InstanceReference(const Scene& scene);

 private:
  struct Run {  // triangles [first, first + count) of a mesh and their local box
    double lo[3], hi[3];
    uint32_t first, count;
  };
  struct WorldBox {
    double lo[3], hi[3];
    bool usable;  // the instance's mesh exists and has triangles
  };
  template <bool kAny>
  bool trace(const fmt::Ray& ray, fmt::Hit* hit) const;
  bool trace_ray(const fmt::Ray& ray, fmt::Hit* hit) const override;

  const Scene& scene_;
  std::vector<std::vector<Run>> runs_;  // per mesh
  std::vector<WorldBox> boxes_;         // per instance, padded
};

}  // namespace rtp
