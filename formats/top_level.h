#pragma once
// Top-level BVH over batching points (Molenaar 2019 §4.1: 4-wide, parent pointers so a paused ray
// resumes from (node, per-level child mask) without a stack), formats/SPEC.md §4.1.
#include <cstddef>
#include <cstdint>

namespace rtp::fmt {

// 128 bytes:
//   0    float lo[3][4]   child box minima, SoA (x lanes, y lanes, z lanes)
//   48   float hi[3][4]   child box maxima
//   96   uint32 child[4]  ChildRef encoding of bvh_layout.h: inner = node index; leaf = bit 31 |
//                         batching point index (bits 0..30); 0xFFFFFFFF empty (box lo=+inf, hi=-inf)
//   112  uint32 parent    parent node index, 0xFFFFFFFF for the root (node 0)
//   116  uint32 slot      this node's lane in its parent (0..3), 0 for the root
//   120  uint32 depth     root = 0
//   124  uint32 reserved  0
struct TopNode {
  static constexpr uint32_t kLeafBit = 0x80000000u;
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
  float lo[3][4];
  float hi[3][4];
  uint32_t child[4];
  uint32_t parent;
  uint32_t slot;
  uint32_t depth;
  uint32_t reserved;
};
static_assert(sizeof(TopNode) == 128 && offsetof(TopNode, child) == 96 && offsetof(TopNode, parent) == 112);

}  // namespace rtp::fmt
