#pragma once
// What the tracer needs of a scene: non-owning views of the two-level wide BVH (formats/ layout).
// Built in core by lib/bvh (InCoreScene) and, later, from a package by lib/package.
#include <cstdint>

#include "formats/bvh_layout.h"

namespace rtp {

// One mesh's BVH in its local space.
template <int W, int B>
struct MeshBvhView {
  const fmt::WideNode<W>* nodes = nullptr;
  const fmt::LeafBlock<B>* blocks = nullptr;
  uint32_t root = fmt::ChildRef::kEmpty;  // a ChildRef: an inner node, or a leaf for tiny meshes
};

// Two levels (Molenaar 2019 §4.1): a W-wide instance BVH whose leaves reference instances, each
// instance pointing at a mesh BVH. Top-level leaf refs use the ChildRef leaf encoding with
// first_block = first entry in `top_instances` and block_count = number of entries (1..16).
template <int W, int B>
struct SceneView {
  const fmt::WideNode<W>* top_nodes = nullptr;
  uint32_t top_root = fmt::ChildRef::kEmpty;
  const uint32_t* top_instances = nullptr;     // instance indices referenced by top-level leaves
  const fmt::InstanceRecord* instances = nullptr;
  const MeshBvhView<W, B>* meshes = nullptr;   // indexed by InstanceRecord::mesh
};

}  // namespace rtp
