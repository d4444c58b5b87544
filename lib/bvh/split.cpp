// Top-down greedy W-way splitting (Benthin 2008 §4.3, Algorithm 1).
//
// A multi-node starts as one range that wants to be split. While it has fewer than W lanes, the lane
// with the largest surface area that wants to be split is split (binned SAH, binned_sah.cpp) and its
// two halves take its place. Then lanes that do not want a split become leaves and the others become
// multi-nodes, recursively (as TBB tasks when large).
//
// "Wants to get split" (the SAH binning step of Algorithm 1), with the §4 block cost ⌈N/B⌉:
//   N <= leaf_size                              no (a-priori leaf, as in the collapse builder)
//   N > 16·B (max_leaf)                         yes, always (the layout allows at most 16 blocks)
//   otherwise                                   yes iff the binned SAH plane lowers the leaf cost:
//                                               SA_L⌈N_L/B⌉ + SA_R⌈N_R/B⌉ < SA⌈N/B⌉
//                                               (a median fallback, i.e. no separating plane or no
//                                               depth budget left, never counts as a gain).
// Lanes are compared by SA with ties to the lowest lane, so the tree is a pure function of the input.
#include <oneapi/tbb/parallel_for.h>

#include "bvh/build_internal.h"

namespace rtp::bvh {
namespace {

template <int W>
class SplitBuilder {
 public:
  SplitBuilder(Splitter& splitter, WideTree<W>& out) : sp_(splitter), p_(splitter.params()), out_(out) {}

  struct Item {
    Range range;
    Split split;
    bool wants = false;
  };

  Item evaluate(const Range& r) const {
    Item item;
    item.range = r;
    const uint32_t n = r.size();
    if (n <= p_.leaf_size) return item;
    item.split = sp_.find(r);
    if (n > p_.max_leaf) {
      item.wants = true;
    } else if (!item.split.median) {
      const Split& s = item.split;
      const double split_cost = s.left_area * blocks(s.left_count, p_.block) + s.right_area * blocks(s.right_count, p_.block);
      item.wants = split_cost < half_area(r.box) * blocks(n, p_.block);
    }
    return item;
  }

  WideLane leaf(const Range& r) {
    // Each leaf is one contiguous range; its part is indexed by its first primitive (unique).
    out_.parts[r.begin] = LeafPart{r.begin, r.size(), kNone};
    WideLane lane;
    lane.box = r.box;
    lane.ref = r.begin;
    lane.prims = r.size();
    lane.kind = LaneKind::kLeaf;
    return lane;
  }

  // Benthin 2008 §4.3 Algorithm 1 make-multi-node for a range that wants to be split.
  WideLane make_node(const Item& first) {
    Item items[W];
    uint32_t count = 1;
    items[0] = first;
    while (count < uint32_t(W)) {
      int pick = -1;
      double area = -1;
      for (uint32_t i = 0; i < count; ++i) {
        if (!items[i].wants) continue;
        const double a = half_area(items[i].range.box);
        if (a > area) {
          area = a;
          pick = int(i);
        }
      }
      if (pick < 0) break;
      Range left, right;
      sp_.apply(items[pick].range, items[pick].split, left, right);
      items[pick] = evaluate(left);
      items[count++] = evaluate(right);
    }

    MultiNode<W> m;
    m.count = count;
    uint32_t below = 0;
    for (uint32_t i = 0; i < count; ++i) {
      if (items[i].wants) {
        below += items[i].range.size();
      } else {
        m.lane[i] = leaf(items[i].range);
      }
    }
    auto recurse = [&](uint32_t i) {
      if (items[i].wants) m.lane[i] = make_node(items[i]);
    };
    if (below >= p_.task_threshold) {
      tbb::parallel_for(uint32_t(0), count, recurse);
    } else {
      for (uint32_t i = 0; i < count; ++i) recurse(i);
    }

    WideLane lane;
    lane.kind = LaneKind::kNode;
    lane.box = first.range.box;
    lane.prims = first.range.size();
    const auto it = out_.nodes.push_back(m);
    lane.ref = uint32_t(it - out_.nodes.begin());
    return lane;
  }

 private:
  Splitter& sp_;
  const BuildParams& p_;
  WideTree<W>& out_;
};

}  // namespace

template <int W>
WideTree<W> split_build(Splitter& splitter, uint32_t n) {
  WideTree<W> tree;
  if (n == 0) return tree;
  tree.parts.resize(n);
  SplitBuilder<W> b(splitter, tree);
  const typename SplitBuilder<W>::Item root = b.evaluate(splitter.make_range(0, n, 0));
  tree.root = root.wants ? b.make_node(root) : b.leaf(root.range);
  return tree;
}

template WideTree<4> split_build<4>(Splitter&, uint32_t);
template WideTree<8> split_build<8>(Splitter&, uint32_t);
template WideTree<16> split_build<16>(Splitter&, uint32_t);

}  // namespace rtp::bvh
