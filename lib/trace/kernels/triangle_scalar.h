#pragma once
// Scalar reference of the watertight ray/triangle test over one SoA leaf block; triangle_simd.h
// computes the same operations in the same order, so both give bit-identical t, u, v.
#include <cfloat>

#include "formats/bvh_layout.h"
#include "trace/kernels/kernel_common.h"
#include "trace/kernels/kernels.h"

namespace rtp::RTP_ISA_NS {

// Woop, Benthin, Wald 2013 "Watertight Ray/Triangle Intersection" §3: translate to the ray origin,
// shear so the ray is the +z axis, 2D edge functions U, V, W (the whole test in double when one is
// within its float rounding bound of 0: triangle_double),
// hit when all have one sign (two-sided). The hit/miss decision is Woop's; t is not his T / det, which
// loses up to ~1e-3 relative on needle triangles hit at grazing angles, but the plane equation
// t = dot(N, p - org) / dot(N, dir) (as Embree's robust Plücker test computes t), with N the cross
// product of the two shorter edges (vertex differences, nearly exact) and p their common vertex: those
// two edges meet at the largest angle, so N does not cancel even for needles. Hit: t in [tnear, tfar].
// u, v weight v1, v2 (formats/ray_file.h): u = V / det, v = W / det, det = U + V + W.
template <int B, bool kAny>
inline uint32_t triangle_test_scalar(const fmt::LeafBlock<B>& blk, const detail::TriRay& r, float tfar, BlockHits<B>* out) {
  const int kx = r.kx, ky = r.ky, kz = r.kz;
  uint32_t mask = 0;
  for (int i = 0; i < B; ++i) {
    const float az = blk.v0[kz][i] - r.org_k[2];
    const float bz = blk.v1[kz][i] - r.org_k[2];
    const float cz = blk.v2[kz][i] - r.org_k[2];
    const float ax0 = blk.v0[kx][i] - r.org_k[0], ay0 = blk.v0[ky][i] - r.org_k[1];
    const float ax = ax0 - r.sx * az;
    const float ay = ay0 - r.sy * az;
    const float bx = (blk.v1[kx][i] - r.org_k[0]) - r.sx * bz;
    const float by = (blk.v1[ky][i] - r.org_k[1]) - r.sy * bz;
    const float cx = (blk.v2[kx][i] - r.org_k[0]) - r.sx * cz;
    const float cy = (blk.v2[ky][i] - r.org_k[1]) - r.sy * cz;
    float u = cx * by - cy * bx;
    float v = ax * cy - ay * cx;
    float w = bx * ay - by * ax;
    const float eu = kEdgeBound * (std::fabs(cx * by) + std::fabs(cy * bx));
    const float ev = kEdgeBound * (std::fabs(ax * cy) + std::fabs(ay * cx));
    const float ew = kEdgeBound * (std::fabs(bx * ay) + std::fabs(by * ax));
    const float p0[3] = {blk.v0[kx][i], blk.v0[ky][i], blk.v0[kz][i]};
    const float p1[3] = {blk.v1[kx][i], blk.v1[ky][i], blk.v1[kz][i]};
    const float p2[3] = {blk.v2[kx][i], blk.v2[ky][i], blk.v2[kz][i]};
    // The lane in double (triangle_double); true when it is a hit, recorded in `out`.
    auto in_double = [&]() {
      float t, bu, bv;
      if (!triangle_double(ax, ay, bx, by, cx, cy, p0, p1, p2, r.org_k, r.dir_k, r.tnear, tfar, &t, &bu, &bv)) return false;
      if constexpr (!kAny) out->t[i] = t, out->u[i] = bu, out->v[i] = bv;
      return true;
    };
    if (std::fabs(u) <= eu || std::fabs(v) <= ev || std::fabs(w) <= ew) [[unlikely]] {
      if (!in_double()) continue;
      if constexpr (kAny) return 1u << i;
      mask |= 1u << i;
      continue;
    }
    const bool inside = (u >= 0.0f && v >= 0.0f && w >= 0.0f) || (u <= 0.0f && v <= 0.0f && w <= 0.0f);
    if (!inside) continue;
    const float det = (u + v) + w;
    if (!(det != 0.0f)) continue;
    const float d01[3] = {p1[0] - p0[0], p1[1] - p0[1], p1[2] - p0[2]};
    const float d12[3] = {p2[0] - p1[0], p2[1] - p1[1], p2[2] - p1[2]};
    const float d20[3] = {p0[0] - p2[0], p0[1] - p2[1], p0[2] - p2[2]};
    const float l01 = (d01[0] * d01[0] + d01[1] * d01[1]) + d01[2] * d01[2];
    const float l12 = (d12[0] * d12[0] + d12[1] * d12[1]) + d12[2] * d12[2];
    const float l20 = (d20[0] * d20[0] + d20[1] * d20[1]) + d20[2] * d20[2];
    // -N for every choice: cross(d01, d20) = cross(d12, d01) = cross(d20, d12).
    const float *ea = d20, *eb = d12;
    float rel[3];  // p - org for the common vertex p of ea and eb
    if (l12 >= l01 && l12 >= l20) {
      ea = d01, eb = d20;
      rel[0] = ax0, rel[1] = ay0, rel[2] = az;
    } else if (l20 >= l01) {
      ea = d12, eb = d01;
      rel[0] = p1[0] - r.org_k[0], rel[1] = p1[1] - r.org_k[1], rel[2] = bz;
    } else {
      rel[0] = p2[0] - r.org_k[0], rel[1] = p2[1] - r.org_k[1], rel[2] = cz;
    }
    const float nx = ea[1] * eb[2] - ea[2] * eb[1], ny = ea[2] * eb[0] - ea[0] * eb[2], nz = ea[0] * eb[1] - ea[1] * eb[0];
    const float den = (nx * r.dir_k[0] + ny * r.dir_k[1]) + nz * r.dir_k[2];
    const float num = (nx * rel[0] + ny * rel[1]) + nz * rel[2];
    const float dsum = (std::fabs(ea[1] * eb[2]) + std::fabs(ea[2] * eb[1])) * std::fabs(r.dir_k[0]) +
                       (std::fabs(ea[2] * eb[0]) + std::fabs(ea[0] * eb[2])) * std::fabs(r.dir_k[1]) +
                       (std::fabs(ea[0] * eb[1]) + std::fabs(ea[1] * eb[0])) * std::fabs(r.dir_k[2]);
    if (std::fabs(den) <= kDenBound * dsum) [[unlikely]] {  // nearly parallel: triangle_double decides
      if (!in_double()) continue;
      if constexpr (kAny) return 1u << i;
      mask |= 1u << i;
      continue;
    }
    if (!(den != 0.0f)) continue;  // the SIMD path divides and rejects the non-finite t
    const float t = num / den;
    if (!(t >= r.tnear && t <= tfar && std::fabs(t) <= FLT_MAX)) continue;
    if constexpr (kAny) return 1u << i;
    mask |= 1u << i;
    out->t[i] = t;
    out->u[i] = v / det;
    out->v[i] = w / det;
  }
  return mask;
}

}  // namespace rtp::RTP_ISA_NS
