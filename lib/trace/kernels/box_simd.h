#pragma once
// SIMD W-wide ray/box slab test, generic over a vector type from simd_avx2.h / simd_avx512.h.
// Same operations, same order as box_test_scalar (box_scalar.h): bit-identical masks and distances.
#include <cstddef>

#include "formats/bvh_layout.h"
#include "trace/kernels/kernel_common.h"

namespace rtp::RTP_ISA_NS {

// A ray as one walk's node tests read it, set up once per walk (issue 11: the broadcasts and the
// sign-selected plane offsets used to be redone at every node): origin, reciprocal direction and tnear
// in every lane, and for each axis the float offset of the near and far planes within a WideNode
// (lo at 0, hi at 3W: WideNode keeps hi right after lo).
template <class V>
struct SimdNodeRay {
  V ox, oy, oz, rx, ry, rz, tnear;
  uint32_t near_off[3], far_off[3];
};

// The near and far plane offsets of each octant (issue 11: computed per axis with branches, ≈30
// instructions per walk set-up; a row of this table is two loads).
template <int W>
struct PlaneOffsets {
  uint32_t off[8][6];  // [octant][near x, y, z, far x, y, z]
  constexpr PlaneOffsets() : off{} {
    for (int o = 0; o < 8; ++o)
      for (int a = 0; a < 3; ++a) {
        const bool neg = (o >> a) & 1;
        off[o][a] = uint32_t((neg ? 3 * W : 0) + a * W);
        off[o][3 + a] = uint32_t((neg ? 0 : 3 * W) + a * W);
      }
  }
};
template <int W>
inline constexpr PlaneOffsets<W> kPlaneOffsets{};

template <class V, int W>
RTP_KERNEL_INLINE SimdNodeRay<V> simd_node_ray(const detail::BoxRay& r) {
  static_assert(offsetof(fmt::WideNode<W>, hi) == 3 * W * sizeof(float));
  SimdNodeRay<V> n{V::splat(r.org[0]),
                   V::splat(r.org[1]),
                   V::splat(r.org[2]),
                   V::splat(r.rcp[0]),
                   V::splat(r.rcp[1]),
                   V::splat(r.rcp[2]),
                   V::splat(r.tnear),
                   {},
                   {}};
  const uint32_t* row = kPlaneOffsets<W>.off[r.octant & 7];
  for (int a = 0; a < 3; ++a) n.near_off[a] = row[a], n.far_off[a] = row[3 + a];
  return n;
}

// Ize 2013 "Robust BVH Ray Traversal" §3: sign-selected planes per octant, NaN-dropping vmin/vmax
// (candidate first, accumulator second), far distance padded by 1 + 2γ(3) toward +inf.
template <class V, int W>
RTP_KERNEL_INLINE uint32_t box_test_simd(const fmt::WideNode<W>& node, const SimdNodeRay<V>& r, float tfar, float* dist) {
  const float* planes = &node.lo[0][0];
  const float* near_x = planes + r.near_off[0];
  const float* near_y = planes + r.near_off[1];
  const float* near_z = planes + r.near_off[2];
  const float* far_x = planes + r.far_off[0];
  const float* far_y = planes + r.far_off[1];
  const float* far_z = planes + r.far_off[2];
  const V tfar_v = V::splat(tfar);
  const V up = V::splat(detail::kFarPadUp), down = V::splat(detail::kFarPadDown);
  uint32_t mask = 0;
  for (int off = 0; off < W; off += V::kLanes) {
    V tn = vmax((V::load(near_x + off) - r.ox) * r.rx, r.tnear);
    V tf = vmin((V::load(far_x + off) - r.ox) * r.rx, tfar_v);
    tn = vmax((V::load(near_y + off) - r.oy) * r.ry, tn);
    tf = vmin((V::load(far_y + off) - r.oy) * r.ry, tf);
    tn = vmax((V::load(near_z + off) - r.oz) * r.rz, tn);
    tf = vmin((V::load(far_z + off) - r.oz) * r.rz, tf);
    tf = vmax(tf * up, tf * down);
    tn.store(dist + off);
    mask |= (tn <= tf).bits() << off;
  }
  return mask;
}

}  // namespace rtp::RTP_ISA_NS
