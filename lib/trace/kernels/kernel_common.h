#pragma once
// Scalar pieces every ISA's kernels share. Included only by the ISA translation units, inside their
// own namespace (RTP_ISA_NS), so code built with different -m flags never merges at link time.
#include <cfloat>
#include <cmath>
#include <cstdint>

#include "formats/bvh_layout.h"
#include "trace/kernels/ray_setup.h"

#ifndef RTP_ISA_NS
#error "define RTP_ISA_NS (scalar, avx2, avx512) before including lib/trace kernel headers"
#endif

namespace rtp::RTP_ISA_NS {

// The forms of min/max that SIMD min/max instructions implement: on NaN (or ±0 ties) the second
// operand wins, so `acc = max_keep(candidate, acc)` drops a NaN candidate (0·inf from a zero direction
// component with the origin on a box plane: that slab does not constrain the ray).
inline float max_keep(float candidate, float acc) { return candidate > acc ? candidate : acc; }
inline float min_keep(float candidate, float acc) { return candidate < acc ? candidate : acc; }

// Ize 2013 "Robust BVH Ray Traversal" §3: far distance scaled by 1 + 2γ(3), toward +inf for either sign.
RTP_KERNEL_INLINE float pad_far(float t) { return max_keep(t * detail::kFarPadUp, t * detail::kFarPadDown); }

// double -> float without the undefined out-of-range conversion: beyond FLT_MAX gives ±inf, NaN stays NaN.
inline float to_float(double x) {
  if (std::fabs(x) <= double(FLT_MAX)) return static_cast<float>(x);
  return x > 0 ? INFINITY : (x < 0 ? -INFINITY : NAN);
}

// Woop, Benthin, Wald 2013 §3: an edge function that is exactly 0 in float is recomputed in double
// (products of floats are exact there), then rounded back, so a shared edge gets one consistent sign.
inline void edge_functions_double(float ax, float ay, float bx, float by, float cx, float cy, float* u, float* v, float* w) {
  const double cxby = double(cx) * double(by), cybx = double(cy) * double(bx);
  const double axcy = double(ax) * double(cy), aycx = double(ay) * double(cx);
  const double bxay = double(bx) * double(ay), byax = double(by) * double(ax);
  *u = to_float(cxby - cybx);
  *v = to_float(axcy - aycx);
  *w = to_float(bxay - byax);
}

// When a float edge function is within its rounding bound of 0 its sign is not trusted (Woop 2013 §3
// falls back to double only at exactly 0): |u| <= kEdgeBound * (|a·b| + |c·d|) for u = a·b − c·d
// (float error ≤ 1.5·2^-24 of that sum; the bound is 2^-21). A lane whose sign is trusted agrees with
// the double value, so a shared edge still gets one sign whichever side falls back.
inline constexpr float kEdgeBound = 1.0f / 2097152.0f;
// The plane-equation t = num / den, den = N·dir: for a ray within ~0.06° of the triangle's plane
// (|den| <= 2^-10 · Σ|N_k terms|·|dir_k|) the float num and den cancel (t came out as 0, 0.25, 16 on
// real meshes, for rays that cross the plane far outside the triangle): such lanes are tested in double.
inline constexpr float kDenBound = 1.0f / 1024.0f;

// The whole test in double for such a lane, from the same float sheared coordinates (watertight) and
// the same float vertices: signs of the double edge functions; t from the plane equation in double
// (float differences are exact there), so a ray nearly parallel to a sliver-thin projection does not
// get the garbage t of a cancelled float dot product; and the plane crossing must lie on the triangle
// within 1e-3 in barycentric terms (a ray whose sheared image falls within rounding of a sliver while
// it crosses the plane far outside the triangle is a miss). p0, p1, p2, org, dir in (kx, ky, kz) order.
inline bool triangle_double(float ax, float ay, float bx, float by, float cx, float cy, const float p0[3], const float p1[3],
                            const float p2[3], const float org[3], const float dir[3], float tnear, float tfar, float* t_out,
                            float* u_out, float* v_out) {
  const double u = double(cx) * by - double(cy) * bx, v = double(ax) * cy - double(ay) * cx,
               w = double(bx) * ay - double(by) * ax;
  if (!((u >= 0 && v >= 0 && w >= 0) || (u <= 0 && v <= 0 && w <= 0))) return false;
  const double det = (u + v) + w;
  if (!(det != 0)) return false;
  double e1[3], e2[3], rel[3];
  for (int k = 0; k < 3; ++k) e1[k] = double(p1[k]) - p0[k], e2[k] = double(p2[k]) - p0[k], rel[k] = double(p0[k]) - org[k];
  const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  const double den = n[0] * dir[0] + n[1] * dir[1] + n[2] * dir[2];
  const double num = n[0] * rel[0] + n[1] * rel[1] + n[2] * rel[2];
  if (!(den != 0)) return false;
  const double t = num / den;
  if (!std::isfinite(t)) return false;
  // Barycentrics of the crossing in the plane of the largest normal component.
  int a = 0;
  for (int k = 1; k < 3; ++k)
    if (std::fabs(n[k]) > std::fabs(n[a])) a = k;
  const int i = (a + 1) % 3, j = (a + 2) % 3;
  const double q[2] = {t * dir[i] - rel[i], t * dir[j] - rel[j]};  // crossing − p0
  const double d2 = e1[i] * e2[j] - e1[j] * e2[i];
  if (!(d2 != 0)) return false;
  const double b1 = (q[0] * e2[j] - q[1] * e2[i]) / d2, b2 = (e1[i] * q[1] - e1[j] * q[0]) / d2;
  if (!(b1 >= -1e-3 && b2 >= -1e-3 && b1 + b2 <= 1 + 1e-3)) return false;
  const float tf = to_float(t);
  if (!(tf >= tnear && tf <= tfar && std::fabs(tf) <= FLT_MAX)) return false;
  *t_out = tf;
  *u_out = to_float(v / det);
  *v_out = to_float(w / det);
  return true;
}

// Traversal status shared by both orders and both levels.
enum class Walk { kDone, kStop, kOverflow };  // kStop: any-hit found

// Starts loading every hit child: the whole of inner nodes (planes, child refs and octant orders, which
// the visit reads right after its box test; issue 11: forest-2k random 1.43 -> 1.51 of Embree), and through
// `prefetch_leaf(ref)` the first block of leaves. Most are visited soon, and the loads then overlap
// instead of each node waiting for its own cache misses.
template <int W, class PrefetchLeaf>
RTP_KERNEL_INLINE void prefetch_children(const fmt::WideNode<W>* nodes, const fmt::WideNode<W>& node, uint32_t mask,
                                         PrefetchLeaf&& prefetch_leaf) {
  for (uint32_t m = mask; m; m &= m - 1) {
    const uint32_t ref = node.child[__builtin_ctz(m)];
    if (fmt::ChildRef::is_leaf(ref)) {
      prefetch_leaf(ref);
    } else if (!fmt::ChildRef::is_empty(ref)) {
      const char* p = reinterpret_cast<const char*>(nodes + ref);
      for (int off = 0; off < 36 * W; off += 64) __builtin_prefetch(p + off);
    }
  }
}

inline int lowest_bit(uint32_t m) { return __builtin_ctz(m); }
inline int highest_bit(uint32_t m) { return 31 - __builtin_clz(m); }
inline int bit_count(uint32_t m) { return __builtin_popcount(m); }

}  // namespace rtp::RTP_ISA_NS
