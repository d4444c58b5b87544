#pragma once
// Single-node and single-block kernels as traversal runs them, callable for one ray on any ISA:
// tests compare the SIMD paths against the scalar reference lane by lane, bit for bit.
#include <cstdint>

#include "formats/bvh_layout.h"
#include "formats/ray_file.h"
#include "trace/trace.h"

namespace rtp {

// One ray against one leaf block: bit i of `mask` is set when triangle lane i is hit with t in
// [ray.tnear, tfar] (Woop 2013 watertight test); t, u, v are defined for those lanes only.
template <int B>
struct BlockHits {
  uint32_t mask = 0;
  alignas(64) float t[B];
  alignas(64) float u[B];
  alignas(64) float v[B];
};

// One ray against one W-wide node: bit i of `mask` is set when child box i overlaps [ray.tnear, tfar]
// (Ize 2013 robust slab test); dist[i] is the entry distance of those lanes.
template <int W>
struct NodeHits {
  uint32_t mask = 0;
  alignas(64) float dist[W];
};

// The ray's tnear/tfar are the interval. Invalid rays (formats/ray_file.h) and zero directions give
// mask = 0. An ISA this CPU lacks falls back to the best one it has (see detect_isa()).
template <int B>
void intersect_block(Isa isa, const fmt::LeafBlock<B>& block, const fmt::Ray& ray, BlockHits<B>* out);
template <int W>
void intersect_node(Isa isa, const fmt::WideNode<W>& node, const fmt::Ray& ray, NodeHits<W>* out);

}  // namespace rtp
