#pragma once
// An independent checker for the wide BVH layout (formats/SPEC.md §2), used by the test_bvh_*.cpp
// tests. It reads only formats/ structs and recomputes everything it checks (bounds, octant orders,
// costs) from them and from the source mesh; it shares no code with lib/bvh except the definition of
// the octant key, which it re-derives here on purpose.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "bvh/bvh.h"
#include "formats/bvh_layout.h"
#include "scene/scene.h"

namespace rtp::bvhtest {

using fmt::ChildRef;

// Bounds in double (float values convert exactly).
struct DBox {
  double lo[3] = {INFINITY, INFINITY, INFINITY};
  double hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  void grow(double x, double y, double z) {
    const double p[3] = {x, y, z};
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], p[a]);
      hi[a] = std::max(hi[a], p[a]);
    }
  }
  void grow(const DBox& b) {
    for (int a = 0; a < 3; ++a) {
      lo[a] = std::min(lo[a], b.lo[a]);
      hi[a] = std::max(hi[a], b.hi[a]);
    }
  }
  double area() const {  // full surface area; 0 when empty
    if (!(lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2])) return 0;
    const double x = hi[0] - lo[0], y = hi[1] - lo[1], z = hi[2] - lo[2];
    return 2 * (x * y + y * z + z * x);
  }
};

// The octant key of SPEC/bvh.h, re-derived: dot(lo + hi, d), d_k = -1 when octant bit k is set.
inline double key_of(const float lo[3], const float hi[3], int octant) {
  double d[3];
  for (int k = 0; k < 3; ++k) d[k] = (octant >> k & 1) ? -1.0 : 1.0;
  return ((double(lo[0]) + double(hi[0])) * d[0] + (double(lo[1]) + double(hi[1])) * d[1]) +
         (double(lo[2]) + double(hi[2])) * d[2];
}

struct WalkResult {
  uint32_t max_depth = 0;  // inner nodes on the longest path
  uint64_t nodes = 0, leaves = 0, blocks = 0, filled = 0, primitives = 0;
  double box_area_sum = 0;   // Σ SA(inner node), absolute (a node's box: the union of its lane boxes)
  double leaf_cost_sum = 0;  // Σ SA(leaf lane box)·⌈N/B⌉, absolute
  double root_area = 0;      // SA of the root node's box (of the exact bounds for a root leaf)
  DBox bounds;               // exact bounds of everything in the tree
};

