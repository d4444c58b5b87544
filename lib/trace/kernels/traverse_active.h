#pragma once
// Front-to-back traversal of one W-wide BVH level with an unsorted active list of (child, entry
// distance). Shared by the instance level and the mesh level.
#include "formats/bvh_layout.h"
#include "trace/kernels/kernel_common.h"

namespace rtp::RTP_ISA_NS {

// Benthin 2008 §5.3–5.4: hit children are appended (compacted by the hit mask) to an unsorted list;
// the entry with the smallest distance is taken next and replaced by the last one; after a leaf
// shortens tfar, entries beyond it are compacted out in place (pruning).
// The list is bounded: above kSoft entries the last entry is taken instead (depth first, which adds
// at most W - 1 entries per level), so kCapacity below is never exceeded by a tree within kMaxDepth.
template <class K, int W, class LeafFn, class PrefetchFn>
RTP_KERNEL_INLINE Walk walk_active_list(const fmt::WideNode<W>* nodes, uint32_t root, const detail::BoxRay& ray,
                                        const float& tfar, LeafFn&& leaf, PrefetchFn&& prefetch_leaf) {
  constexpr int kSoft = 64;
  constexpr int kCapacity = kSoft + W + (W - 1) * detail::kMaxDepth + 1;
  uint32_t refs[kCapacity];
  float dists[kCapacity];
  int n = 0;
  alignas(64) float dist[W];
  const typename K::template NodeRay<W> node_ray = K::template node_ray<W>(ray);
  uint32_t cur = root;
  for (;;) {
    if (fmt::ChildRef::is_leaf(cur)) {
      const float before = tfar;
      const Walk w = leaf(cur);
      if (w != Walk::kDone) return w;
      if (tfar < before) {
        const float limit = pad_far(tfar);
        int kept = 0;
        for (int i = 0; i < n; ++i) {
          if (dists[i] <= limit) {
            refs[kept] = refs[i];
            dists[kept] = dists[i];
            ++kept;
          }
        }
        n = kept;
      }
    } else if (!fmt::ChildRef::is_empty(cur)) {
      const fmt::WideNode<W>& node = nodes[fmt::ChildRef::node_index(cur)];
      const uint32_t mask = K::template node<W>(node, node_ray, tfar, dist);
      prefetch_children(nodes, node, mask, prefetch_leaf);
      if (n + bit_count(mask) > kCapacity) return Walk::kOverflow;
      for (uint32_t m = mask; m; m &= m - 1) {
        const int i = lowest_bit(m);
        refs[n] = node.child[i];
        dists[n] = dist[i];
        ++n;
      }
    }
    if (n == 0) return Walk::kDone;
    int pick = n - 1;
    if (n <= kSoft) {
      pick = 0;
      for (int i = 1; i < n; ++i)
        if (dists[i] < dists[pick]) pick = i;
    }
    cur = refs[pick];
    --n;
    refs[pick] = refs[n];
    dists[pick] = dists[n];
  }
}

}  // namespace rtp::RTP_ISA_NS
