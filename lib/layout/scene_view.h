#pragma once
// What the tracer needs of a scene: non-owning views of the two-level wide BVH (formats/ layout).
// Built in core by lib/bvh (InCoreScene) and, later, from a package by lib/package.
#include <cstdint>
#include <vector>

#include "formats/bvh_layout.h"
#include "formats/ray_file.h"  // fmt::Hit (name_merged_hits)

namespace rtp {

inline constexpr uint32_t kNoDirectInstance = 0xFFFFFFFFu;

// 0 when the `count` records are one identity record (T = 0, L^-1 = I exactly: transform_ray would
// return the world ray unchanged), else kNoDirectInstance. For the builders of views (baseline code).
inline uint32_t direct_instance(const fmt::InstanceRecord* records, uint64_t count) {
  if (count != 1) return kNoDirectInstance;
  const fmt::InstanceRecord& r = records[0];
  for (int a = 0; a < 3; ++a) {
    if (r.translation[a] != 0) return kNoDirectInstance;
    for (int b = 0; b < 3; ++b)
      if (r.inverse_linear[3 * a + b] != (a == b ? 1.0f : 0.0f)) return kNoDirectInstance;
  }
  return 0;
}

// How an instance record moves a ray, worked out once per view so that walks need not test it per
// visit (issue 11). kAxes: L^-1 is a signed permutation (translations, axis flips, quarter turns;
// Lantern's and BoomBox's nodes), so org' = ±(org − T)[axis] and dir' = ±dir[axis], exactly as
// transform_ray's double products give them whenever no component is zero (trace: move_ray_by_axes),
// and 1/dir' is ±1/dir.
struct AxisMove {
  enum Kind : uint8_t { kGeneral = 0, kNone = 1, kAxes = 2 };  // kNone: T = 0 and L^-1 = I exactly
  uint8_t axis[3];                                             // row r of L^-1 has its one nonzero entry in column axis[r]
  uint8_t neg;                                                 // bit r: that entry is -1
  uint8_t kind;
};

inline AxisMove axis_move(const fmt::InstanceRecord& r) {
  AxisMove m{{0, 0, 0}, 0, AxisMove::kGeneral};
  uint32_t columns = 0;
  for (int row = 0; row < 3; ++row) {
    int found = -1;
    for (int c = 0; c < 3; ++c) {
      const float x = r.inverse_linear[3 * row + c];
      if (x == 1.0f || x == -1.0f) {
        if (found >= 0) return {{0, 0, 0}, 0, AxisMove::kGeneral};
        found = c;
        m.neg |= uint8_t((x < 0 ? 1u : 0u) << row);
      } else if (!(x == 0.0f)) {
        return {{0, 0, 0}, 0, AxisMove::kGeneral};  // also NaN
      }
    }
    if (found < 0 || (columns >> found) & 1u) return {{0, 0, 0}, 0, AxisMove::kGeneral};
    columns |= 1u << found;
    m.axis[row] = uint8_t(found);
  }
  const bool identity = m.neg == 0 && m.axis[0] == 0 && m.axis[1] == 1 && m.axis[2] == 2;
  const bool no_translation = r.translation[0] == 0 && r.translation[1] == 0 && r.translation[2] == 0;
  m.kind = identity && no_translation ? AxisMove::kNone : AxisMove::kAxes;
  return m;
}

// One AxisMove per record, for the view's owner to keep beside the records.
inline std::vector<AxisMove> axis_moves(const fmt::InstanceRecord* records, uint64_t count) {
  std::vector<AxisMove> out(count);
  for (uint64_t i = 0; i < count; ++i) out[i] = axis_move(records[i]);
  return out;
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
  const uint32_t* top_instances = nullptr;  // instance indices referenced by top-level leaves
  const fmt::InstanceRecord* instances = nullptr;
  const MeshBvhView<W, B>* meshes = nullptr;  // indexed by InstanceRecord::mesh
  // The scene's only instance when its record is the identity (direct_instance()): rays walk its mesh
  // in world space and skip the instance level (issue 11). The answers are the same bit for bit.
  uint32_t direct = kNoDirectInstance;
  // axis_moves(instances): how each record moves a ray; nullptr: every visit takes the general path
  // (transform_ray). The answers are the same bit for bit either way.
  const AxisMove* moves = nullptr;
  // A mesh merged from several instances that share one transform (InCoreScene,
  // BuildOptions::merge_instances): its triangles are the instances' meshes in instance order, triangle
  // p of it is triangle p - part_first[k] of instance part_instance[k] for the last k with
  // part_first[k] <= p. The public trace calls (trace.h) report hits under those names; the kernels see
  // the merged mesh only. Ordering hits by (t, merged triangle) is ordering them by (t, instance,
  // triangle), so every answer is the one the unmerged scene gives. parts = 0: no merged mesh.
  const uint32_t* part_first = nullptr;
  const uint32_t* part_instance = nullptr;
  uint32_t parts = 0;
};

// The original (instance, triangle) of a hit on a merged mesh (SceneView::part_first); misses and
// views without one are left as they are.
template <int W, int B>
inline void name_merged_hits(const SceneView<W, B>& s, fmt::Hit* hits, size_t n) {
  if (s.parts == 0) return;
  for (size_t i = 0; i < n; ++i) {
    fmt::Hit& h = hits[i];
    if (h.instance == fmt::Hit::kNone) continue;
    uint32_t lo = 0, hi = s.parts;  // the last k with part_first[k] <= prim
    while (hi - lo > 1) {
      const uint32_t mid = (lo + hi) / 2;
      (s.part_first[mid] <= h.prim ? lo : hi) = mid;
    }
    h.instance = s.part_instance[lo];
    h.prim -= s.part_first[lo];
  }
}

}  // namespace rtp
