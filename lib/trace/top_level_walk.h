#pragma once
// The top level over batching points (formats/top_level.h) as both package tracers walk it: one lane
// box test, shared so that the in-core walk (a stack) and the out-of-core walk (parent pointers) visit
// batching points in exactly the same order, whatever their scheduling: nearest entry distance first,
// ties by the higher lane first (the order the in-core stack pops them).
#include <algorithm>
#include <cstdint>

#include "formats/ray_file.h"
#include "formats/top_level.h"

namespace rtp {

struct TopLane {
  double t0;  // entry distance (depends on the ray's tnear only, never on tfar)
  bool hit;   // the box meets [tnear, tfar]
};

// Lane l of `node` against the ray (double precision, the box's far side widened by 1e-12 relative).
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
    double after_t = 0;
    if (after != TopPosition::kNoLane) after_t = top_lane(n, int(after), ray, inv).t0;
    int best = -1;
    double best_t = 0;
    for (int l = 3; l >= 0; --l) {  // descending lanes: on equal t the first found (higher lane) wins
      if (n.child[l] == fmt::TopNode::kEmpty) continue;
      const TopLane c = top_lane(n, l, ray, inv);
      if (!c.hit) continue;
      if (after != TopPosition::kNoLane && !(c.t0 > after_t || (c.t0 == after_t && uint32_t(l) < after))) continue;
      if (best < 0 || c.t0 < best_t) best = l, best_t = c.t0;
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
