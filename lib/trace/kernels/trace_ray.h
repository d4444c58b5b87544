#pragma once
// One ray through the two-level BVH (instance level, then mesh level) and the batch entry points,
// generic over a kernel set K (kernels_scalar.h / kernels_simd.h). Each ISA translation unit
// includes this (through multi_hit.h) once inside its own namespace and instantiates it with
// RTP_DEFINE_ISA_ENTRY_POINTS.
#include <cmath>
#include <cstddef>
#include <type_traits>

#include "trace/kernels/isa_entry.h"
#include "trace/kernels/kernel_common.h"
#include "trace/kernels/ray_prep.h"
#include "layout/scene_view.h"
#include "trace/kernels/traverse_active.h"
#include "trace/kernels/traverse_octant.h"

namespace rtp::RTP_ISA_NS {

// The best hit so far; `t` doubles as the live tfar of the traversal. Equal t: the smaller
// (instance, prim) wins, so the answer does not depend on ISA, order, W or B.
struct Closest {
  float t;
  uint32_t instance;
  uint32_t prim;
  float u, v;
};

template <TraversalOrder O, class K, int W, bool kFixedFar = false, class LeafFn, class PrefetchFn>
RTP_KERNEL_INLINE Walk walk(const fmt::WideNode<W>* nodes, uint32_t root, const detail::BoxRay& ray, const float& tfar,
                            LeafFn&& leaf, PrefetchFn&& prefetch_leaf) {
  if constexpr (O == TraversalOrder::kOctantStack)
    return walk_octant_stack<K, W, kFixedFar>(nodes, root, ray, tfar, leaf, prefetch_leaf);
  else
    return walk_active_list<K, W>(nodes, root, ray, tfar, leaf, prefetch_leaf);
}

// What a walk does with one leaf block's hits: keep the closest (ClosestSink), stop at any (AnySink), or
// keep the N closest (multi_hit.h). tfar() is the live far distance both levels cull with.
struct ClosestSink {
  static constexpr bool kFixedFar = false;  // each hit found shortens tfar
  Closest best;
  float& tfar() { return best.t; }
  template <class K, int B>
  RTP_KERNEL_INLINE Walk block(const fmt::LeafBlock<B>& blk, const detail::TriRay& tri, uint32_t id) {
    BlockHits<B> h;
    for (uint32_t m = K::template block<B>(blk, tri, best.t, &h); m; m &= m - 1) {
      const int i = lowest_bit(m);
      const uint32_t prim = blk.prim[i];
      offer(h.t[i], id, prim, h.u[i], h.v[i]);
    }
    return Walk::kDone;
  }
  // The closest hit by (t, instance, prim), whatever the order hits are offered in.
  RTP_KERNEL_INLINE void offer(float t, uint32_t id, uint32_t prim, float u, float v) {
    if (t < best.t || (t == best.t && (id < best.instance || (id == best.instance && prim < best.prim))))
      best = {t, id, prim, u, v};
  }
};

struct AnySink {
  static constexpr bool kFixedFar = true;  // t never changes: the first hit ends the walk
  float t;
  float& tfar() { return t; }
  template <class K, int B>
  RTP_KERNEL_INLINE Walk block(const fmt::LeafBlock<B>& blk, const detail::TriRay& tri, uint32_t) {
    return K::template block_any<B>(blk, tri, t) ? Walk::kStop : Walk::kDone;
  }
};

// One ray through one instance's mesh BVH from node `root` (the mesh's root, or a subtree a packet
// left the ray in, packet.h), with the ray in the mesh's local space: org/dir and their box form.
template <class K, TraversalOrder O, int W, int B, class Sink>
RTP_KERNEL_INLINE Walk walk_mesh_inline(const SceneView<W, B>& s, uint32_t id, uint32_t root, const float org[3],
                                        const float dir[3], float tnear, const detail::BoxRay& box, Sink& sink) {
  const MeshBvhView<W, B>& mesh = s.meshes[s.instances[id].mesh];
  detail::TriRay tri;
  bool tri_ready = false;  // set up at the first leaf: many instance boxes are entered but no leaf
  auto block_leaf = [&](uint32_t leaf_ref) __attribute__((always_inline))->Walk {
    if (!tri_ready) setup_tri_ray(org, dir, tnear, &tri), tri_ready = true;
    const uint32_t b0 = fmt::ChildRef::first_block(leaf_ref), nb = fmt::ChildRef::block_count(leaf_ref);
    for (uint32_t b = b0; b < b0 + nb; ++b) {
      const Walk w = sink.template block<K, B>(mesh.blocks[b], tri, id);
      if (w != Walk::kDone) return w;
    }
    return Walk::kDone;
  };
  auto prefetch_block = [&](uint32_t leaf_ref) __attribute__((always_inline)) {
    const char* p = reinterpret_cast<const char*>(mesh.blocks + fmt::ChildRef::first_block(leaf_ref));
    for (size_t off = 0; off < sizeof(fmt::LeafBlock<B>); off += 64) __builtin_prefetch(p + off);
  };
  return walk<O, K, W, Sink::kFixedFar>(mesh.nodes, root, box, sink.tfar(), block_leaf, prefetch_block);
}

// The same, out of line: one copy per (ISA, order, W, B, sink) that every instance visit calls (issue 11:
// two inlined copies in the instance leaf cost more than the call). The one-instance path inlines it.
template <class K, TraversalOrder O, int W, int B, class Sink>
__attribute__((noinline)) Walk walk_mesh_one(const SceneView<W, B>& s, uint32_t id, uint32_t root, const float org[3],
                                             const float dir[3], float tnear, const detail::BoxRay& box, Sink& sink) {
  return walk_mesh_inline<K, O>(s, id, root, org, dir, tnear, box, sink);
}

// One instance-level leaf for one world ray: each instance's record moves the ray into its local space
// (transform_ray, direction not renormalized, so t is shared by both levels) and its mesh is walked.
// `world` is the world ray's box form: an instance that moves no ray (AxisMove::kNone) is walked with
// it, one whose L^-1 is a signed permutation gets its local ray from it (move_ray_by_axes).
template <class K, TraversalOrder O, int W, int B, class Sink>
inline Walk instance_leaf_one(const SceneView<W, B>& s, uint32_t ref, const fmt::Ray& ray, const detail::BoxRay& world,
                              Sink& sink) {
  const uint32_t first = fmt::ChildRef::first_block(ref), count = fmt::ChildRef::block_count(ref);
  for (uint32_t k = first; k < first + count; ++k) {
    const uint32_t id = s.top_instances[k];
    if (k + 1 < first + count) {  // the next instance's record, while this one is walked
      const char* next = reinterpret_cast<const char*>(s.instances + s.top_instances[k + 1]);
      __builtin_prefetch(next), __builtin_prefetch(next + 64);
    }
    const uint32_t mesh_root = s.meshes[s.instances[id].mesh].root;
    // One call site for both cases (the walk is one out-of-line function per sink, not two inlined copies).
    const float* o = ray.org;
    const float* d = ray.dir;
    const detail::BoxRay* b = &world;
    alignas(16) float org[4], dir[4];
    detail::BoxRay box;
    const fmt::InstanceRecord& inst = s.instances[id];
    const uint8_t kind = s.moves ? s.moves[id].kind : uint8_t(moves_no_ray(inst) ? AxisMove::kNone : AxisMove::kGeneral);
    if (kind != AxisMove::kNone) {
      AxisMoveResult r = AxisMoveResult::kGeneral;
      if (kind == AxisMove::kAxes) r = move_ray_by_axes(inst, s.moves[id], ray, world, org, dir, &box);
      if (r == AxisMoveResult::kSkip) continue;
      if (r == AxisMoveResult::kGeneral) {
        if (!transform_ray(inst, ray.org, ray.dir, org, dir)) continue;
        setup_box_ray(org, dir, ray.tnear, &box);
      }
      o = org, d = dir, b = &box;
    }
    const Walk w = walk_mesh_one<K, O>(s, id, mesh_root, o, d, ray.tnear, *b, sink);
    if (w != Walk::kDone) return w;
  }
  return Walk::kDone;
}

// Molenaar 2019 §4.1 two-level BVH: walk the instance BVH with the world ray; at an instance leaf,
// move the ray into the instance's local space and walk that mesh's BVH with the same tfar. A view
// whose instance level is one leaf of one instance (the identity, SceneView::direct, or a moved one:
// DamagedHelmet's and BoomBox's root nodes, a merged mesh under a shared transform) moves the ray
// and walks that mesh inline: the walk of a leaf root tests no box, so the answers are the two-level
// walk's bit for bit (issue 11: the world box form set up for nothing, the out-of-line call and the
// instance loop cost DamagedHelmet's random rays 1507 → 1380 instructions per ray, callgrind).
template <class K, TraversalOrder O, int W, int B, class Sink>
inline Walk trace_one(const SceneView<W, B>& s, const fmt::Ray& ray, Sink& sink) {
  detail::BoxRay world;
  uint32_t only = s.direct;
  if (only == kNoDirectInstance && fmt::ChildRef::is_leaf(s.top_root) && fmt::ChildRef::block_count(s.top_root) == 1)
    only = s.top_instances[fmt::ChildRef::first_block(s.top_root)];
  if (only != kNoDirectInstance) {
    const fmt::InstanceRecord& inst = s.instances[only];
    const float* o = ray.org;
    const float* d = ray.dir;
    const detail::BoxRay* b = &world;
    alignas(16) float org[4], dir[4];
    detail::BoxRay box;
    const uint8_t kind = only == s.direct ? uint8_t(AxisMove::kNone)
                         : s.moves        ? s.moves[only].kind
                                          : uint8_t(moves_no_ray(inst) ? AxisMove::kNone : AxisMove::kGeneral);
    if (kind != AxisMove::kGeneral) setup_box_ray(ray.org, ray.dir, ray.tnear, &world);
    if (kind != AxisMove::kNone) {
      AxisMoveResult r = AxisMoveResult::kGeneral;
      if (kind == AxisMove::kAxes) r = move_ray_by_axes(inst, s.moves[only], ray, world, org, dir, &box);
      if (r == AxisMoveResult::kSkip) return Walk::kDone;
      if (r == AxisMoveResult::kGeneral) {
        if (!transform_ray(inst, ray.org, ray.dir, org, dir)) return Walk::kDone;
        setup_box_ray(org, dir, ray.tnear, &box);
      }
      o = org, d = dir, b = &box;
    }
    return walk_mesh_inline<K, O>(s, only, s.meshes[inst.mesh].root, o, d, ray.tnear, *b, sink);
  }
  setup_box_ray(ray.org, ray.dir, ray.tnear, &world);
  auto instance_leaf = [&](uint32_t ref) -> Walk { return instance_leaf_one<K, O>(s, ref, ray, world, sink); };
  // A hit instance leaf's first record (its transform and mesh, the first loads of its visit), fetched
  // while the walk goes on (issue 11: forest-2k's shadow rays stalled on that load).
  auto prefetch_record = [&](uint32_t ref) __attribute__((always_inline)) {
    const char* rec = reinterpret_cast<const char*>(s.instances + s.top_instances[fmt::ChildRef::first_block(ref)]);
    __builtin_prefetch(rec), __builtin_prefetch(rec + 64);
  };
  return walk<O, K, W, Sink::kFixedFar>(s.top_nodes, s.top_root, world, sink.tfar(), instance_leaf, prefetch_record);
}

template <class K, TraversalOrder O, bool kAny, int W, int B>
inline TraceStats trace_batch(const SceneView<W, B>& s, const fmt::Ray* rays, fmt::Hit* hits, uint8_t* occluded, size_t n) {
  TraceStats stats;
  stats.rays = n;
  for (size_t i = 0; i < n; ++i) {
    // Read in place: a copy was stored as two 16-byte halves that ray_is_valid's one 32-byte load then
    // waited for (a failed store-to-load forward, a third of far.glb's shadow-ray time).
    const fmt::Ray& ray = rays[i];
    std::conditional_t<kAny, AnySink, ClosestSink> sink;
    if constexpr (kAny)
      sink.t = ray.tfar;
    else
      sink.best = {ray.tfar, fmt::Hit::kNone, fmt::Hit::kNone, 0.0f, 0.0f};
    Walk w = Walk::kDone;
    if (!ray_is_valid(ray))
      ++stats.invalid_rays;
    else if (direction_usable(ray.dir))
      w = trace_one<K, O>(s, ray, sink);
    if (w == Walk::kOverflow) ++stats.overflow_rays;
    if constexpr (kAny) {
      occluded[i] = w == Walk::kStop ? 1 : 0;
    } else if (w == Walk::kOverflow || sink.best.instance == fmt::Hit::kNone) {
      hits[i] = {INFINITY, fmt::Hit::kNone, fmt::Hit::kNone, 0.0f, 0.0f};
    } else {
      const Closest& b = sink.best;
      hits[i] = {b.t, b.instance, b.prim, b.u, b.v};
    }
  }
  return stats;
}

template <class K, int B>
inline void block_test_impl(const fmt::LeafBlock<B>& block, const fmt::Ray& ray, BlockHits<B>* out) {
  out->mask = 0;
  if (!ray_is_valid(ray) || !direction_usable(ray.dir)) return;
  detail::TriRay r;
  setup_tri_ray(ray.org, ray.dir, ray.tnear, &r);
  out->mask = K::template block<B>(block, r, ray.tfar, out);
}

template <class K, int W>
inline void node_test_impl(const fmt::WideNode<W>& node, const fmt::Ray& ray, NodeHits<W>* out) {
  out->mask = 0;
  if (!ray_is_valid(ray)) return;
  detail::BoxRay r;
  setup_box_ray(ray.org, ray.dir, ray.tnear, &r);
  out->mask = K::template node<W>(node, K::template node_ray<W>(r), ray.tfar, out->dist);
}

}  // namespace rtp::RTP_ISA_NS

