#pragma once
// The N closest hits of a ray, generic over a kernel set like trace_ray.h: node-culling multi-hit
// traversal and the collect-everything baseline it is measured against. TESTING.md item 7: the N
// closest in (t, instance, prim) order, each triangle once.
#include <algorithm>
#include <vector>

#include "trace/kernels/trace_ray.h"

namespace rtp::RTP_ISA_NS {

// TESTING.md item 7 order: t, then instance, then primitive.
inline bool hit_before(const fmt::Hit& a, const fmt::Hit& b) {
  if (a.t != b.t) return a.t < b.t;
  if (a.instance != b.instance) return a.instance < b.instance;
  return a.prim < b.prim;
}

// Gribble 2016 "Node Culling Multi-Hit BVH Traversal" §2.1 (Algorithm 1): the N closest hits so far,
// kept sorted; once N are found the N-th hit's t becomes the walk's tfar, so a node (of either level)
// whose entry distance lies beyond it is culled by the walk's own pad_far(tfar) test and a triangle
// beyond it fails the leaf test. A lane that repeats a short block's last triangle reports the same
// (instance, prim) again and is dropped.
struct MultiSink {
  static constexpr bool kFixedFar = false;  // the N-th hit's t culls
  fmt::Hit* list;
  uint32_t cap;
  uint32_t count;
  float cull;
  float& tfar() { return cull; }
  void insert(const fmt::Hit& x) {
    if (count == cap && !hit_before(x, list[cap - 1])) return;
    for (uint32_t k = 0; k < count; ++k)
      if (list[k].instance == x.instance && list[k].prim == x.prim) return;
    uint32_t k = count < cap ? count++ : cap - 1;
    for (; k > 0 && hit_before(x, list[k - 1]); --k) list[k] = list[k - 1];
    list[k] = x;
    if (count == cap) cull = list[cap - 1].t;
  }
  template <class K, int B>
  Walk block(const fmt::LeafBlock<B>& blk, const detail::TriRay& tri, uint32_t id) {
    BlockHits<B> h;
    for (uint32_t m = K::template block<B>(blk, tri, cull, &h); m; m &= m - 1) {
      const int i = lowest_bit(m);
      insert({h.t[i], id, blk.prim[i], h.u[i], h.v[i]});
    }
    return Walk::kDone;
  }
};

// The baseline, Gribble 2016 §1 "naive multi-hit" (all-hit traversal): every hit in [tnear, tfar], tfar
// never shrinks; sorted and cut to N afterwards.
struct CollectSink {
  static constexpr bool kFixedFar = false;  // the baseline keeps the general walk
  std::vector<fmt::Hit>* all;
  float t;
  float& tfar() { return t; }
  template <class K, int B>
  Walk block(const fmt::LeafBlock<B>& blk, const detail::TriRay& tri, uint32_t id) {
    BlockHits<B> h;
    for (uint32_t m = K::template block<B>(blk, tri, t, &h); m; m &= m - 1) {
      const int i = lowest_bit(m);
      all->push_back({h.t[i], id, blk.prim[i], h.u[i], h.v[i]});
    }
    return Walk::kDone;
  }
};

// hits[i·N, i·N + N): ray i's hits in order, then misses; counts[i] = how many are hits.
template <class K, TraversalOrder O, bool kCull, int W, int B>
inline TraceStats multi_batch(const SceneView<W, B>& s, const fmt::Ray* rays, size_t n, uint32_t N, fmt::Hit* hits,
                              uint32_t* counts) {
  TraceStats stats;
  stats.rays = n;
  for (size_t i = 0; i < n; ++i) {
    const fmt::Ray& ray = rays[i];  // in place, as trace_batch (a copy's halves stall ray_is_valid's load)
    fmt::Hit* out = hits + i * N;
    std::fill(out, out + N, fmt::Hit{INFINITY, fmt::Hit::kNone, fmt::Hit::kNone, 0.0f, 0.0f});
    counts[i] = 0;
    if (!ray_is_valid(ray)) {
      ++stats.invalid_rays;
      continue;
    }
    if (!direction_usable(ray.dir)) continue;
    if constexpr (kCull) {
      MultiSink sink{out, N, 0, ray.tfar};
      if (trace_one<K, O>(s, ray, sink) == Walk::kOverflow) {
        ++stats.overflow_rays;
        std::fill(out, out + N, fmt::Hit{INFINITY, fmt::Hit::kNone, fmt::Hit::kNone, 0.0f, 0.0f});
        continue;
      }
      counts[i] = sink.count;
    } else {
      thread_local std::vector<fmt::Hit> all;
      all.clear();
      CollectSink sink{&all, ray.tfar};
      if (trace_one<K, O>(s, ray, sink) == Walk::kOverflow) {
        ++stats.overflow_rays;
        continue;
      }
      std::sort(all.begin(), all.end(), hit_before);
      const auto same = [](const fmt::Hit& a, const fmt::Hit& b) { return a.instance == b.instance && a.prim == b.prim; };
      all.erase(std::unique(all.begin(), all.end(), same), all.end());
      const uint32_t c = uint32_t(std::min<size_t>(N, all.size()));
      std::copy(all.begin(), all.begin() + c, out);
      counts[i] = c;
    }
  }
  return stats;
}

}  // namespace rtp::RTP_ISA_NS
