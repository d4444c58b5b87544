// SAH collapse of a binary BVH into a W-wide multi-BVH (Benthin 2008 §4.2).
//
// Cost model (§4): C = Σ_{multi-nodes} SA + Σ_{leaves} SA·⌈N/B⌉. Three transformations, applied
// greedily by their exact change of C:
//   pull-up      a child's children become the node's own when they fit (count − 1 + N(c) ≤ W); the
//                gain is SA(c) > 0, so it is done as often as possible, largest SA first;
//   leaf merge   two leaf children become one (N_i + N_j ≤ 16·B); gain
//                SA_i⌈N_i/B⌉ + SA_j⌈N_j/B⌉ − SA_ij⌈(N_i+N_j)/B⌉, done when positive, best first;
//   inner merge  two inner children become one node (N(c_i) + N(c_j) ≤ W); gain SA_i + SA_j − SA_ij,
//                done when positive, best first.
// Order (§4.2 "Taking it all together"): at each node, first pull up children top-down while the node
// has room, then recurse into the children, and only then merge leaf pairs and inner pairs (pull-ups
// of children that a merge made small enough are retried in between). The a-priori leaf collapse of
// subtrees with <= leaf_size triangles already happened in the binary build.
//
// Subtrees of at least task_threshold primitives collapse as TBB tasks. Multi-nodes go to a
// concurrent_vector (their index depends on scheduling, nothing else does: ties are broken by lane
// position, and leaf part lists are indexed by binary node, which each task owns).
#include <oneapi/tbb/parallel_for.h>

#include "bvh/build_internal.h"
#include "core/error.h"

namespace rtp::bvh {
namespace {

template <int W>
class Collapser {
 public:
  Collapser(const BinaryTree& binary, const BuildParams& params, WideTree<W>& out) : bt_(binary.nodes), p_(params), out_(out) {}

  // A lane for binary node b: a leaf (its prim range as one part) or a still uncollapsed node.
  WideLane lane_of(uint32_t b) {
    const BinaryNode& n = bt_[b];
    WideLane lane;
    lane.box = n.box;
    lane.prims = n.count;
    lane.ref = b;
    if (n.leaf()) {
      lane.kind = LaneKind::kLeaf;
      out_.parts[b] = LeafPart{n.begin, n.count, kNone};
    } else {
      lane.kind = LaneKind::kBinary;
    }
    return lane;
  }

  // Benthin 2008 §4.2 "taking it all together": pull up top-down, recurse, then merge pairs.
  // Collapses the subtree of binary inner node b; returns its lane (a multi-node, or a single leaf
  // when every child merged into one).
  WideLane collapse(uint32_t b) {
    MultiNode<W> m;
    m.count = 2;
    m.lane[0] = lane_of(b + 1);
    m.lane[1] = lane_of(bt_[b].right);

    // Benthin 2008 §4.2 merging a child node into its parent, top-down: a binary child brings 2 lanes.
    while (m.count < uint32_t(W)) {
      const int i = largest(m, [](const WideLane& l) { return l.kind == LaneKind::kBinary; });
      if (i < 0) break;
      const uint32_t c = m.lane[i].ref;
      m.lane[i] = lane_of(c + 1);
      m.lane[m.count++] = lane_of(bt_[c].right);
    }

    // Recurse into the children that are still binary nodes.
    uint32_t below = 0;
    for (uint32_t i = 0; i < m.count; ++i)
      if (m.lane[i].kind == LaneKind::kBinary) below += m.lane[i].prims;
    auto recurse = [&](uint32_t i) {
      if (m.lane[i].kind == LaneKind::kBinary) m.lane[i] = collapse(m.lane[i].ref);
    };
    if (below >= p_.task_threshold) {
      tbb::parallel_for(uint32_t(0), m.count, recurse);
    } else {
      for (uint32_t i = 0; i < m.count; ++i) recurse(i);
    }

    merge_children(m);
    if (m.count == 1) return m.lane[0];
    return store(m);
  }