// Defines this ISA's entry points (isa_entry.h) with kernel set K and instantiates them for
// (W, B) in {(4,4), (8,8), (16,16), (8,4), (16,8)}, blocks B in {4, 8, 16}, nodes W in {4, 8, 16}.
#define RTP_DEFINE_ISA_ENTRY_POINTS(K)                                                                                     \
  namespace rtp::RTP_ISA_NS {                                                                                              \
  template <int W, int B>                                                                                                  \
  TraceStats closest(const SceneView<W, B>& s, const fmt::Ray* rays, fmt::Hit* hits, size_t n, TraversalOrder order) {     \
    return order == TraversalOrder::kOctantStack                                                                           \
               ? trace_batch<K, TraversalOrder::kOctantStack, false>(s, rays, hits, nullptr, n)                            \
               : trace_batch<K, TraversalOrder::kActiveList, false>(s, rays, hits, nullptr, n);                            \
  }                                                                                                                        \
  template <int W, int B>                                                                                                  \
  TraceStats any(const SceneView<W, B>& s, const fmt::Ray* rays, uint8_t* occluded, size_t n, TraversalOrder order) {      \
    return order == TraversalOrder::kOctantStack                                                                           \
               ? trace_batch<K, TraversalOrder::kOctantStack, true>(s, rays, nullptr, occluded, n)                         \
               : trace_batch<K, TraversalOrder::kActiveList, true>(s, rays, nullptr, occluded, n);                         \
  }                                                                                                                        \
  template <int W, int B>                                                                                                  \
  TraceStats multi(const SceneView<W, B>& s, const fmt::Ray* rays, size_t n, uint32_t max_hits, bool cull, fmt::Hit* hits, \
                   uint32_t* counts, TraversalOrder order) {                                                               \
    constexpr TraversalOrder kOct = TraversalOrder::kOctantStack, kAct = TraversalOrder::kActiveList;                      \
    if (order == kOct)                                                                                                     \
      return cull ? multi_batch<K, kOct, true>(s, rays, n, max_hits, hits, counts)                                         \
                  : multi_batch<K, kOct, false>(s, rays, n, max_hits, hits, counts);                                       \
    return cull ? multi_batch<K, kAct, true>(s, rays, n, max_hits, hits, counts)                                           \
                : multi_batch<K, kAct, false>(s, rays, n, max_hits, hits, counts);                                         \
  }                                                                                                                        \
  template <int B>                                                                                                         \
  void block_test(const fmt::LeafBlock<B>& block, const fmt::Ray& ray, BlockHits<B>* out) {                                \
    block_test_impl<K, B>(block, ray, out);                                                                                \
  }                                                                                                                        \
  template <int W>                                                                                                         \
  void node_test(const fmt::WideNode<W>& node, const fmt::Ray& ray, NodeHits<W>* out) {                                    \
    node_test_impl<K, W>(node, ray, out);                                                                                  \
  }                                                                                                                        \
  RTP_INSTANTIATE_WB(4, 4)                                                                                                 \
  RTP_INSTANTIATE_WB(8, 8)                                                                                                 \
  RTP_INSTANTIATE_WB(16, 16)                                                                                               \
  RTP_INSTANTIATE_WB(8, 4)                                                                                                 \
  RTP_INSTANTIATE_WB(16, 8)                                                                                                \
  RTP_INSTANTIATE_N(4)                                                                                                     \
  RTP_INSTANTIATE_N(8)                                                                                                     \
  RTP_INSTANTIATE_N(16)                                                                                                    \
  }

#define RTP_INSTANTIATE_WB(W, B)                                                                                         \
  template TraceStats closest<W, B>(const SceneView<W, B>&, const fmt::Ray*, fmt::Hit*, size_t, TraversalOrder);         \
  template TraceStats any<W, B>(const SceneView<W, B>&, const fmt::Ray*, uint8_t*, size_t, TraversalOrder);              \
  template TraceStats multi<W, B>(const SceneView<W, B>&, const fmt::Ray*, size_t, uint32_t, bool, fmt::Hit*, uint32_t*, \
                                  TraversalOrder);
#define RTP_INSTANTIATE_N(N)                                                             \
  template void block_test<N>(const fmt::LeafBlock<N>&, const fmt::Ray&, BlockHits<N>*); \
  template void node_test<N>(const fmt::WideNode<N>&, const fmt::Ray&, NodeHits<N>*);
