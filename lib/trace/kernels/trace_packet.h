#pragma once
// Packets of P consecutive rays through the two-level BVH (packet.h per level) and their batch entry
// points; included by the SIMD translation units after trace_ray.h (through multi_hit.h). The answers
// equal trace_batch's bit for bit: every lane runs the single-ray box and triangle tests' arithmetic,
// a closest hit wins by (t, instance, prim) whatever the visit order, and any ray the packet cannot
// take (invalid, another octant, an infinite reciprocal the packet's others lack, a stack overflow)
// is traced alone.
#include <algorithm>
#include <cstring>
#include <type_traits>

#include "trace/kernels/packet.h"
#include "trace/kernels/triangle_packet.h"
#include "trace/kernels/trace_ray.h"

namespace rtp::RTP_ISA_NS {

// The per-ray state of one packet: world rays, sinks, live tfar (the sinks' t, copied after each
// leaf for the lane tests), and which rays are still walking, stopped (any hit) or overflowed.
template <int P, class Sink>
struct PacketLanes {
  fmt::Ray ray[P];
  detail::BoxRay world[P];
  Sink sink[P];
  alignas(64) float tfar[P];
  uint32_t live = 0, stopped = 0, overflow = 0;
  void finish(int lane, Walk w) {
    if (w == Walk::kDone) return;
    live &= ~(1u << lane);
    (w == Walk::kStop ? stopped : overflow) |= 1u << lane;
  }
  void sync(int lane) { tfar[lane] = sink[lane].tfar(); }
};

// One instance's mesh for the rays of `mask`, given in its local space (org/dir/box per lane).
// org/dir: rows of N >= 3 floats per lane (x, y, z first).
template <class K, int P, int W, int B, class Sink, int N>
inline Walk packet_mesh(const SceneView<W, B>& s, uint32_t id, uint32_t mask, float (*org)[N], float (*dir)[N],
                        const detail::BoxRay* box, PacketLanes<P, Sink>& L, PacketCounters& pc,
                        const PacketRays<P>* ready = nullptr) {
  constexpr TraversalOrder kOct = TraversalOrder::kOctantStack;
  const MeshBvhView<W, B>& mesh = s.meshes[s.instances[id].mesh];
  auto single = [&](uint32_t ref, int lane) {
    L.finish(lane, walk_mesh_one<K, kOct>(s, id, ref, org[lane], dir[lane], L.ray[lane].tnear, box[lane], L.sink[lane]));
    L.sync(lane);
  };
  PacketRays<P> own;
  if (bit_count(mask) < kPacketMinActive || (!ready && !make_packet<typename K::template Vec<P>, P>(box, mask, &own))) {
    for (uint32_t m = mask; m; m &= m - 1) single(mesh.root, lowest_bit(m));
    return Walk::kDone;
  }
  const PacketRays<P>& pr = ready ? *ready : own;
  detail::TriRay tri[P];
  uint32_t tri_ready = 0;
  // Closest-hit leaves with most of the packet's rays: triangle by triangle for all of them (Wu 2016
  // §2.3), when the rays share their shear axes; set up once per mesh visit, at the first such leaf.
  PacketTriRays<P> ptri;
  int ptri_state = 0;  // 0: not set up, 1: usable, 2: the rays' axes differ
  auto leaf = [&](uint32_t ref, uint32_t rays) {
    const uint32_t b0 = fmt::ChildRef::first_block(ref), nb = fmt::ChildRef::block_count(ref);
    if constexpr (std::is_same_v<Sink, ClosestSink>) {
      if (2 * bit_count(rays) >= P && ptri_state != 2) {
        if (ptri_state == 0) {
          for (uint32_t m = mask & ~tri_ready; m; m &= m - 1) {
            const int lane = lowest_bit(m);
            setup_tri_ray(org[lane], dir[lane], L.ray[lane].tnear, &tri[lane]);
          }
          tri_ready |= mask;
          ptri_state = make_packet_tri<P>(tri, mask, &ptri) ? 1 : 2;
        }
        if (ptri_state == 1) {
          alignas(64) float t[P], u[P], v[P];
          for (uint32_t b = b0; b < b0 + nb; ++b) {
            const fmt::LeafBlock<B>& blk = mesh.blocks[b];
            for (int j = 0; j < B; ++j) {
              if (j > 0 && repeats_previous(blk, j)) continue;  // a short block's padding: the same hit again
              ++pc.triangle_tests;
              using VP = typename K::template Vec<P>;
              for (uint32_t m = packet_triangle_test<VP, P, B>(blk, j, ptri, L.tfar, rays, t, u, v); m; m &= m - 1) {
                const int lane = lowest_bit(m);
                L.sink[lane].offer(t[lane], id, blk.prim[j], u[lane], v[lane]);
                L.sync(lane);
              }
            }
          }
          return;
        }
      }
    }
    for (uint32_t m = rays; m; m &= m - 1) {
      const int lane = lowest_bit(m);
      if (!(tri_ready >> lane & 1u)) setup_tri_ray(org[lane], dir[lane], L.ray[lane].tnear, &tri[lane]), tri_ready |= 1u << lane;
      for (uint32_t b = b0; b < b0 + nb; ++b) {
        const Walk w = L.sink[lane].template block<K, B>(mesh.blocks[b], tri[lane], id);
        if (w != Walk::kDone) {
          L.finish(lane, w);
          break;
        }
      }
      L.sync(lane);
    }
  };
  return walk_packet<K, W, P>(mesh.nodes, mesh.root, mask, pr, L.tfar, L.live, leaf, single, pc);
}

// The rays of `mask` (one octant, valid) through the scene: the instance level as a packet, each
// instance's mesh as a packet of the rays that reach it.
template <class K, int P, int W, int B, class Sink>
inline Walk trace_packet(const SceneView<W, B>& s, uint32_t mask, PacketLanes<P, Sink>& L, PacketCounters& pc) {
  constexpr TraversalOrder kOct = TraversalOrder::kOctantStack;
  // The world rays' origins and directions as packet_mesh reads them, copied only for a mesh walked in
  // world space (the view's direct instance, or an instance that moves no ray).
  float world_org[P][3], world_dir[P][3];
  bool world_rows = false;
  auto copy_world_rows = [&] {
    if (world_rows) return;
    for (int i = 0; i < P; ++i)
      for (int a = 0; a < 3; ++a) world_org[i][a] = L.ray[i].org[a], world_dir[i][a] = L.ray[i].dir[a];
    world_rows = true;
  };
  if (s.direct != kNoDirectInstance) {
    copy_world_rows();
    return packet_mesh<K>(s, s.direct, mask, world_org, world_dir, L.world, L, pc);
  }
  // The world rays' packet, made when first needed: a top level that is one leaf (a scene of one moved
  // instance, e.g. a glTF root node with a transform) tests no node, and a moved instance makes its own.
  PacketRays<P> pr;
  int pr_state = 0;  // 0: not made, 1: made, 2: the rays cannot form one (they go alone)
  auto world_packet = [&]() -> const PacketRays<P>* {
    if (pr_state == 0) pr_state = make_packet<typename K::template Vec<P>, P>(L.world, mask, &pr) ? 1 : 2;
    return pr_state == 1 ? &pr : nullptr;
  };
  Walk status = Walk::kDone;
  auto single = [&](uint32_t ref, int lane) {
    auto leaf = [&](uint32_t r) { return instance_leaf_one<K, kOct>(s, r, L.ray[lane], L.world[lane], L.sink[lane]); };
    L.finish(lane, walk<kOct, K, W>(s.top_nodes, ref, L.world[lane], L.sink[lane].tfar(), leaf, [](uint32_t) {}));
    L.sync(lane);
  };
  auto leaf = [&](uint32_t ref, uint32_t rays) {
    const uint32_t first = fmt::ChildRef::first_block(ref), count = fmt::ChildRef::block_count(ref);
    for (uint32_t k = first; k < first + count && (rays & L.live); ++k) {
      const uint32_t id = s.top_instances[k];
      if (moves_no_ray(s.instances[id])) {  // the world rays and their packet as they are
        copy_world_rows();
        if (packet_mesh<K>(s, id, rays & L.live, world_org, world_dir, L.world, L, pc, world_packet()) == Walk::kOverflow)
          status = Walk::kOverflow;
        continue;
      }
      // One float more per lane: move_ray_by_axes stores four floats at a time.
      alignas(16) float org[P][4], dir[P][4];
      detail::BoxRay box[P];
      uint32_t in = 0;
      // An instance whose L^-1 is a signed permutation (BoomBox's and Lantern's nodes) moves each lane by
      // permuting its world ray, as instance_leaf_one does for single rays (issue 11: the packet path ran
      // the double transform and a division per lane). Same bits as the general transform (scene_view.h);
      // a lane with a zero component takes the general path.
      if (s.moves && s.moves[id].kind == AxisMove::kAxes) {
        const InstanceMove move(s.instances[id]);  // transform_ray's operands, once for the packet
        for (uint32_t m = rays & L.live; m; m &= m - 1) {
          const int lane = lowest_bit(m);
          const AxisMoveResult r =
              move_ray_by_axes(s.instances[id], s.moves[id], L.ray[lane], L.world[lane], org[lane], dir[lane], &box[lane]);
          if (r == AxisMoveResult::kSkip) continue;
          if (r == AxisMoveResult::kGeneral) {
            if (!move.apply(L.ray[lane].org, L.ray[lane].dir, org[lane], dir[lane])) continue;
            setup_box_ray(org[lane], dir[lane], L.ray[lane].tnear, &box[lane]);
          }
          in |= 1u << lane;
        }
      } else {
        // Four consecutive lanes at a time, the same bits as InstanceMove::apply and setup_box_ray lane by
        // lane; a lane outside `rays` is moved too (every lane holds a ray) and not taken.
        static_assert(P % 4 == 0);
        const InstanceMove4 move4(s.instances[id]);
        const uint32_t want = rays & L.live;
        for (int g = 0; g < P; g += 4) {
          const uint32_t sub = (want >> g) & 0xFu;
          if (sub) in |= (move4.apply(L.ray + g, org + g, dir + g, box + g) & sub) << g;
        }
      }
      if (in && packet_mesh<K>(s, id, in, org, dir, box, L, pc) == Walk::kOverflow) status = Walk::kOverflow;
    }
  };
  if (fmt::ChildRef::is_leaf(s.top_root)) {  // walk_packet would call the leaf and stop
    leaf(s.top_root, mask & L.live);
    return status;
  }
  if (!world_packet()) return Walk::kOverflow;  // the caller traces them alone
  const Walk w = walk_packet<K, W, P>(s.top_nodes, s.top_root, mask, pr, L.tfar, L.live, leaf, single, pc);
  return w == Walk::kOverflow ? w : status;
}

// trace_batch (trace_ray.h) with P consecutive rays at a time: the valid rays of the first valid ray's
// octant go as a packet when there are at least kPacketMinActive of them, the others alone.
template <class K, bool kAny, int P, int W, int B>
inline TraceStats trace_batch_packets(const SceneView<W, B>& s, const fmt::Ray* rays, fmt::Hit* hits, uint8_t* occluded,
                                      size_t n) {
  using Sink = std::conditional_t<kAny, AnySink, ClosestSink>;
  constexpr TraversalOrder kOct = TraversalOrder::kOctantStack;
  TraceStats stats;
  stats.rays = n;
  PacketCounters pc;
  PacketLanes<P, Sink> L;
  auto reset = [&](int i) {
    if constexpr (kAny)
      L.sink[i].t = L.ray[i].tfar;
    else
      L.sink[i].best = {L.ray[i].tfar, fmt::Hit::kNone, fmt::Hit::kNone, 0.0f, 0.0f};
    L.tfar[i] = L.ray[i].tfar;
  };
  for (size_t base = 0; base < n; base += P) {
    const int count = int(std::min<size_t>(P, n - base));
    if (count == P) {
      std::memcpy(L.ray, rays + base, sizeof L.ray);
    } else {
      for (int i = 0; i < P; ++i) L.ray[i] = rays[base + std::min(i, count - 1)];  // lanes past the end copy the last ray
    }
    for (int i = 0; i < P; ++i) reset(i);
    // ray_is_valid, direction_usable and setup_box_ray four lanes at a time (the same bits), and the
    // lanes of the first valid ray's octant by one byte compare.
    static_assert(P % 4 == 0 && P <= 16);
    const uint32_t present = (1u << count) - 1;
    uint32_t valid = 0, invalid = 0;
    alignas(16) uint8_t octants[16] = {};
    for (int g = 0; g < P; g += 4) {
      uint32_t bad = 0;
      valid |= setup_box_rays4(L.ray + g, L.world + g, &bad, octants + g) << g;
      invalid |= bad << g;
    }
    valid &= present;
    stats.invalid_rays += uint64_t(bit_count(invalid & present));
    uint32_t packet = 0;
    if (valid) {
      const __m128i all = _mm_load_si128(reinterpret_cast<const __m128i*>(octants));
      const __m128i first = _mm_set1_epi8(char(octants[lowest_bit(valid)]));
      packet = uint32_t(_mm_movemask_epi8(_mm_cmpeq_epi8(all, first))) & valid;
      if (bit_count(packet) < kPacketMinActive) packet = 0;
    }
    L.live = packet, L.stopped = 0, L.overflow = 0;
    if (packet) {
      if (trace_packet<K>(s, packet, L, pc) == Walk::kOverflow) {  // start these rays again, alone
        for (uint32_t m = packet; m; m &= m - 1) reset(lowest_bit(m));
        L.live = 0, L.stopped = 0, L.overflow = 0;
        packet = 0;
      } else {
        ++stats.packets;
        stats.packet_rays += uint64_t(bit_count(packet));
      }
    }
    for (uint32_t m = valid & ~packet; m; m &= m - 1) {
      const int i = lowest_bit(m);
      L.finish(i, trace_one<K, kOct>(s, L.ray[i], L.sink[i]));
    }
    stats.overflow_rays += uint64_t(bit_count(L.overflow & present));
    for (int i = 0; i < count; ++i) {
      if constexpr (kAny) {
        occluded[base + i] = ((L.stopped >> i) & 1u) ? 1 : 0;
      } else {
        const Closest& b = L.sink[i].best;
        const bool miss = ((L.overflow >> i) & 1u) || b.instance == fmt::Hit::kNone;
        hits[base + i] =
            miss ? fmt::Hit{INFINITY, fmt::Hit::kNone, fmt::Hit::kNone, 0.0f, 0.0f} : fmt::Hit{b.t, b.instance, b.prim, b.u, b.v};
      }
    }
  }
  stats.packet_node_tests = pc.node_tests;
  stats.packet_active_lanes = pc.active_lanes;
  stats.packet_single_walks = pc.single_walks;
  stats.packet_triangle_tests = pc.triangle_tests;
  return stats;
}

}  // namespace rtp::RTP_ISA_NS

