#pragma once
// The top level over batching points (formats/top_level.h) as both package tracers walk it: one lane
// box test, shared so that the in-core walk (a stack) and the out-of-core walk (parent pointers) visit
// batching points in exactly the same order, whatever their scheduling: nearest entry distance first,
// ties by the higher lane first (the order the in-core stack pops them).
#include <emmintrin.h>

#include <algorithm>
#include <cstdint>

#include "formats/ray_file.h"
#include "formats/top_level.h"

namespace rtp {

struct TopLane {
  double t0;  // entry distance (depends on the ray's tnear only, never on tfar)
  bool hit;   // the box meets [tnear, tfar]
};

// Lane l of `node` against the ray (double precision, the box's far side widened by 1e-12 relative): the
// one-lane reference that top_lanes, which both walks use, is tested against (tests/test_top_level_walk.cpp).
inline TopLane top_lane(const fmt::TopNode& node, int l, const fmt::Ray& ray, const double inv[3]) {
  double t0 = ray.tnear, t1 = ray.tfar;
  bool hit = true;
  for (int k = 0; k < 3 && hit; ++k) {
    const double o = ray.org[k], lo = node.lo[k][l], hi = node.hi[k][l];
    if (ray.dir[k] == 0) {
      hit = o >= lo && o <= hi;
      continue;
    }
    double a = (lo - o) * inv[k], b = (hi - o) * inv[k];
    if (a > b) std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b * (1 + 1e-12));
  }
  return {t0, hit && t0 <= t1};
}

// The four lanes of `node` at once, two per SSE2 register: for every lane whose box the ray's line
// meets on the axes where dir is 0, the same t0 as top_lane (the same operations: a compare picks the
// near plane as top_lane's swap does, std::max and std::min are compares and selects), and `hit`
// bit l equal to top_lane's hit. (top_lane stops at an axis where dir is 0 and the origin is outside the
// slab; here the other axes still move that lane's t0, which no caller reads for a lane that misses.)
struct TopLanes {
  double t0[4];
  uint32_t hit;  // bit l: lane l hit (empty lanes are not masked out here)
};
inline TopLanes top_lanes(const fmt::TopNode& node, const fmt::Ray& ray, const double inv[3]) {
  __m128d t0[2] = {_mm_set1_pd(double(ray.tnear)), _mm_set1_pd(double(ray.tnear))};
  __m128d t1[2] = {_mm_set1_pd(double(ray.tfar)), _mm_set1_pd(double(ray.tfar))};
  __m128d in[2] = {_mm_castsi128_pd(_mm_set1_epi32(-1)), _mm_castsi128_pd(_mm_set1_epi32(-1))};
  const __m128d widen = _mm_set1_pd(1 + 1e-12);
  auto select = [](__m128d m, __m128d yes, __m128d no) { return _mm_or_pd(_mm_and_pd(m, yes), _mm_andnot_pd(m, no)); };
  for (int k = 0; k < 3; ++k) {
    const __m128d o = _mm_set1_pd(double(ray.org[k])), iv = _mm_set1_pd(inv[k]);
    for (int h = 0; h < 2; ++h) {
      const __m128d lo = _mm_cvtps_pd(_mm_castsi128_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(&node.lo[k][2 * h]))));
      const __m128d hi = _mm_cvtps_pd(_mm_castsi128_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(&node.hi[k][2 * h]))));
      if (ray.dir[k] == 0) {
        in[h] = _mm_and_pd(in[h], _mm_and_pd(_mm_cmpge_pd(o, lo), _mm_cmple_pd(o, hi)));
        continue;
      }
      const __m128d a = _mm_mul_pd(_mm_sub_pd(lo, o), iv), b = _mm_mul_pd(_mm_sub_pd(hi, o), iv);
      const __m128d swap = _mm_cmpgt_pd(a, b);
      const __m128d near = select(swap, b, a), far = _mm_mul_pd(select(swap, a, b), widen);
      t0[h] = select(_mm_cmplt_pd(t0[h], near), near, t0[h]);  // std::max(t0, near)
      t1[h] = select(_mm_cmplt_pd(far, t1[h]), far, t1[h]);    // std::min(t1, far)
    }
  }
  TopLanes r;
  _mm_storeu_pd(r.t0, t0[0]);
  _mm_storeu_pd(r.t0 + 2, t0[1]);
  r.hit = uint32_t(_mm_movemask_pd(_mm_and_pd(in[0], _mm_cmple_pd(t0[0], t1[0])))) |
          uint32_t(_mm_movemask_pd(_mm_and_pd(in[1], _mm_cmple_pd(t0[1], t1[1])))) << 2;
  return r;
}

inline void top_inverse(const fmt::Ray& ray, double inv[3]) {
  for (int k = 0; k < 3; ++k) inv[k] = 1.0 / double(ray.dir[k]);
}

// Where a paused ray stands: the lane of the batching point it waits at, in node `node`.
struct TopPosition {
  static constexpr uint32_t kNoLane = 4;
  uint32_t node = 0;
  uint32_t lane = kNoLane;  // kNoLane: nothing of `node` visited yet (a fresh ray stands at the root)
};

// Molenaar 2019 §4.1: the next batching point of the ray's front-to-back walk after `pos`, found
// without a stack by climbing parent pointers (check_top_level guarantees parent/slot name the lane
// that references a node, and a child's index exceeds its parent's, so the climb ends). The ray's
// tfar is the current one: a lane the in-core walk would have pushed and then skipped is not hit now.
// Returns the batching point (pos = its node and lane) or kNone when the walk is over.
inline constexpr uint32_t kTopNone = 0xFFFFFFFFu;
inline uint32_t top_next(const fmt::TopNode* top, const fmt::Ray& ray, const double inv[3], TopPosition& pos) {
  uint32_t node = pos.node, after = pos.lane;
  for (;;) {
    const fmt::TopNode& n = top[node];
    const TopLanes lanes = top_lanes(n, ray, inv);  // the after lane's t0 too (its slab holds the origin)
    const double after_t = after != TopPosition::kNoLane ? lanes.t0[after] : 0;
    int best = -1;
    double best_t = 0;
    for (int l = 3; l >= 0; --l) {  // descending lanes: on equal t the first found (higher lane) wins
      if (n.child[l] == fmt::TopNode::kEmpty || !((lanes.hit >> l) & 1u)) continue;
      const double t0 = lanes.t0[l];
      if (after != TopPosition::kNoLane && !(t0 > after_t || (t0 == after_t && uint32_t(l) < after))) continue;
      if (best < 0 || t0 < best_t) best = l, best_t = t0;
    }
    if (best >= 0) {
      const uint32_t child = n.child[best];
      if (child & fmt::TopNode::kLeafBit) {
        pos = {node, uint32_t(best)};
        return child & ~fmt::TopNode::kLeafBit;
      }
      node = child;
      after = TopPosition::kNoLane;
      continue;
    }
    if (n.parent == fmt::TopNode::kEmpty) return kTopNone;
    after = n.slot;
    node = n.parent;
  }
}

}  // namespace rtp
