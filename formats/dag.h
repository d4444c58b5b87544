#pragma once
// Occlusion-culling proxies (formats/SPEC.md §4.5, version 3.0): per batching point a conservative
// voxel grid stored as a sparse voxel DAG whose nodes live in one pool shared by every batching point
// of the package (Molenaar 2019 §3.3; Kämpe et al. 2013 bottom-up hashing). Version 3.0 adds inline leaves.
#include <bit>
#include <cstddef>
#include <cstdint>

namespace rtp::fmt {

// Child references in the DAG pool.
inline constexpr uint32_t kDagEmpty = 0xFFFFFFFEu;  // nothing set (a root only: every ray is culled)
inline constexpr uint32_t kDagFull = 0xFFFFFFFFu;   // every cell of the region set (a root only; children use the full mask)
inline constexpr uint32_t kDagLeafEdge = 4;         // a leaf is a 4x4x4 block of cells: one uint64 mask
inline constexpr uint32_t kDagMinResolution = 4, kDagMaxResolution = 1024;

// Per batching point grid (section kPointGrids of the descriptors chunk), 32 bytes:
//   0  float  origin[3]   world position of cell (0,0,0)'s minimum corner
//   12 float  cell        edge of the cubic cells (world units, > 0)
//   16 uint32 resolution  R cells per axis, a power of two in [4, 1024]; the root covers R^3 cells
//                         (or kDagBoxes, version 7.0: see below)
//   20 uint32 root        root reference at level log2(R/4) (level 0 = a leaf index, above = a node
//                         word offset), or kDagEmpty / kDagFull
//   24 float  margin      world distance every set cell was grown by when voxelizing (vertex and
//                         instance-transform rounding; SPEC §4.5 states the bound)
//   28 float  ray_rel     the ray test grows every cell further by ray_rel * (|org|_inf + G),
//                         G = max |coordinate| of the grid box (rounding of the ray in the kernels)
// Version 7.0: a grid whose resolution is kDagBoxes is no voxel grid but the point's instance boxes:
// root is the first of its nodes in section kCullNodes of the DAG pool chunk, the point's instance BVH
// (SPEC §4.2) node for node with each box rounded outward to 8 bits (CullNode below); origin, cell,
// margin and ray_rel are 0. A ray is culled when it meets no leaf box within its interval: boxes that
// contain the ones the point's own instance walk tests, so culling cannot change an answer.
inline constexpr uint32_t kDagBoxes = 0;

// One node of an instance-box proxy (section kCullNodes), 24 + 10W bytes (W = the package's BVH width):
//   0       float   origin[3]   per axis, the smallest lo of the node's filled lanes
//   12      float   scale[3]    per axis, >= 0: a lane's box is origin + q * scale, q = 0..255, in double
//   24      uint8   lo[3][W]    per axis and lane, q of the box minimum (rounded down: <= the BVH's lo)
//   24+3W   uint8   hi[3][W]    q of the box maximum (rounded up: >= the BVH's hi)
//   24+6W   uint32  child[W]    the BVH node's ChildRef (formats/bvh_layout.h): an inner node's index
//                               relative to the point's first node, a leaf (an instance), or empty
// Every inner child's index is greater than its parent's, and no node has two parents.
template <int W>
struct CullNode {
  static_assert(W == 4 || W == 8 || W == 16);
  float origin[3];
  float scale[3];
  uint8_t lo[3][W];
  uint8_t hi[3][W];
  uint32_t child[W];
};
static_assert(sizeof(CullNode<4>) == 64 && sizeof(CullNode<8>) == 104 && sizeof(CullNode<16>) == 184);
static_assert(offsetof(CullNode<8>, lo) == 24 && offsetof(CullNode<8>, hi) == 48 && offsetof(CullNode<8>, child) == 72);
// A quantized plane as the writer rounds it and every reader decodes it, in double (the product of a
// float and a q <= 255 is exact).
inline double cull_plane(float origin, float scale, uint8_t q) { return double(origin) + double(q) * double(scale); }
// sizeof(CullNode<w>) for a width known at run time.
inline constexpr size_t cull_node_bytes(uint32_t w) { return 24 + 10 * size_t(w); }
static_assert(cull_node_bytes(4) == 64 && cull_node_bytes(8) == 104 && cull_node_bytes(16) == 184);
struct DagGrid {
  float origin[3];
  float cell;
  uint32_t resolution;
  uint32_t root;
  float margin;
  float ray_rel;
};
static_assert(sizeof(DagGrid) == 32 && offsetof(DagGrid, cell) == 12 && offsetof(DagGrid, root) == 20 &&
              offsetof(DagGrid, ray_rel) == 28);

// DAG pool (chunk kind 7, resident): section kDagNodes (uint32 words) and kDagLeaves (uint64 masks).
// An inner node at word offset o:
//   word o       bits 0..7 child mask (child c = x | y << 1 | z << 2, 1 = the child's region is
//                non-empty); bits 8..15 full mask (a subset of the child mask: the child's region is
//                entirely set and has no reference); bits 16..23 inline mask (level-1 nodes only, a
//                subset of child mask & ~full mask: that child's leaf mask is stored in the node);
//                bits 24..31 zero
//   words o+1..  per child in the child mask but not in the full mask, in ascending child order:
//                inline children two words (the leaf mask, low half first), the others one uint32
//                reference: a word offset (children above level 0) or a leaf index (children at
//                level 0). A node has at least one non-full child or a mask != 0xFF.
// A leaf mask: bit x + 4y + 16z is the cell (x, y, z) of the 4^3 block; never 0, never all ones.
// The converter inlines a leaf that only one level-1 node of its batching point uses (a reference
// plus a pooled mask cost 12 bytes, an inline mask 8), and pools the others (version 3.0).
// Identical nodes (same words) and identical leaves are stored once in the whole package.
inline constexpr uint32_t dag_child_mask(uint32_t word) { return word & 0xFFu; }
inline constexpr uint32_t dag_full_mask(uint32_t word) { return (word >> 8) & 0xFFu; }
inline constexpr uint32_t dag_inline_mask(uint32_t word) { return (word >> 16) & 0xFFu; }
// Words of the node whose first word is `word`: 1 + one per reference + two per inline leaf.
inline constexpr uint32_t dag_node_words(uint32_t word) {
  return 1u + uint32_t(std::popcount(dag_child_mask(word) & ~dag_full_mask(word))) +
         uint32_t(std::popcount(dag_inline_mask(word)));
}
// Word index, after the node's first word, where child c's reference or inline mask starts.
inline constexpr uint32_t dag_child_slot(uint32_t word, uint32_t c) {
  const uint32_t below = (1u << c) - 1u;
  return uint32_t(std::popcount(dag_child_mask(word) & ~dag_full_mask(word) & below)) +
         uint32_t(std::popcount(dag_inline_mask(word) & below));
}

}  // namespace rtp::fmt
