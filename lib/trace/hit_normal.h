#pragma once
// The geometric normal of a hit, found in the batching point that made it while its chunk is resident
// (ray_stream.h: a renderer shades without reading another chunk). The kernels report (instance, prim,
// t, u, v); the triangle's vertices are in the pre-gathered leaf blocks (formats/bvh_layout.h), which
// are not ordered by prim, so the mesh BVH is walked down the boxes that hold the hit point (a few
// nodes), and the whole tree only if rounding put the point outside every box (never seen; kept so that
// a normal is always found). Internal to lib/trace.
#include <cmath>
#include <cstdint>

#include "formats/bvh_layout.h"
#include "formats/ray_file.h"
#include "layout/scene_view.h"

namespace rtp {

namespace hit_normal_detail {

// Whether p lies in child lane l of node n, its box widened by `tol` (relative to its size and place).
template <int W>
inline bool box_holds(const fmt::WideNode<W>& n, int l, const double p[3], double rel) {
  for (int k = 0; k < 3; ++k) {
    const double lo = n.lo[k][l], hi = n.hi[k][l];
    const double tol = rel * (std::fabs(lo) + std::fabs(hi) + (hi - lo)) + 1e-30;
    if (!(p[k] >= lo - tol && p[k] <= hi + tol)) return false;
  }
  return true;
}

// Walks the mesh's BVH (every lane when `rel` < 0) for the leaf lane holding triangle `prim`; writes its
// unnormalized local-space normal cross(v1 - v0, v2 - v0). False when no lane holds it.
template <int W, int B>
inline bool find_normal(const MeshBvhView<W, B>& mesh, uint32_t prim, const double p[3], double rel, float n[3]) {
  uint32_t stack[64 * W];
  int top = 0;
  stack[top++] = mesh.root;
  while (top > 0) {
    const uint32_t ref = stack[--top];
    if (fmt::ChildRef::is_empty(ref)) continue;
    if (fmt::ChildRef::is_leaf(ref)) {
      const uint32_t first = fmt::ChildRef::first_block(ref), count = fmt::ChildRef::block_count(ref);
      for (uint32_t b = first; b < first + count; ++b) {
        const fmt::LeafBlock<B>& blk = mesh.blocks[b];
        for (int j = 0; j < B; ++j) {
          if (blk.prim[j] != prim) continue;
          const float e1[3] = {blk.v1[0][j] - blk.v0[0][j], blk.v1[1][j] - blk.v0[1][j], blk.v1[2][j] - blk.v0[2][j]};
          const float e2[3] = {blk.v2[0][j] - blk.v0[0][j], blk.v2[1][j] - blk.v0[1][j], blk.v2[2][j] - blk.v0[2][j]};
          n[0] = e1[1] * e2[2] - e1[2] * e2[1];
          n[1] = e1[2] * e2[0] - e1[0] * e2[2];
          n[2] = e1[0] * e2[1] - e1[1] * e2[0];
          return true;
        }
      }
      continue;
    }
    const fmt::WideNode<W>& node = mesh.nodes[fmt::ChildRef::node_index(ref)];
    for (int l = 0; l < W; ++l) {
      if (fmt::ChildRef::is_empty(node.child[l])) continue;
      if (rel >= 0 && !box_holds<W>(node, l, p, rel)) continue;
      if (top < int(sizeof stack / sizeof stack[0])) stack[top++] = node.child[l];
    }
  }
  return false;
}

}  // namespace hit_normal_detail

// The unit geometric normal, in world space, of hit `h` (h.instance: the point's local instance index,
// as the kernels report it) of world ray `ray` in point view `view`: cross(v1 - v0, v2 - v0) of the
// triangle as stored, moved by the inverse transpose of the instance's linear part and flipped for a
// mirrored instance, so that it follows the triangle's winding in the scene. Zeros for a degenerate
// triangle or a singular instance.
template <int W, int B>
inline void hit_geometric_normal(const SceneView<W, B>& view, const fmt::Ray& ray, const fmt::Hit& h, float out[3]) {
  out[0] = out[1] = out[2] = 0.f;
  const fmt::InstanceRecord& rec = view.instances[h.instance];
  const float* m = rec.inverse_linear;  // L^-1, row-major
  double org[3], dir[3], p[3];
  for (int r = 0; r < 3; ++r) {
    const double rel[3] = {double(ray.org[0]) - rec.translation[0], double(ray.org[1]) - rec.translation[1],
                           double(ray.org[2]) - rec.translation[2]};
    org[r] = m[3 * r] * rel[0] + m[3 * r + 1] * rel[1] + m[3 * r + 2] * rel[2];
    dir[r] = m[3 * r] * double(ray.dir[0]) + m[3 * r + 1] * double(ray.dir[1]) + m[3 * r + 2] * double(ray.dir[2]);
    p[r] = org[r] + double(h.t) * dir[r];
  }
  const MeshBvhView<W, B>& mesh = view.meshes[rec.mesh];
  float n[3];
  if (!hit_normal_detail::find_normal(mesh, h.prim, p, 1e-5, n) && !hit_normal_detail::find_normal(mesh, h.prim, p, -1, n))
    return;
  // World normal = (L^-1)^T n; for a mirrored L the winding turns, det(L) < 0 flips it back.
  double w[3];
  for (int c = 0; c < 3; ++c) w[c] = double(m[c]) * n[0] + double(m[3 + c]) * n[1] + double(m[6 + c]) * n[2];
  if (rec.flags & 1u) w[0] = -w[0], w[1] = -w[1], w[2] = -w[2];
  const double len = std::sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
  if (!(len > 0) || !std::isfinite(len)) return;
  for (int c = 0; c < 3; ++c) out[c] = float(w[c] / len);
}

}  // namespace rtp
