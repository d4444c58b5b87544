#pragma once
// The precomputed forms of a ray that the box and triangle kernels read, and the constants every ISA
// path shares. Plain structs; the functions that fill them are in ray_prep.h.
#include <cstdint>

#include "formats/ray_file.h"

// Issue 11: the kernels and per-ray set-up are forced inline into the walk. GCC left box_test_simd,
// triangle_test_simd and setup_box_ray out of line (each walk instantiation calls them from several
// places), which reloaded the ray from memory and ran a vzeroupper at every node.
#define RTP_KERNEL_INLINE inline __attribute__((always_inline))

namespace rtp::detail {

// Traversal stacks are sized for this many inner-node levels (lib/bvh's depth limit); a deeper
// (malformed) tree makes the ray come back as a miss counted in TraceStats::overflow_rays.
inline constexpr int kMaxDepth = 64;

// Ize 2013 "Robust BVH Ray Traversal" §3: far distances are scaled by 1 + 2γ(3); we round the factor
// up to 1 + 4 ulp(1) and apply it toward +inf whatever the sign (max(x·up, x·down)).
inline constexpr float kFarPadUp = 1.0f + 4.0f * 1.1920929e-7f;    // 1 + 2^-21
inline constexpr float kFarPadDown = 1.0f - 4.0f * 1.1920929e-7f;  // 1 - 2^-21

// A ray as the W-wide slab test reads it.
struct BoxRay {
  float org[3];
  float rcp[3];  // 1/dir, ±inf for a ±0 component (sign kept)
  float tnear;
  uint8_t octant;  // bit a = signbit(dir[a]): the near plane is hi, the far plane lo (WideNode::order row)
};

// A ray as the watertight triangle test reads it (Woop, Benthin, Wald 2013 §3): kz the dominant
// direction axis, kx/ky the other two (swapped when dir[kz] < 0 to keep the winding), shear sx, sy.
struct TriRay {
  int kx, ky, kz;
  float org_k[3];  // org[kx], org[ky], org[kz]
  float dir_k[3];  // dir[kx], dir[ky], dir[kz]
  float sx, sy;
  float tnear;
};

}  // namespace rtp::detail
