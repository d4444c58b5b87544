// Reader-side BVH statistics and structural checks: one walk over the stored WideNode/LeafBlock arrays
// (formats/SPEC.md §2) computes the Benthin 2008 §4 cost model and, when asked, checks every child
// reference, lane layout, box containment and leaf padding rule.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "inspect/inspect.h"

namespace rtp {

void Box3d::grow(const double p[3]) {
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::min(lo[a], p[a]);
    hi[a] = std::max(hi[a], p[a]);
  }
}

void Box3d::grow(const Box3d& b) {
  if (b.empty()) return;
  grow(b.lo);
  grow(b.hi);
}

void Problems::add(const std::string& message) {
  ++count_;
  if (listed_.size() < keep_) listed_.push_back(message);
}

void Spread::add(double v) {
  min = std::min(min, v);
  max = std::max(max, v);
  sum += v;
  ++n;
}

nlohmann::json Spread::json() const {
  if (n == 0) return {{"min", nullptr}, {"mean", nullptr}, {"max", nullptr}};
  return {{"min", min}, {"mean", sum / double(n)}, {"max", max}};
}

void BvhGroup::add(const BvhShape& s) {
  ++bvhs;
  if (s.nodes == 0 && s.leaves > 0) ++root_leaves;
  triangles += s.primitives;
  nodes += s.nodes;
  blocks += s.blocks;
  if (s.leaves == 0) return;  // an empty BVH has no shape
  c_box.add(s.c_box);
  c_tri.add(s.c_tri);
  sah.add(s.c_box + s.c_tri);
  if (s.nodes) branching.add(s.branching);
  if (s.blocks) leaf_fill.add(s.leaf_fill);
  max_depth.add(s.max_depth);
}

nlohmann::json BvhGroup::json() const {
  return {{"bvhs", bvhs},
          {"root_leaves", root_leaves},
          {"primitives", triangles},
          {"nodes", nodes},
          {"blocks", blocks},
          {"c_box", c_box.json()},
          {"c_tri", c_tri.json()},
          {"sah", sah.json()},
          {"branching", branching.json()},
          {"leaf_fill", leaf_fill.json()},
          {"max_depth", max_depth.json()}};
}

void Histogram::add(uint64_t v) {
  size_t k = 0;
  while (k < 64 && (v >> k) != 0) ++k;  // v in [2^(k-1), 2^k)
  if (buckets.size() <= k) buckets.resize(k + 1, 0);
  ++buckets[k];
}

nlohmann::json Histogram::json() const {
  nlohmann::json out = nlohmann::json::array();
  size_t first = 0;
  while (first < buckets.size() && buckets[first] == 0) ++first;
  for (size_t k = first; k < buckets.size(); ++k) {
    const uint64_t lo = k == 0 ? 0 : uint64_t(1) << (k - 1);
    const nlohmann::json hi = k == 0 ? nlohmann::json(1) : (k < 64 ? nlohmann::json(uint64_t(1) << k) : nlohmann::json(nullptr));
    out.push_back({{"min", lo}, {"max", hi}, {"count", buckets[k]}});
  }
  return out;
}

