#pragma once
// Scalar reference of the W-wide ray/box slab test; the SIMD version (box_simd.h) computes the same
// operations in the same order, so both give bit-identical masks and entry distances.
#include "formats/bvh_layout.h"
#include "trace/kernels/kernel_common.h"

namespace rtp::RTP_ISA_NS {

// Ize 2013 "Robust BVH Ray Traversal" §3: sign-selected near/far planes per ray octant, reciprocal
// direction, NaN-dropping min/max, far distance padded by 1 + 2γ(3). Empty lanes (lo = +inf,
// hi = -inf) give near = +inf > far and never hit.
template <int W>
inline uint32_t box_test_scalar(const fmt::WideNode<W>& node, const detail::BoxRay& r, float tfar, float* dist) {
  uint32_t mask = 0;
  for (int i = 0; i < W; ++i) {
    float tn = r.tnear, tf = tfar;
    for (int a = 0; a < 3; ++a) {
      const bool neg = (r.octant >> a) & 1u;
      const float near_plane = neg ? node.hi[a][i] : node.lo[a][i];
      const float far_plane = neg ? node.lo[a][i] : node.hi[a][i];
      tn = max_keep((near_plane - r.org[a]) * r.rcp[a], tn);
      tf = min_keep((far_plane - r.org[a]) * r.rcp[a], tf);
    }
    tf = pad_far(tf);
    dist[i] = tn;
    if (tn <= tf) mask |= 1u << i;
  }
  return mask;
}

// The lanes of `mask` renumbered by the node's octant order: bit i set when lane order[i] is hit.
// Like pshufb, an order byte uses its low 4 bits and a byte with bit 7 set selects nothing.
template <int W>
inline uint32_t ordered_mask_scalar(uint32_t mask, const uint8_t* order) {
  uint32_t om = 0;
  for (int i = 0; i < W; ++i) {
    const uint8_t o = order[i];
    if (!(o & 0x80) && ((mask >> (o & 15)) & 1u)) om |= 1u << i;
  }
  return om;
}

}  // namespace rtp::RTP_ISA_NS
