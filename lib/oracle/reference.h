#pragma once
// Brute-force reference in double precision for small scenes (TESTING.md "The oracle"): every
// instanced triangle is transformed to world space in double (the stored float transform applied to
// the float vertices, no rounding afterwards) and intersected with every ray (Moller-Trumbore in
// double). Triangles are grouped in runs of 32 with padded double boxes only to skip work; the boxes
// are conservative, so the answer is that of testing every triangle.
//
// It is the check on how we drive Embree (transform conventions, u/v, ids), not a tracer.
#include <cstddef>
#include <cstdint>
#include <vector>

#include "formats/ray_file.h"
#include "scene/scene.h"

namespace rtp {

// A double-precision judge of disputed rays (compare.h CompareOptions::exact).
class ExactReference {
 public:
  virtual ~ExactReference() = default;
  /// Closest hit in [tnear, tfar] (inclusive), ties broken by the smaller (instance, prim).
  /// Rays that are invalid by formats/ray_file.h miss. Parallel over rays (TBB).
  void closest(const fmt::Ray* rays, fmt::Hit* hits, size_t n) const;
  /// Any hit in [tnear, tfar].
  void occluded(const fmt::Ray* rays, uint8_t* occluded, size_t n) const;

 protected:
  /// One valid ray: the closest hit into *hit, or whether any hit exists (hit == nullptr).
  virtual bool trace_ray(const fmt::Ray& ray, fmt::Hit* hit) const = 0;
};

class BruteForceReference final : public ExactReference {
 public:
  /// Throws rtp::Error(kInputInvalid) when the scene has more than `max_triangles` instanced triangles.
  explicit BruteForceReference(const Scene& scene, uint64_t max_triangles = 4'000'000);

  // closest() and occluded() (ExactReference): rays with tnear < 0 or huge components are traced
  // (double handles them).

  uint64_t triangle_count() const { return tris_.size(); }

 private:
  struct Tri {
    double v0[3], e1[3], e2[3];
    uint32_t instance, prim;
  };
  struct Cluster {
    double lo[3], hi[3];
    uint32_t first, count;
  };
  template <bool kAny>
  bool trace(const fmt::Ray& ray, fmt::Hit* hit) const;
  bool trace_ray(const fmt::Ray& ray, fmt::Hit* hit) const override;

  std::vector<Tri> tris_;
  std::vector<Cluster> clusters_;
};

}  // namespace rtp