// Walks a W-wide tree from `root`. `leaf(ref, prims_out)` checks one leaf and returns the exact bounds
// of what it holds (prims_out = its primitive count). `tight`: every lane box must equal the exact
// bounds below it (lib/bvh's boxes are unions of float triangle boxes), not only contain them.
template <int W>
WalkResult walk_tree(const std::vector<fmt::WideNode<W>>& nodes, uint32_t root, bool tight, uint32_t cost_block,
                     const std::function<DBox(uint32_t, uint64_t&)>& leaf) {
  WalkResult res;
  std::vector<char> reached(nodes.size(), 0);
  // Returns exact bounds below `ref`; lane_area: SA of the lane box that holds ref (< 0 at the root).
  std::function<DBox(uint32_t, uint32_t, double)> visit = [&](uint32_t ref, uint32_t depth, double lane_area) -> DBox {
    if (ChildRef::is_leaf(ref)) {
      uint64_t n = 0;
      DBox b = leaf(ref, n);
      res.leaves += 1;
      res.primitives += n;
      const uint64_t blocks = (n + cost_block - 1) / cost_block;
      res.blocks += blocks;
      if (lane_area < 0) res.root_area = lane_area = b.area();
      res.leaf_cost_sum += lane_area * double(blocks);
      return b;
    }
    DBox none;
    EXPECT_LT(ChildRef::node_index(ref), nodes.size()) << "inner ref out of range";
    if (ChildRef::node_index(ref) >= nodes.size()) return none;
    const uint32_t ni = ChildRef::node_index(ref);
    EXPECT_FALSE(reached[ni]) << "node " << ni << " reached twice";
    if (reached[ni]) return none;
    reached[ni] = 1;
    res.nodes += 1;
    res.max_depth = std::max(res.max_depth, depth);
    const fmt::WideNode<W>& n = nodes[ni];
    int filled = 0;
    while (filled < W && !ChildRef::is_empty(n.child[filled])) ++filled;
    EXPECT_GE(filled, 2) << "node " << ni << " has " << filled << " filled lanes";
    res.filled += uint64_t(filled);
    for (int i = filled; i < W; ++i) {  // no garbage after the filled lanes
      EXPECT_EQ(n.child[i], ChildRef::kEmpty) << "node " << ni << " lane " << i;
      for (int a = 0; a < 3; ++a) {
        EXPECT_TRUE(n.lo[a][i] == INFINITY) << "node " << ni << " empty lane " << i << " lo";
        EXPECT_TRUE(n.hi[a][i] == -INFINITY) << "node " << ni << " empty lane " << i << " hi";
      }
    }
    // Octant orders: filled lanes by (key, lane), then empty lanes ascending.
    for (int o = 0; o < 8; ++o) {
      std::vector<int> expect(W);
      for (int i = 0; i < W; ++i) expect[i] = i;
      std::stable_sort(expect.begin(), expect.begin() + filled, [&](int a, int b) {
        const float la[3] = {n.lo[0][a], n.lo[1][a], n.lo[2][a]}, ha[3] = {n.hi[0][a], n.hi[1][a], n.hi[2][a]};
        const float lb[3] = {n.lo[0][b], n.lo[1][b], n.lo[2][b]}, hb[3] = {n.hi[0][b], n.hi[1][b], n.hi[2][b]};
        return key_of(la, ha, o) < key_of(lb, hb, o);
      });
      for (int i = 0; i < W; ++i) EXPECT_EQ(int(n.order[o][i]), expect[i]) << "node " << ni << " octant " << o << " pos " << i;
    }
    DBox node_box, below;
    for (int i = 0; i < filled; ++i) {
      DBox lane_box;
      lane_box.grow(n.lo[0][i], n.lo[1][i], n.lo[2][i]);
      lane_box.grow(n.hi[0][i], n.hi[1][i], n.hi[2][i]);
      const DBox b = visit(n.child[i], depth + 1, lane_box.area());
      for (int a = 0; a < 3; ++a) {
        EXPECT_LE(double(n.lo[a][i]), b.lo[a]) << "node " << ni << " lane " << i << " axis " << a << " does not contain lo";
        EXPECT_GE(double(n.hi[a][i]), b.hi[a]) << "node " << ni << " lane " << i << " axis " << a << " does not contain hi";
        if (tight) {
          EXPECT_EQ(double(n.lo[a][i]), b.lo[a]) << "node " << ni << " lane " << i << " not tight";
          EXPECT_EQ(double(n.hi[a][i]), b.hi[a]) << "node " << ni << " lane " << i << " not tight";
        }
      }
      node_box.grow(n.lo[0][i], n.lo[1][i], n.lo[2][i]);
      node_box.grow(n.hi[0][i], n.hi[1][i], n.hi[2][i]);
      below.grow(b);
    }
    res.box_area_sum += node_box.area();
    if (lane_area < 0) res.root_area = node_box.area();
    return below;
  };
  if (!ChildRef::is_empty(root)) res.bounds = visit(root, 1, -1.0);
  for (size_t i = 0; i < nodes.size(); ++i) EXPECT_TRUE(reached[i]) << "node " << i << " unreachable";
  return res;
}

struct MeshCheck {
  WalkResult walk;
  double c_box = 0, c_tri = 0;
};

