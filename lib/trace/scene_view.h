#pragma once
// What the tracer needs of a scene: non-owning views of the two-level wide BVH (formats/ layout).
// Built in core by lib/bvh (InCoreScene) and, later, from a package by lib/package.
#include <cstdint>

#include "formats/bvh_layout.h"

namespace rtp {

inline constexpr uint32_t kNoDirectInstance = 0xFFFFFFFFu;

// 0 when the `count` records are one identity record (T = 0, L = L^-1 = I exactly: transform_ray would
// return the world ray unchanged), else kNoDirectInstance. For the builders of views (baseline code).
inline uint32_t direct_instance(const fmt::InstanceRecord* records, uint64_t count) {
  if (count != 1) return kNoDirectInstance;
  const fmt::InstanceRecord& r = records[0];
  for (int a = 0; a < 3; ++a) {
    if (r.translation[a] != 0) return kNoDirectInstance;
    for (int b = 0; b < 3; ++b)
      if (r.linear[3 * a + b] != (a == b ? 1.0f : 0.0f) || r.inverse_linear[3 * a + b] != (a == b ? 1.0f : 0.0f))
        return kNoDirectInstance;
  }
  return 0;
}

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
  // The scene's only instance when its record is the identity (direct_instance()): rays walk its mesh
  // in world space and skip the instance level (issue 11). The answers are the same bit for bit.
  uint32_t direct = kNoDirectInstance;
};

}  // namespace rtp