  // Bottom-up part of §4.2: pull-ups of (now final) inner children, then leaf pairs, then inner pairs.
  void merge_children(MultiNode<W>& m) {
    for (;;) {
      // Pull-up: the child with the largest SA among those whose lanes fit.
      const int up = largest(m, [&](const WideLane& l) {
        return l.kind == LaneKind::kNode && m.count - 1 + out_.nodes[l.ref].count <= uint32_t(W);
      });
      if (up >= 0) {
        const MultiNode<W>& c = out_.nodes[m.lane[up].ref];
        m.lane[up] = c.lane[0];
        for (uint32_t k = 1; k < c.count; ++k) m.lane[m.count++] = c.lane[k];
        continue;
      }
      // Benthin 2008 §4.2 merging two leaf-node children, best positive gain first.
      int bi = -1, bj = -1;
      double best = 0;
      for (uint32_t i = 0; i < m.count; ++i) {
        const WideLane& a = m.lane[i];
        if (a.kind != LaneKind::kLeaf) continue;
        const double ca = half_area(a.box) * blocks(a.prims, p_.block);
        for (uint32_t j = i + 1; j < m.count; ++j) {
          const WideLane& b = m.lane[j];
          if (b.kind != LaneKind::kLeaf || a.prims + b.prims > p_.max_leaf) continue;
          const double gain = ca + half_area(b.box) * blocks(b.prims, p_.block) -
                              half_area(join(a.box, b.box)) * blocks(a.prims + b.prims, p_.block);
          if (gain > best) {
            best = gain;
            bi = int(i);
            bj = int(j);
          }
        }
      }
      if (bi >= 0) {
        merge_leaves(m.lane[bi], m.lane[bj]);
        remove_lane(m, uint32_t(bj));
        continue;
      }
      // Benthin 2008 §4.2 merging two inner-node children, best positive gain first.
      best = 0;
      for (uint32_t i = 0; i < m.count; ++i) {
        const WideLane& a = m.lane[i];
        if (a.kind != LaneKind::kNode) continue;
        for (uint32_t j = i + 1; j < m.count; ++j) {
          const WideLane& b = m.lane[j];
          if (b.kind != LaneKind::kNode || out_.nodes[a.ref].count + out_.nodes[b.ref].count > uint32_t(W)) continue;
          const double gain = half_area(a.box) + half_area(b.box) - half_area(join(a.box, b.box));
          if (gain > best) {
            best = gain;
            bi = int(i);
            bj = int(j);
          }
        }
      }
      if (bi >= 0) {
        // c_i takes c_j's lanes; c_j's storage is left unreferenced. The merged node may now merge
        // its own children.
        MultiNode<W>& a = out_.nodes[m.lane[bi].ref];
        const MultiNode<W>& b = out_.nodes[m.lane[bj].ref];
        for (uint32_t k = 0; k < b.count; ++k) a.lane[a.count++] = b.lane[k];
        merge_children(a);
        WideLane& lane = m.lane[bi];
        grow(lane.box, m.lane[bj].box);
        lane.prims += m.lane[bj].prims;
        if (a.count == 1) lane = a.lane[0];
        remove_lane(m, uint32_t(bj));
        continue;
      }
      break;
    }
  }

 private:
  // The lane with the largest half area among those `eligible`; ties: the lowest lane. -1 if none.
  template <class Pred>
  static int largest(const MultiNode<W>& m, Pred eligible) {
    int best = -1;
    double area = -1;
    for (uint32_t i = 0; i < m.count; ++i) {
      if (!eligible(m.lane[i])) continue;
      const double a = half_area(m.lane[i].box);
      if (a > area) {
        area = a;
        best = int(i);
      }
    }
    return best;
  }

  void merge_leaves(WideLane& a, const WideLane& b) {
    uint32_t tail = a.ref;
    while (out_.parts[tail].next != kNone) tail = out_.parts[tail].next;
    out_.parts[tail].next = b.ref;
    grow(a.box, b.box);
    a.prims += b.prims;
  }

  static void remove_lane(MultiNode<W>& m, uint32_t j) {
    for (uint32_t k = j; k + 1 < m.count; ++k) m.lane[k] = m.lane[k + 1];
    --m.count;
    m.lane[m.count] = WideLane{};
  }

  WideLane store(const MultiNode<W>& m) {
    WideLane lane;
    lane.kind = LaneKind::kNode;
    for (uint32_t i = 0; i < m.count; ++i) {
      grow(lane.box, m.lane[i].box);
      lane.prims += m.lane[i].prims;
    }
    const auto it = out_.nodes.push_back(m);
    lane.ref = uint32_t(it - out_.nodes.begin());
    return lane;
  }

  const std::vector<BinaryNode>& bt_;
  const BuildParams& p_;
  WideTree<W>& out_;
};

}  // namespace

template <int W>
WideTree<W> collapse_binary(const BinaryTree& binary, const BuildParams& params) {
  WideTree<W> tree;
  if (binary.nodes.empty()) return tree;
  tree.parts.resize(binary.nodes.size());
  Collapser<W> c(binary, params, tree);
  tree.root = binary.nodes[0].leaf() ? c.lane_of(0) : c.collapse(0);
  return tree;
}

template WideTree<4> collapse_binary<4>(const BinaryTree&, const BuildParams&);
template WideTree<8> collapse_binary<8>(const BinaryTree&, const BuildParams&);
template WideTree<16> collapse_binary<16>(const BinaryTree&, const BuildParams&);

}  // namespace rtp::bvh