// Full check of a mesh BVH against its mesh: structure, exact bounds, every triangle in exactly one
// leaf lane with its exact vertices, padding only at the end of a leaf's last block, every block used
// once, depth <= max_depth, and the reported statistics recomputed.
template <int W, int B>
MeshCheck check_mesh_bvh(const Mesh& mesh, const MeshBvh<W, B>& bvh, uint32_t max_depth, const std::string& what) {
  SCOPED_TRACE(what);
  const size_t tris = mesh.indices.size() / 3;
  std::vector<char> seen(tris, 0), block_used(bvh.blocks.size(), 0);
  auto same_bits = [](float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; };
  auto leaf = [&](uint32_t ref, uint64_t& count) -> DBox {
    DBox b;
    const uint32_t first = ChildRef::first_block(ref), nb = ChildRef::block_count(ref);
    EXPECT_LE(uint64_t(first) + nb, bvh.blocks.size()) << "leaf blocks out of range";
    if (uint64_t(first) + nb > bvh.blocks.size()) return b;
    uint32_t real = 0, prev = 0xFFFFFFFFu;
    bool padding = false;
    for (uint32_t k = 0; k < nb; ++k) {
      EXPECT_FALSE(block_used[first + k]) << "block " << first + k << " in two leaves";
      block_used[first + k] = 1;
      const fmt::LeafBlock<B>& blk = bvh.blocks[first + k];
      for (int l = 0; l < B; ++l) {
        const uint32_t prim = blk.prim[l];
        if (prim == prev) padding = true;
        if (padding) {
          // Padding repeats the last real triangle, only in the last block.
          EXPECT_EQ(k, nb - 1) << "padding before the last block";
          EXPECT_EQ(prim, prev) << "padding lane holds another triangle";
          const int pl = int((real - 1) % B);
          const fmt::LeafBlock<B>& pb = bvh.blocks[first + (real - 1) / B];
          for (int a = 0; a < 3; ++a) {
            EXPECT_TRUE(same_bits(blk.v0[a][l], pb.v0[a][pl]) && same_bits(blk.v1[a][l], pb.v1[a][pl]) &&
                        same_bits(blk.v2[a][l], pb.v2[a][pl]))
                << "padding lane vertices differ";
          }
          continue;
        }
        EXPECT_LT(prim, tris) << "prim out of range";
        if (prim >= tris) continue;
        EXPECT_FALSE(seen[prim]) << "triangle " << prim << " in two lanes";
        seen[prim] = 1;
        ++real;
        prev = prim;
        for (int v = 0; v < 3; ++v) {
          const Vec3f& p = mesh.positions[mesh.indices[3 * size_t(prim) + size_t(v)]];
          const float* lane_v[3] = {v == 0   ? blk.v0[0]
                                    : v == 1 ? blk.v1[0]
                                             : blk.v2[0],
                                    v == 0   ? blk.v0[1]
                                    : v == 1 ? blk.v1[1]
                                             : blk.v2[1],
                                    v == 0   ? blk.v0[2]
                                    : v == 1 ? blk.v1[2]
                                             : blk.v2[2]};
          for (int a = 0; a < 3; ++a)
            EXPECT_TRUE(same_bits(lane_v[a][l], p[a])) << "triangle " << prim << " vertex " << v << " differs";
          b.grow(p.x, p.y, p.z);
        }
      }
    }
    EXPECT_EQ(nb, (real + B - 1) / B) << "a leaf block holds only padding";
    count = real;
    return b;
  };
  MeshCheck out;
  out.walk = walk_tree<W>(bvh.nodes, bvh.root, /*tight=*/true, B, leaf);
  for (size_t t = 0; t < tris; ++t)
    if (!seen[t]) ADD_FAILURE() << "triangle " << t << " missing";
  for (size_t k = 0; k < block_used.size(); ++k)
    if (!block_used[k]) ADD_FAILURE() << "block " << k << " unreferenced";
  EXPECT_LE(out.walk.max_depth, max_depth);
  if (tris == 0) {
    EXPECT_EQ(bvh.root, ChildRef::kEmpty);
    EXPECT_TRUE(bvh.nodes.empty() && bvh.blocks.empty());
  }

  // Statistics, recomputed from the layout (relative to the root's area; ratio 1 if it is 0).
  const double root_area = out.walk.root_area;
  auto rel = [&](double sum, double count) { return root_area > 0 ? sum / root_area : count; };
  out.c_box = rel(out.walk.box_area_sum, double(out.walk.nodes));
  out.c_tri = rel(out.walk.leaf_cost_sum, double(out.walk.blocks));
  const BvhStats& s = bvh.stats;
  EXPECT_EQ(s.nodes, bvh.nodes.size());
  EXPECT_EQ(s.blocks, bvh.blocks.size());
  EXPECT_EQ(s.leaves, out.walk.leaves);
  EXPECT_EQ(s.primitives, tris);
  EXPECT_EQ(s.max_depth, out.walk.max_depth);
  EXPECT_EQ(s.node_bytes, bvh.nodes.size() * sizeof(fmt::WideNode<W>));
  EXPECT_EQ(s.block_bytes, bvh.blocks.size() * sizeof(fmt::LeafBlock<B>));
  EXPECT_NEAR(s.c_box, out.c_box, 1e-9 * std::max(1.0, out.c_box));
  EXPECT_NEAR(s.c_tri, out.c_tri, 1e-9 * std::max(1.0, out.c_tri));
  EXPECT_DOUBLE_EQ(s.sah, s.c_box + s.c_tri);
  if (!bvh.nodes.empty()) {
    EXPECT_DOUBLE_EQ(s.branching, double(out.walk.filled) / double(out.walk.nodes));
    EXPECT_GE(s.branching, 2.0);
    EXPECT_LE(s.branching, double(W));
    EXPECT_GE(s.c_box, 1.0);  // the root counts 1
  }
  if (tris) {
    EXPECT_DOUBLE_EQ(s.leaf_fill, double(tris) / (double(bvh.blocks.size()) * B));
    EXPECT_GT(s.leaf_fill, 0.0);
    EXPECT_LE(s.leaf_fill, 1.0);
  }
  return out;
}

}  // namespace rtp::bvhtest