namespace {

using fmt::ChildRef;
constexpr uint32_t kNone = 0xFFFFFFFFu;
constexpr float kFInf = std::numeric_limits<float>::infinity();

double half_area(const Box3d& b) {
  if (b.empty()) return 0;
  const double x = b.hi[0] - b.lo[0], y = b.hi[1] - b.lo[1], z = b.hi[2] - b.lo[2];
  return x * y + y * z + z * x;
}

bool inside(const Box3d& in, const Box3d& out) {
  for (int a = 0; a < 3; ++a)
    if (!(out.lo[a] <= in.lo[a] && in.hi[a] <= out.hi[a])) return false;
  return true;
}

template <int W>
Box3d lane_box(const fmt::WideNode<W>& n, int l) {
  Box3d b;
  for (int a = 0; a < 3; ++a) b.lo[a] = n.lo[a][l], b.hi[a] = n.hi[a][l];
  return b;
}

struct LeafCount {
  uint64_t prims = 0, blocks = 0;
};

void report(BvhCheck* ck, uint32_t node, int lane, const std::string& text) {
  if (node == kNone)
    ck->problems->add(ck->label + ": root leaf: " + text);
  else
    ck->problems->add(ck->label + ": node " + std::to_string(node) + " lane " + std::to_string(lane) + ": " + text);
}

// Lane layout (SPEC §2.2): filled lanes first, empty lanes with the never-hit box, valid boxes, and
// each octant order a permutation listing the filled lanes first, front to back (Molenaar 2019 §4.1).
template <int W>
uint32_t check_lanes(const fmt::WideNode<W>& n, uint32_t index, BvhCheck* ck) {
  uint32_t filled = 0;
  bool seen_empty = false;
  for (int l = 0; l < W; ++l) {
    const bool empty = n.child[l] == ChildRef::kEmpty;
    if (!empty) ++filled;
    if (!ck) continue;
    const Box3d b = lane_box(n, l);
    if (empty) {
      for (int a = 0; a < 3; ++a)
        if (!(n.lo[a][l] == kFInf && n.hi[a][l] == -kFInf)) {
          report(ck, index, l, "empty lane without the empty box (lo = +inf, hi = -inf)");
          break;
        }
      seen_empty = true;
    } else {
      if (seen_empty) report(ck, index, l, "filled lane after an empty lane");
      if (b.empty() || !std::isfinite(b.lo[0] + b.lo[1] + b.lo[2] + b.hi[0] + b.hi[1] + b.hi[2]))
        report(ck, index, l, "invalid box (not finite or lo > hi)");
    }
  }
  if (!ck) return filled;
  if (filled == 0) ck->problems->add(ck->label + ": node " + std::to_string(index) + ": no filled lane");
  for (int o = 0; o < 8; ++o) {
    uint32_t seen = 0;
    bool ok = true;
    for (int i = 0; i < W; ++i) {
      const uint32_t l = n.order[o][i];
      if (l >= uint32_t(W) || (seen >> l & 1u) || (uint32_t(i) < filled) != (n.child[l] != ChildRef::kEmpty))
        ok = false;
      else
        seen |= 1u << l;
    }
    if (!ok) {
      ck->problems->add(ck->label + ": node " + std::to_string(index) + ": octant " + std::to_string(o) +
                        " order is not a permutation of the lanes with the filled lanes first");
      break;
    }
    // Front to back (formats/bvh_layout.h): box centres along the octant's diagonal, ascending.
    double prev = -std::numeric_limits<double>::infinity();
    for (uint32_t i = 0; i < filled; ++i) {
      const uint32_t l = n.order[o][i];
      double key = 0;
      for (int a = 0; a < 3; ++a) key += (double(n.lo[a][l]) + double(n.hi[a][l])) * ((o >> a & 1) ? -1.0 : 1.0);
      if (key < prev - 1e-12 * (std::fabs(prev) + 1.0)) {
        ck->problems->add(ck->label + ": node " + std::to_string(index) + ": octant " + std::to_string(o) +
                          " order is not front to back (lane " + std::to_string(l) + ")");
        return filled;
      }
      prev = key;
    }
  }
  return filled;
}

// The walk shared by mesh and instance BVHs; `leaf(ref, lane box or null, node, lane, contents)`.
template <int W, class Leaf>
BvhShape walk(const fmt::WideNode<W>* nodes, uint64_t nn, uint32_t root, uint32_t cost_block, BvhCheck* ck, Leaf&& leaf) {
  BvhShape s;
  BvhCheck* chk = ck && ck->problems ? ck : nullptr;
  if (root == ChildRef::kEmpty) return s;
  auto cost = [cost_block](uint64_t n) {
    const uint64_t blocks = (n + cost_block - 1) / cost_block;  // whole blocks: the division rounds up
    return double(blocks);
  };
  if (ChildRef::is_leaf(root)) {
    Box3d contents;
    const LeafCount c = leaf(root, nullptr, kNone, 0, contents);
    s.leaves = 1;
    s.blocks = c.blocks;
    s.primitives = c.prims;
    s.c_tri = cost(c.prims);
    s.leaf_fill = c.blocks ? double(c.prims) / double(c.blocks * cost_block) : 0;
    if (ck) ck->root_box = contents;
    return s;
  }
  if (root >= nn) {
    if (chk)
      chk->problems->add(chk->label + ": root node " + std::to_string(root) + " out of range (" + std::to_string(nn) + " nodes)");
    return s;
  }
  struct Item {
    uint32_t node, depth, parent;
    int lane;
  };
  std::vector<Item> stack{{root, 1, kNone, 0}};
  std::vector<uint8_t> visited(nn, 0);
  double root_area = 0;
  uint64_t filled_lanes = 0;
  auto ratio = [&root_area](const Box3d& b) { return root_area > 0 ? half_area(b) / root_area : 1.0; };
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    if (visited[it.node]) {
      if (chk) report(chk, it.parent, it.lane, "node " + std::to_string(it.node) + " is referenced a second time");
      continue;
    }
    visited[it.node] = 1;
    const fmt::WideNode<W>& n = nodes[it.node];
    const uint32_t filled = check_lanes(n, it.node, chk);
    Box3d u;
    for (int l = 0; l < W; ++l)
      if (n.child[l] != ChildRef::kEmpty) u.grow(lane_box(n, l));
    if (it.parent == kNone) {
      root_area = half_area(u);
      if (ck) ck->root_box = u;
    } else if (chk && !inside(u, lane_box(nodes[it.parent], it.lane))) {
      report(chk, it.parent, it.lane, "child box not inside parent (node " + std::to_string(it.node) + ")");
    }
    ++s.nodes;
    s.c_box += ratio(u);
    s.max_depth = std::max(s.max_depth, it.depth);
    filled_lanes += filled;
    for (int l = W; l-- > 0;) {
      const uint32_t c = n.child[l];
      if (c == ChildRef::kEmpty) continue;
      if (ChildRef::is_leaf(c)) {
        const Box3d lb = lane_box(n, l);
        Box3d contents;
        const LeafCount k = leaf(c, &lb, it.node, l, contents);
        ++s.leaves;
        s.blocks += k.blocks;
        s.primitives += k.prims;
        s.c_tri += ratio(lb) * cost(k.prims);
      } else if (c >= nn) {
        if (chk) report(chk, it.node, l, "child node " + std::to_string(c) + " out of range (" + std::to_string(nn) + " nodes)");
      } else {
        stack.push_back({c, it.depth + 1, it.node, l});
      }
    }
  }
  s.branching = s.nodes ? double(filled_lanes) / double(s.nodes) : 0;
  s.leaf_fill = s.blocks ? double(s.primitives) / double(s.blocks * cost_block) : 0;
  return s;
}