// Defines this ISA's packet entry points (isa_entry.h) for P in {4, 8, 16} and the (W, B) pairs of
// RTP_DEFINE_ISA_ENTRY_POINTS.
#define RTP_DEFINE_PACKET_ENTRY_POINTS(K)                                                                                 \
  namespace rtp::RTP_ISA_NS {                                                                                             \
  template <int W, int B>                                                                                                 \
  TraceStats closest_packets(const SceneView<W, B>& s, const fmt::Ray* rays, fmt::Hit* hits, size_t n, uint32_t packet) { \
    if (packet == 4) return trace_batch_packets<K, false, 4>(s, rays, hits, nullptr, n);                                  \
    if (packet == 8) return trace_batch_packets<K, false, 8>(s, rays, hits, nullptr, n);                                  \
    return trace_batch_packets<K, false, 16>(s, rays, hits, nullptr, n);                                                  \
  }                                                                                                                       \
  template <int W, int B>                                                                                                 \
  TraceStats any_packets(const SceneView<W, B>& s, const fmt::Ray* rays, uint8_t* occluded, size_t n, uint32_t packet) {  \
    if (packet == 4) return trace_batch_packets<K, true, 4>(s, rays, nullptr, occluded, n);                               \
    if (packet == 8) return trace_batch_packets<K, true, 8>(s, rays, nullptr, occluded, n);                               \
    return trace_batch_packets<K, true, 16>(s, rays, nullptr, occluded, n);                                               \
  }                                                                                                                       \
  RTP_INSTANTIATE_PACKETS(4, 4)                                                                                           \
  RTP_INSTANTIATE_PACKETS(8, 8)                                                                                           \
  RTP_INSTANTIATE_PACKETS(16, 16)                                                                                         \
  RTP_INSTANTIATE_PACKETS(8, 4)                                                                                           \
  RTP_INSTANTIATE_PACKETS(16, 8)                                                                                          \
  }

#define RTP_INSTANTIATE_PACKETS(W, B)                                                                              \
  template TraceStats closest_packets<W, B>(const SceneView<W, B>&, const fmt::Ray*, fmt::Hit*, size_t, uint32_t); \
  template TraceStats any_packets<W, B>(const SceneView<W, B>&, const fmt::Ray*, uint8_t*, size_t, uint32_t);
