#pragma once
// On-disk and in-memory layout of the wide BVH that every chunk carries (formats/SPEC.md §2).
// Plain old data, little-endian, no pointers: the builder (lib/bvh) writes these, the tracer
// (lib/trace) reads them; nothing else is shared between the two.
#include <cstddef>
#include <cstdint>
#include <type_traits>

namespace rtp::fmt {

// A child reference, 32 bits (SPEC §2.1):
//   0xFFFFFFFF                  empty lane (its box is lo = +inf, hi = -inf)
//   bit 31 = 0                  inner node: bits 0..30 = node index
//   bit 31 = 1                  leaf: bits 0..26 = first leaf block, bits 27..30 = block count - 1
//                               (1..16 consecutive blocks)
struct ChildRef {
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
  static constexpr uint32_t kLeafBit = 0x80000000u;
  static constexpr uint32_t kMaxNodes = 0x7FFFFFFFu;
  static constexpr uint32_t kMaxBlockIndex = (1u << 27) - 1;
  static constexpr uint32_t kMaxBlocksPerLeaf = 16;

  static constexpr uint32_t inner(uint32_t node) { return node; }
  static constexpr uint32_t leaf(uint32_t first_block, uint32_t block_count) {
    return kLeafBit | ((block_count - 1) << 27) | first_block;
  }
  static constexpr bool is_empty(uint32_t r) { return r == kEmpty; }
  static constexpr bool is_leaf(uint32_t r) { return (r & kLeafBit) != 0 && r != kEmpty; }
  static constexpr uint32_t node_index(uint32_t r) { return r; }
  static constexpr uint32_t first_block(uint32_t r) { return r & kMaxBlockIndex; }
  static constexpr uint32_t block_count(uint32_t r) { return ((r >> 27) & 0xFu) + 1; }
};

// A W-wide BVH node (Benthin 2008 §4 multi-BVH; Molenaar 2019 §4.1 octant orders), SPEC §2.2.
//   offset 0          float lo[3][W]   child box minima, SoA: x lanes, then y lanes, then z lanes
//   offset 12W        float hi[3][W]   child box maxima, same order
//   offset 24W        uint32 child[W]  ChildRef per lane; filled lanes first, empty lanes last
//   offset 28W        uint8 order[8][W] per ray octant (bit0: dir.x<0, bit1: dir.y<0, bit2: dir.z<0),
//                                      the lanes in front-to-back order of their box centres along
//                                      that octant's diagonal; empty lanes listed last
//   size  36W bytes  (W=4: 144, W=8: 288, W=16: 576), alignment 4W
template <int W>
struct alignas(4 * W) WideNode {
  static_assert(W == 4 || W == 8 || W == 16);
  float lo[3][W];
  float hi[3][W];
  uint32_t child[W];
  uint8_t order[8][W];
};
static_assert(sizeof(WideNode<4>) == 144 && sizeof(WideNode<8>) == 288 && sizeof(WideNode<16>) == 576);
static_assert(offsetof(WideNode<8>, hi) == 96 && offsetof(WideNode<8>, child) == 192 && offsetof(WideNode<8>, order) == 224);
static_assert(std::is_trivially_copyable_v<WideNode<8>> && std::is_standard_layout_v<WideNode<8>>);

// A pre-gathered SoA block of B triangles (Benthin 2008 §4.3 "pre-gathered leaves"), SPEC §2.3.
//   offset 0     float v0[3][B]  first vertex, SoA x/y/z lanes
//   offset 12B   float v1[3][B]
//   offset 24B   float v2[3][B]
//   offset 36B   uint32 prim[B]  triangle index within the mesh (Mesh::source maps it to glTF)
//   size 40B bytes (B=4: 160, B=8: 320, B=16: 640), alignment 4B
// A short block is padded by repeating its last triangle (vertices and prim id): no lane holds
// garbage, and a repeated lane can only report the same hit again.
template <int B>
struct alignas(4 * B) LeafBlock {
  static_assert(B == 4 || B == 8 || B == 16);
  float v0[3][B];
  float v1[3][B];
  float v2[3][B];
  uint32_t prim[B];
};
static_assert(sizeof(LeafBlock<4>) == 160 && sizeof(LeafBlock<8>) == 320 && sizeof(LeafBlock<16>) == 640);
static_assert(offsetof(LeafBlock<8>, v1) == 96 && offsetof(LeafBlock<8>, prim) == 288);

// An instance as the tracer sees it (SPEC §2.4, version 6.0), 72 bytes: what moves a ray, nothing else
// (6.0 dropped the forward L and the glTF source fields, 40 of 112 bytes no tracer read; the source
// fields are in the instance table, InstanceRef):
//   offset 0   double translation[3]     local->world translation T, as the glTF nodes compose it
//   offset 24  float  inverse_linear[9]  world->local 3x3 L^-1, row-major, inverted in double then
//                                        rounded; all zeros when L is singular (the instance is never hit)
//   offset 60  uint32 mesh               mesh (BVH) index
//   offset 64  uint32 flags              bit 0: mirrored (det of the stored L^-1 < 0)
//   offset 68  uint32 reserved           0
// A world ray enters the instance as org' = L^-1 (org - T), dir' = L^-1 dir, evaluated in double: the
// translation is kept apart so a far instance (T = 3000000.3) is as exact as one at the origin.
struct InstanceRecord {
  double translation[3];
  float inverse_linear[9];
  uint32_t mesh;
  uint32_t flags;
  uint32_t reserved;
};
static_assert(sizeof(InstanceRecord) == 72 && alignof(InstanceRecord) == 8);
static_assert(offsetof(InstanceRecord, inverse_linear) == 24 && offsetof(InstanceRecord, mesh) == 60 &&
              offsetof(InstanceRecord, reserved) == 68);

// One scene instance in the instance table (SPEC §2.5, version 5.0), 20 bytes: where its record is, not
// the record (each record is stored once, in the batching point that traces it: a 10^6-instance
// forest's table was 112 MB raw, a third of its package, repeating the points' records).
//   offset 0  uint32 mesh                 scene mesh index
//   offset 4  uint32 point                batching point whose section 5 holds the instance's record (for a
//                                         unique mesh: its first piece's, by point then local index), or
//                                         kNoPoint: no point holds it (a mesh without triangles)
//   offset 8  uint32 local                that record's index in the point's section 5 (0 with kNoPoint)
//   offset 12 uint32 source_node          glTF node
//   offset 16 uint32 source_gpu_instance  EXT_mesh_gpu_instancing index or 0xFFFFFFFF
struct InstanceRef {
  static constexpr uint32_t kNoPoint = 0xFFFFFFFFu;
  uint32_t mesh;
  uint32_t point;
  uint32_t local;
  uint32_t source_node;
  uint32_t source_gpu_instance;
};
static_assert(sizeof(InstanceRef) == 20 && alignof(InstanceRef) == 4);
static_assert(offsetof(InstanceRef, point) == 4 && offsetof(InstanceRef, local) == 8 &&
              offsetof(InstanceRef, source_gpu_instance) == 16);

}  // namespace rtp::fmt