template <int B>
bool same_lane(const fmt::LeafBlock<B>& b, int x, int y) {
  if (b.prim[x] != b.prim[y]) return false;
  for (int a = 0; a < 3; ++a)
    if (std::memcmp(&b.v0[a][x], &b.v0[a][y], 4) || std::memcmp(&b.v1[a][x], &b.v1[a][y], 4) ||
        std::memcmp(&b.v2[a][x], &b.v2[a][y], 4))
      return false;
  return true;
}

}  // namespace

template <int W, int B>
BvhShape mesh_bvh_shape(const fmt::WideNode<W>* nodes, uint64_t nn, const fmt::LeafBlock<B>* blocks, uint64_t nb, uint32_t root,
                        BvhCheck* ck) {
  BvhCheck* chk = ck && ck->problems ? ck : nullptr;
  auto leaf = [&](uint32_t ref, const Box3d* box, uint32_t node, int lane, Box3d& contents) {
    LeafCount out;
    const uint64_t first = ChildRef::first_block(ref), count = ChildRef::block_count(ref);
    if (first + count > nb) {
      if (chk)
        report(chk, node, lane,
               "leaf blocks [" + std::to_string(first) + ", " + std::to_string(first + count) + ") outside the " +
                   std::to_string(nb) + " blocks");
      return out;
    }
    out.blocks = count;
    for (uint64_t k = first; k < first + count; ++k) {
      const fmt::LeafBlock<B>& b = blocks[k];
      int real = B;  // SPEC §2.3: a short block repeats its last triangle in the unused lanes
      for (int l = 1; l < B; ++l)
        if (b.prim[l] == b.prim[l - 1]) {
          real = l;
          break;
        }
      out.prims += uint64_t(real);
      for (int l = 0; l < real; ++l) {
        if (ck && ck->prims) ck->prims->push_back(b.prim[l]);
        bool outside = false;
        for (const auto* v : {&b.v0, &b.v1, &b.v2}) {
          const double p[3] = {(*v)[0][l], (*v)[1][l], (*v)[2][l]};
          contents.grow(p);
          if (box)
            for (int a = 0; a < 3; ++a) outside |= !(box->lo[a] <= p[a] && p[a] <= box->hi[a]);
        }
        if (chk && outside)
          report(chk, node, lane,
                 "block " + std::to_string(k) + " lane " + std::to_string(l) + " (prim " + std::to_string(b.prim[l]) +
                     "): vertex not inside the leaf box");
      }
      if (chk)
        for (int l = real; l < B; ++l)
          if (!same_lane(b, l, real - 1)) {
            report(chk, node, lane,
                   "block " + std::to_string(k) + " lane " + std::to_string(l) +
                       ": padding lane differs from the triangle it repeats");
            break;
          }
    }
    return out;
  };
  return walk<W>(nodes, nn, root, uint32_t(B), ck, leaf);
}

