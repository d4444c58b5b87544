#pragma once
// Scalar pieces every ISA's kernels share. Included only by the ISA translation units, inside their
// own namespace (RTP_ISA_NS), so code built with different -m flags never merges at link time.
#include <cfloat>
#include <cmath>
#include <cstdint>

#include "formats/bvh_layout.h"
#include "trace/ray_setup.h"

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
inline float pad_far(float t) { return max_keep(t * detail::kFarPadUp, t * detail::kFarPadDown); }

// double -> float without the undefined out-of-range conversion: beyond FLT_MAX gives ±inf, NaN stays NaN.
inline float to_float(double x) {
  if (std::fabs(x) <= double(FLT_MAX)) return static_cast<float>(x);
  return x > 0 ? INFINITY : (x < 0 ? -INFINITY : NAN);
}

// Woop, Benthin, Wald 2013 §3: an edge function that is exactly 0 in float is recomputed in double
// (products of floats are exact there), then rounded back, so a shared edge gets one consistent sign.
inline void edge_functions_double(float ax, float ay, float bx, float by, float cx, float cy, float* u, float* v,
                                  float* w) {
  const double cxby = double(cx) * double(by), cybx = double(cy) * double(bx);
  const double axcy = double(ax) * double(cy), aycx = double(ay) * double(cx);
  const double bxay = double(bx) * double(ay), byax = double(by) * double(ax);
  *u = to_float(cxby - cybx);
  *v = to_float(axcy - aycx);
  *w = to_float(bxay - byax);
}

// Traversal status shared by both orders and both levels.
enum class Walk { kDone, kStop, kOverflow };  // kStop: any-hit found

// Starts loading every hit child: the box planes (first 24·W bytes) of inner nodes, and through
// `prefetch_leaf(ref)` the first block of leaves. Most are visited soon, and the loads then overlap
// instead of each node waiting for its own cache misses.
template <int W, class PrefetchLeaf>
inline void prefetch_children(const fmt::WideNode<W>* nodes, const fmt::WideNode<W>& node, uint32_t mask,
                              PrefetchLeaf&& prefetch_leaf) {
  for (uint32_t m = mask; m; m &= m - 1) {
    const uint32_t ref = node.child[__builtin_ctz(m)];
    if (fmt::ChildRef::is_leaf(ref)) {
      prefetch_leaf(ref);
    } else if (!fmt::ChildRef::is_empty(ref)) {
      const char* p = reinterpret_cast<const char*>(nodes + ref);
      for (int off = 0; off < 24 * W; off += 64) __builtin_prefetch(p + off);
    }
  }
}

inline int lowest_bit(uint32_t m) { return __builtin_ctz(m); }
inline int highest_bit(uint32_t m) { return 31 - __builtin_clz(m); }
inline int bit_count(uint32_t m) { return __builtin_popcount(m); }

}  // namespace rtp::RTP_ISA_NS
