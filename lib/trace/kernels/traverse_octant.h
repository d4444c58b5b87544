#pragma once
// Depth-first traversal of one W-wide BVH level in the node's precomputed octant order, with a
// fixed-size stack of (child, entry distance). Shared by the instance level and the mesh level.
#include <type_traits>

#include "formats/bvh_layout.h"
#include "trace/kernels/kernel_common.h"

namespace rtp::RTP_ISA_NS {

// Molenaar 2019 §4.1 (after Fuetterling 2017): hit children in node.order[octant] order, the nearest
// taken next, the others pushed far to near with their entry distance; a popped entry whose distance
// is beyond the (padded) current tfar is dropped. `tfar` is live: the leaf callback may shorten it.
// leaf(ref) returns kDone to go on, kStop/kOverflow to end the walk with that status.
// kFixedFar: the leaves never shorten `tfar` (any-hit walks stop at the first hit instead), so every
// pushed child, hit with entry <= pad_far(tfar), passes the pop test: the stack keeps references only
// (after Embree's any-hit traversal, which pushes no distances) and pops without a test.
template <class K, int W, bool kFixedFar = false, class LeafFn, class PrefetchFn>
RTP_KERNEL_INLINE Walk walk_octant_stack(const fmt::WideNode<W>* nodes, uint32_t root, const detail::BoxRay& ray,
                                         const float& tfar, LeafFn&& leaf, PrefetchFn&& prefetch_leaf) {
  struct Pair {
    uint32_t ref;
    float dist;
  };
  using Entry = std::conditional_t<kFixedFar, uint32_t, Pair>;
  // Each inner level adds at most W - 1 entries (the nearest child is not pushed).
  constexpr int kCapacity = (W - 1) * detail::kMaxDepth + 1;
  Entry stack[kCapacity + W];  // push_ordered8/16 write W entries, the pushed ones first
  int sp = 0;
  alignas(64) float dist[W];
  const typename K::template NodeRay<W> node_ray = K::template node_ray<W>(ray);
  uint32_t cur = root;
  for (;;) {
    if (fmt::ChildRef::is_leaf(cur)) {
      const Walk w = leaf(cur);
      if (w != Walk::kDone) return w;
    } else if (!fmt::ChildRef::is_empty(cur)) {
      const fmt::WideNode<W>& node = nodes[fmt::ChildRef::node_index(cur)];
      const uint32_t mask = K::template node<W>(node, node_ray, tfar, dist);
      prefetch_children(nodes, node, mask, prefetch_leaf);
      const uint8_t* order = node.order[ray.octant];
      if (mask && !(mask & (mask - 1))) {  // one child hit: no order needed
        cur = node.child[lowest_bit(mask)];
        continue;
      }
      uint32_t om = mask ? K::template ordered<W>(mask, order) : 0u;
      if (om) {
        const int nearest = lowest_bit(om);
        om &= om - 1;
        if (sp + bit_count(om) > kCapacity) return Walk::kOverflow;
        if constexpr (W == 8 && K::kPushOrdered8) {
          if constexpr (kFixedFar)
            K::push_ordered8_refs(stack + sp, node.child, order, om);
          else
            K::push_ordered8(stack + sp, node.child, dist, order, om);
          sp += bit_count(om);
        } else if constexpr (W == 16 && K::kPushOrdered16 && !kFixedFar) {
          K::push_ordered16(stack + sp, node.child, dist, order, om);
          sp += bit_count(om);
        } else {
          while (om) {
            const int i = highest_bit(om);
            om &= ~(1u << i);
            const int lane = order[i] & 15;
            if constexpr (kFixedFar)
              stack[sp++] = node.child[lane];
            else
              stack[sp++] = {node.child[lane], dist[lane]};
          }
        }
        cur = node.child[order[nearest] & 15];
        continue;
      }
    }
    if constexpr (kFixedFar) {
      if (sp == 0) return Walk::kDone;
      cur = stack[--sp];
    } else {
      for (;;) {
        if (sp == 0) return Walk::kDone;
        const Entry e = stack[--sp];
        if (e.dist <= pad_far(tfar)) {
          cur = e.ref;
          break;
        }
      }
    }
  }
}

}  // namespace rtp::RTP_ISA_NS