template <int W>
BvhShape instance_bvh_shape(const fmt::WideNode<W>* nodes, uint64_t nn, const uint32_t* ids, uint64_t n_ids, uint32_t root,
                            BvhCheck* ck) {
  BvhCheck* chk = ck && ck->problems ? ck : nullptr;
  auto leaf = [&](uint32_t ref, const Box3d* box, uint32_t node, int lane, Box3d& contents) {
    LeafCount out;
    const uint64_t first = ChildRef::first_block(ref), count = ChildRef::block_count(ref);
    if (first + count > n_ids) {
      if (chk)
        report(chk, node, lane,
               "leaf entries [" + std::to_string(first) + ", " + std::to_string(first + count) + ") outside the " +
                   std::to_string(n_ids) + " instance ids");
      return out;
    }
    out.blocks = out.prims = count;
    for (uint64_t k = first; k < first + count; ++k) {
      const uint32_t id = ids[k];
      if (ck && ck->prims) ck->prims->push_back(id);
      if (!ck || !ck->items) continue;
      if (id >= ck->item_count) {
        if (chk)
          report(chk, node, lane, "instance " + std::to_string(id) + " out of range (" + std::to_string(ck->item_count) + ")");
        continue;
      }
      const ItemBound& ib = ck->items[id];
      contents.grow(ib.box);
      if (!chk || !box || ib.box.empty()) continue;
      for (int a = 0; a < 3; ++a)
        if (!(box->lo[a] <= ib.box.lo[a] + ib.tol[a] && ib.box.hi[a] - ib.tol[a] <= box->hi[a])) {
          report(chk, node, lane, "instance " + std::to_string(id) + ": transformed mesh bounds not inside the leaf box");
          break;
        }
    }
    return out;
  };
  return walk<W>(nodes, nn, root, 1, ck, leaf);
}

#define RTP_MESH_SHAPE(W, B)                                                                                              \
  template BvhShape mesh_bvh_shape<W, B>(const fmt::WideNode<W>*, uint64_t, const fmt::LeafBlock<B>*, uint64_t, uint32_t, \
                                         BvhCheck*);
RTP_MESH_SHAPE(4, 4)
RTP_MESH_SHAPE(8, 8)
RTP_MESH_SHAPE(16, 16)
RTP_MESH_SHAPE(8, 4)
RTP_MESH_SHAPE(16, 8)
#undef RTP_MESH_SHAPE
template BvhShape instance_bvh_shape<4>(const fmt::WideNode<4>*, uint64_t, const uint32_t*, uint64_t, uint32_t, BvhCheck*);
template BvhShape instance_bvh_shape<8>(const fmt::WideNode<8>*, uint64_t, const uint32_t*, uint64_t, uint32_t, BvhCheck*);
template BvhShape instance_bvh_shape<16>(const fmt::WideNode<16>*, uint64_t, const uint32_t*, uint64_t, uint32_t, BvhCheck*);

}  // namespace rtp
