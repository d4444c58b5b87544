#pragma once
// In-core tracing kernels over the two-level wide BVH: closest hit, any hit and the N closest, scalar reference,
// AVX2 and AVX-512 paths chosen at run time, two traversal orders.
#include <cstddef>
#include <cstdint>

#include "core/isa.h"
#include "formats/ray_file.h"
#include "layout/hit_order.h"
#include "layout/scene_view.h"

namespace rtp {

// Benthin 2008 §5.3–5.4 unsorted active list with pruning, or Molenaar 2019 §4.1 octant order + stack.
enum class TraversalOrder { kOctantStack, kActiveList };
const char* order_name(TraversalOrder order);

struct TraceOptions {
  Isa isa = Isa::kScalar;
  TraversalOrder order = TraversalOrder::kOctantStack;
  // Wu 2016 coherent packets for closest and any hit: 0 traces single rays; 4, 8 or 16 traces each run
  // of that many consecutive rays (e.g. a 2x2, 4x2 or 4x4 pixel tile) as a packet (packet.h), in octant
  // order whatever `order` says. Same answers bit for bit. The scalar ISA traces single rays.
  uint32_t packet = 0;
};
inline bool packet_size_ok(uint32_t p) { return p == 0 || p == 4 || p == 8 || p == 16; }

struct TraceStats {
  uint64_t rays = 0;
  uint64_t invalid_rays = 0;   // NaN/Inf, tnear > tfar, tnear = inf: returned as misses
  uint64_t overflow_rays = 0;  // tree deeper than the fixed traversal stacks allow (malformed BVH): misses
  // With TraceOptions::packet: packets traced and their rays (the others went alone: invalid, another
  // octant than the packet's first ray, too few), node tests by packets and the active rays summed over
  // them (SIMD utilization = packet_active_lanes / (packet_node_tests · packet size), Wu 2016 §4.2.1),
  // and subtrees rays finished alone after their packet thinned out; closest-hit leaf triangles tested
  // by a whole packet at once (Wu 2016 §2.3) rather than ray by ray.
  uint64_t packets = 0, packet_rays = 0, packet_node_tests = 0, packet_active_lanes = 0, packet_single_walks = 0;
  uint64_t packet_triangle_tests = 0;
  void add(const TraceStats& o) {
    rays += o.rays, invalid_rays += o.invalid_rays, overflow_rays += o.overflow_rays;
    packets += o.packets, packet_rays += o.packet_rays, packet_node_tests += o.packet_node_tests;
    packet_active_lanes += o.packet_active_lanes, packet_single_walks += o.packet_single_walks;
    packet_triangle_tests += o.packet_triangle_tests;
  }
};

// Closest hit for rays[0..n): hits[i].t = +inf on a miss. Thread-safe (no shared mutable state),
// no allocation. Callers parallelize over ray ranges.
template <int W, int B>
TraceStats trace_closest(const SceneView<W, B>& scene, const fmt::Ray* rays, fmt::Hit* hits, size_t n,
                         const TraceOptions& options);

// Any hit: occluded[i] = 1 if some triangle is hit with t in [tnear, tfar], else 0.
template <int W, int B>
TraceStats trace_any(const SceneView<W, B>& scene, const fmt::Ray* rays, uint8_t* occluded, size_t n,
                     const TraceOptions& options);

// The N closest hits of each ray, N = max_hits in [1, kMaxMultiHit]: hits[i·N, i·N + N) holds ray i's
// hits in (t, instance, prim) order, each triangle once, then misses (t = +inf); counts[i] = how many
// are hits. kNodeCulling (Gribble 2016 §2.1) culls nodes beyond the N-th hit found so far;
// kCollectAll is the naive baseline (every hit, sorted, cut to N; allocates), same answers.
// Throws rtp::Error(kUsage) for N outside [1, kMaxMultiHit].
inline constexpr uint32_t kMaxMultiHit = 64;
// The order of hits is hit_order_less (layout/hit_order.h).
enum class MultiHitMethod { kNodeCulling, kCollectAll };
template <int W, int B>
TraceStats trace_multi(const SceneView<W, B>& scene, const fmt::Ray* rays, size_t n, uint32_t max_hits, fmt::Hit* hits,
                       uint32_t* counts, const TraceOptions& options, MultiHitMethod method = MultiHitMethod::kNodeCulling);

}  // namespace rtp
