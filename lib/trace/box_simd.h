#pragma once
// SIMD W-wide ray/box slab test, generic over a vector type from simd_avx2.h / simd_avx512.h.
// Same operations, same order as box_test_scalar (box_scalar.h): bit-identical masks and distances.
#include "formats/bvh_layout.h"
#include "trace/kernel_common.h"

namespace rtp::RTP_ISA_NS {

// Ize 2013 "Robust BVH Ray Traversal" §3: sign-selected planes per octant, NaN-dropping vmin/vmax
// (candidate first, accumulator second), far distance padded by 1 + 2γ(3) toward +inf.
template <class V, int W>
inline uint32_t box_test_simd(const fmt::WideNode<W>& node, const detail::BoxRay& r, float tfar, float* dist) {
  const float* lo = &node.lo[0][0];
  const float* hi = &node.hi[0][0];
  const float* near_x = r.neg[0] ? hi : lo;
  const float* near_y = (r.neg[1] ? hi : lo) + W;
  const float* near_z = (r.neg[2] ? hi : lo) + 2 * W;
  const float* far_x = r.neg[0] ? lo : hi;
  const float* far_y = (r.neg[1] ? lo : hi) + W;
  const float* far_z = (r.neg[2] ? lo : hi) + 2 * W;
  const V ox = V::splat(r.org[0]), oy = V::splat(r.org[1]), oz = V::splat(r.org[2]);
  const V rx = V::splat(r.rcp[0]), ry = V::splat(r.rcp[1]), rz = V::splat(r.rcp[2]);
  const V tnear = V::splat(r.tnear), tfar_v = V::splat(tfar);
  const V up = V::splat(detail::kFarPadUp), down = V::splat(detail::kFarPadDown);
  uint32_t mask = 0;
  for (int off = 0; off < W; off += V::kLanes) {
    V tn = vmax((V::load(near_x + off) - ox) * rx, tnear);
    V tf = vmin((V::load(far_x + off) - ox) * rx, tfar_v);
    tn = vmax((V::load(near_y + off) - oy) * ry, tn);
    tf = vmin((V::load(far_y + off) - oy) * ry, tf);
    tn = vmax((V::load(near_z + off) - oz) * rz, tn);
    tf = vmin((V::load(far_z + off) - oz) * rz, tf);
    tf = vmax(tf * up, tf * down);
    tn.store(dist + off);
    mask |= (tn <= tf).bits() << off;
  }
  return mask;
}

}  // namespace rtp::RTP_ISA_NS
