#pragma once
// SIMD watertight ray/triangle test over one SoA leaf block, generic over a vector type from
// simd_avx2.h / simd_avx512.h. Same operations, same order as triangle_test_scalar: bit-identical results.
#include <cfloat>

#include "formats/bvh_layout.h"
#include "trace/kernels/kernel_common.h"
#include "trace/kernels/kernels.h"

namespace rtp::RTP_ISA_NS {

// The sheared vertices relative to the ray and the edge functions of Woop, Benthin, Wald 2013 §3, with
// the lanes whose signs are not trusted (|u| within its float rounding bound of 0, and so on): those
// take the whole test in double (triangle_double), as the scalar kernel. Shared by the block test
// (lanes = triangles) and the packet test (lanes = rays, triangle_packet.h): the same operations in the
// same order, so both give each (ray, triangle) pair the same bits.
template <class V>
struct Sheared {
  V ax0, ay0, az, bz, cz, ax, ay, bx, by, cx, cy, u, v, w;
  uint32_t slow;
};
template <class V>
RTP_KERNEL_INLINE Sheared<V> shear(V p0x, V p0y, V p0z, V p1x, V p1y, V p1z, V p2x, V p2y, V p2z, V ox, V oy, V oz, V sx, V sy) {
  Sheared<V> e;
  e.az = p0z - oz, e.bz = p1z - oz, e.cz = p2z - oz;
  e.ax0 = p0x - ox, e.ay0 = p0y - oy;
  e.ax = e.ax0 - sx * e.az;
  e.ay = e.ay0 - sy * e.az;
  e.bx = (p1x - ox) - sx * e.bz;
  e.by = (p1y - oy) - sy * e.bz;
  e.cx = (p2x - ox) - sx * e.cz;
  e.cy = (p2y - oy) - sy * e.cz;
  e.u = e.cx * e.by - e.cy * e.bx;
  e.v = e.ax * e.cy - e.ay * e.cx;
  e.w = e.bx * e.ay - e.by * e.ax;
  const V kb = V::splat(kEdgeBound);
  const V eu = kb * (vabs(e.cx * e.by) + vabs(e.cy * e.bx));
  const V ev = kb * (vabs(e.ax * e.cy) + vabs(e.ay * e.cx));
  const V ew = kb * (vabs(e.bx * e.ay) + vabs(e.by * e.ax));
  e.slow = ((vabs(e.u) <= eu) | (vabs(e.v) <= ev) | (vabs(e.w) <= ew)).bits();
  return e;
}

// Woop, Benthin, Wald 2013 "Watertight Ray/Triangle Intersection" §3: shear by the dominant axis,
// edge functions, the whole test in double for the lanes where one is within its float rounding bound
// of 0 (triangle_double, scalar),
// two-sided sign test; t from the plane equation with the two shorter edges (see triangle_scalar.h),
// in [tnear, tfar] and finite;
// u = V / det, v = W / det.
template <class V, int B, bool kAny>
RTP_KERNEL_INLINE uint32_t triangle_test_simd(const fmt::LeafBlock<B>& blk, const detail::TriRay& r, float tfar,
                                              BlockHits<B>* out) {
  const int kx = r.kx, ky = r.ky, kz = r.kz;
  const V ox = V::splat(r.org_k[0]), oy = V::splat(r.org_k[1]), oz = V::splat(r.org_k[2]);
  const V sx = V::splat(r.sx), sy = V::splat(r.sy);
  const V zero = V::splat(0.0f);
  uint32_t mask = 0;
  for (int off = 0; off < B; off += V::kLanes) {
    const V p0x = V::load(&blk.v0[kx][off]), p0y = V::load(&blk.v0[ky][off]), p0z = V::load(&blk.v0[kz][off]);
    const V p1x = V::load(&blk.v1[kx][off]), p1y = V::load(&blk.v1[ky][off]), p1z = V::load(&blk.v1[kz][off]);
    const V p2x = V::load(&blk.v2[kx][off]), p2y = V::load(&blk.v2[ky][off]), p2z = V::load(&blk.v2[kz][off]);
    const Sheared<V> e = shear(p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z, ox, oy, oz, sx, sy);
    const V &ax0 = e.ax0, &ay0 = e.ay0, &az = e.az, &bz = e.bz, &cz = e.cz;
    const V &ax = e.ax, &ay = e.ay, &bx = e.bx, &by = e.by, &cx = e.cx, &cy = e.cy, &u = e.u, &v = e.v, &w = e.w;
    const uint32_t slow = e.slow;
    const auto inside = ((u >= zero) & (v >= zero) & (w >= zero)) | ((u <= zero) & (v <= zero) & (w <= zero));
    if (!(inside.bits() & ~slow) && !slow) continue;
    const V det = (u + v) + w;
    const V d01x = p1x - p0x, d01y = p1y - p0y, d01z = p1z - p0z;
    const V d12x = p2x - p1x, d12y = p2y - p1y, d12z = p2z - p1z;
    const V d20x = p0x - p2x, d20y = p0y - p2y, d20z = p0z - p2z;
    const V l01 = (d01x * d01x + d01y * d01y) + d01z * d01z;
    const V l12 = (d12x * d12x + d12y * d12y) + d12z * d12z;
    const V l20 = (d20x * d20x + d20y * d20y) + d20z * d20z;
    const auto skip12 = (l12 >= l01) & (l12 >= l20);  // (d01, d20) at p0
    const auto skip20 = l20 >= l01;                   // else (d12, d01) at p1, else (d20, d12) at p2
    const V eax = vselect(skip12, d01x, vselect(skip20, d12x, d20x));
    const V eay = vselect(skip12, d01y, vselect(skip20, d12y, d20y));
    const V eaz = vselect(skip12, d01z, vselect(skip20, d12z, d20z));
    const V ebx = vselect(skip12, d20x, vselect(skip20, d01x, d12x));
    const V eby = vselect(skip12, d20y, vselect(skip20, d01y, d12y));
    const V ebz = vselect(skip12, d20z, vselect(skip20, d01z, d12z));
    const V rx = vselect(skip12, ax0, vselect(skip20, p1x - ox, p2x - ox));
    const V ry = vselect(skip12, ay0, vselect(skip20, p1y - oy, p2y - oy));
    const V rz = vselect(skip12, az, vselect(skip20, bz, cz));
    const V nx = eay * ebz - eaz * eby, ny = eaz * ebx - eax * ebz, nz = eax * eby - eay * ebx;
    const V den = (nx * V::splat(r.dir_k[0]) + ny * V::splat(r.dir_k[1])) + nz * V::splat(r.dir_k[2]);
    const V num = (nx * rx + ny * ry) + nz * rz;
    // A ray nearly parallel to the plane: den within its rounding bound of 0 gives a garbage t (and
    // the sheared sliver may contain the ray only through rounding): those lanes go to double too.
    const V dsum = (vabs(eay * ebz) + vabs(eaz * eby)) * V::splat(std::fabs(r.dir_k[0])) +
                   (vabs(eaz * ebx) + vabs(eax * ebz)) * V::splat(std::fabs(r.dir_k[1])) +
                   (vabs(eax * eby) + vabs(eay * ebx)) * V::splat(std::fabs(r.dir_k[2]));
    const uint32_t grazing = (vabs(den) <= V::splat(kDenBound) * dsum).bits() & (inside & (det != zero)).bits();
    const uint32_t slow_all = slow | grazing;
    uint32_t slow_hit = 0;
    alignas(64) float st[V::kLanes], su[V::kLanes], sv[V::kLanes];
    if (slow_all) [[unlikely]] {
      alignas(64) float s6[6][V::kLanes];
      ax.store(s6[0]), ay.store(s6[1]), bx.store(s6[2]), by.store(s6[3]), cx.store(s6[4]), cy.store(s6[5]);
      for (uint32_t m = slow_all; m; m &= m - 1) {
        const int i = lowest_bit(m);
        const float q0[3] = {blk.v0[kx][off + i], blk.v0[ky][off + i], blk.v0[kz][off + i]};
        const float q1[3] = {blk.v1[kx][off + i], blk.v1[ky][off + i], blk.v1[kz][off + i]};
        const float q2[3] = {blk.v2[kx][off + i], blk.v2[ky][off + i], blk.v2[kz][off + i]};
        if (triangle_double(s6[0][i], s6[1][i], s6[2][i], s6[3][i], s6[4][i], s6[5][i], q0, q1, q2, r.org_k, r.dir_k, r.tnear,
                            tfar, &st[i], &su[i], &sv[i]))
          slow_hit |= 1u << i;
      }
      if constexpr (kAny)
        if (slow_hit) return slow_hit << off;
    }
    const V t = num / den;
    const uint32_t hit =
        (inside & (det != zero) & (t >= V::splat(r.tnear)) & (t <= V::splat(tfar)) & (vabs(t) <= V::splat(FLT_MAX))).bits();
    const uint32_t fast_hit = hit & ~slow_all;
    if (!fast_hit && !slow_hit) continue;
    if constexpr (kAny) return fast_hit << off;
    mask |= (fast_hit | slow_hit) << off;
    t.store(out->t + off);
    (v / det).store(out->u + off);
    (w / det).store(out->v + off);
    for (uint32_t m = slow_hit; m; m &= m - 1) {
      const int i = lowest_bit(m);
      out->t[off + i] = st[i], out->u[off + i] = su[i], out->v[off + i] = sv[i];
    }
  }
  return mask;
}

}  // namespace rtp::RTP_ISA_NS
