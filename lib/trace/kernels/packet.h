#pragma once
// Coherent ray packets over one W-wide BVH level (Wu 2016 "Ray Packet Tracing with Acceleration using
// AVX"): P rays of one octant test a node together, first as one interval frustum against the node's W
// children, then child by child with one lane per ray; a packet thinned to a few rays finishes the
// subtree ray by ray with the single-ray walk. SIMD only (kernels_simd.h): P rays in K::Vec<P>.
#include <immintrin.h>

#include <cfloat>
#include <cmath>
#include <cstddef>

#include "formats/bvh_layout.h"
#include "trace/kernels/kernel_common.h"

namespace rtp::RTP_ISA_NS {

// Wu 2016 §2.1.3 (after Boulos 2007's adaptive packets): a packet with fewer active rays than this
// leaves them to finish the current subtree alone, where the single-ray walk's W-wide node test keeps
// its SIMD lanes busy. Measured with rtpack-bench --packets on the samples (design.md).
inline constexpr int kPacketMinActive = 3;

// What packets did, for TraceStats: SIMD utilization = active_lanes / (node_tests · P) (Wu 2016 §4.2.1).
struct PacketCounters {
  uint64_t node_tests = 0, active_lanes = 0, single_walks = 0, triangle_tests = 0;
};

// The packet's rays in one level's space as the per-child lane test reads them (SoA, one lane per
// ray), and the interval bounds of the whole packet that the frustum test reads.
template <int P>
struct PacketRays {
  alignas(64) float ox[P], oy[P], oz[P], rx[P], ry[P], rz[P], tnear[P];
  float o_near[3], o_far[3];  // per axis: the origin bound giving the lowest near / highest far distance
  float rmin[3], rmax[3];     // per axis: reciprocal direction bounds (one sign: one octant)
  float tnear_min;
  uint8_t octant;
};

// The BoxRay layout transpose8x8 reads: one ray per 8 floats, its fields at these float positions.
static_assert(sizeof(detail::BoxRay) == 32 && offsetof(detail::BoxRay, org) == 0 && offsetof(detail::BoxRay, rcp) == 12 &&
              offsetof(detail::BoxRay, tnear) == 24 && offsetof(detail::BoxRay, octant) == 28);

// r[k] = row k of an 8x8 float matrix on entry, column k on return (unpack, shuffle, lane permute).
inline void transpose8x8(__m256 r[8]) {
  const __m256 t0 = _mm256_unpacklo_ps(r[0], r[1]), t1 = _mm256_unpackhi_ps(r[0], r[1]);
  const __m256 t2 = _mm256_unpacklo_ps(r[2], r[3]), t3 = _mm256_unpackhi_ps(r[2], r[3]);
  const __m256 t4 = _mm256_unpacklo_ps(r[4], r[5]), t5 = _mm256_unpackhi_ps(r[4], r[5]);
  const __m256 t6 = _mm256_unpacklo_ps(r[6], r[7]), t7 = _mm256_unpackhi_ps(r[6], r[7]);
  const __m256 s0 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(1, 0, 1, 0)), s1 = _mm256_shuffle_ps(t0, t2, _MM_SHUFFLE(3, 2, 3, 2));
  const __m256 s2 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(1, 0, 1, 0)), s3 = _mm256_shuffle_ps(t1, t3, _MM_SHUFFLE(3, 2, 3, 2));
  const __m256 s4 = _mm256_shuffle_ps(t4, t6, _MM_SHUFFLE(1, 0, 1, 0)), s5 = _mm256_shuffle_ps(t4, t6, _MM_SHUFFLE(3, 2, 3, 2));
  const __m256 s6 = _mm256_shuffle_ps(t5, t7, _MM_SHUFFLE(1, 0, 1, 0)), s7 = _mm256_shuffle_ps(t5, t7, _MM_SHUFFLE(3, 2, 3, 2));
  r[0] = _mm256_permute2f128_ps(s0, s4, 0x20), r[1] = _mm256_permute2f128_ps(s1, s5, 0x20);
  r[2] = _mm256_permute2f128_ps(s2, s6, 0x20), r[3] = _mm256_permute2f128_ps(s3, s7, 0x20);
  r[4] = _mm256_permute2f128_ps(s0, s4, 0x31), r[5] = _mm256_permute2f128_ps(s1, s5, 0x31);
  r[6] = _mm256_permute2f128_ps(s2, s6, 0x31), r[7] = _mm256_permute2f128_ps(s3, s7, 0x31);
}

// Fills `out` from the rays of `lanes` (box forms already set up). False when they do not share an
// octant, or when on one axis some reciprocal directions are infinite (a zero or denormal component)
// and the others are not the same infinity: such rays go alone. Lanes outside `lanes` copy the first
// ray. An axis on which every ray has the same ±inf (an axis-aligned orthographic camera; issue 11:
// half of gallery's primary rays went alone) keeps the frustum conservative: (plane − o)·inf has the
// sign of the exact difference, which the interval end o_near / o_far bounds for every ray, and 0·inf
// = NaN is dropped by vmax/vmin there as in each ray's own test, so that axis then bounds nothing.
// The bounds are reduced over the SoA lanes with VP vectors (issue 11: lane by lane, compare and branch
// per value, this was a third of the per-packet set-up on BoomBox); every lane is one of `lanes`' rays,
// so they are the same bounds (valid rays carry no NaN; a zero's sign cannot change a product's test).
template <class VP, int P>
inline bool make_packet(const detail::BoxRay* box, uint32_t lanes, PacketRays<P>* out) {
  const int first = lowest_bit(lanes);
  const uint8_t octant = box[first].octant;
  uint32_t other_octant = 0;
  if constexpr (P % 8 == 0) {
    // Eight BoxRays (32 bytes each: org, rcp, tnear, octant) transposed into the SoA columns at once
    // (issue 11: field by field this loop was a fifth of a packet's instance-level set-up).
    float* column[7] = {out->ox, out->oy, out->oz, out->rx, out->ry, out->rz, out->tnear};
    const __m256i octant_v = _mm256_set1_epi32(octant), low_byte = _mm256_set1_epi32(0xFF);
    for (int off = 0; off < P; off += 8) {
      __m256 r[8];
      for (int k = 0; k < 8; ++k)
        r[k] = _mm256_loadu_ps(reinterpret_cast<const float*>(&box[(lanes >> (off + k)) & 1u ? off + k : first]));
      transpose8x8(r);
      for (int c = 0; c < 7; ++c) _mm256_storeu_ps(column[c] + off, r[c]);
      // Lane 7 is the octant byte and three padding bytes: only the byte is compared.
      const __m256i oct = _mm256_and_si256(_mm256_castps_si256(r[7]), low_byte);
      other_octant |= ~uint32_t(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(oct, octant_v)))) & 0xFFu;
    }
  } else {
    for (int i = 0; i < P; ++i) {
      const detail::BoxRay& b = box[(lanes >> i) & 1u ? i : first];
      out->ox[i] = b.org[0], out->oy[i] = b.org[1], out->oz[i] = b.org[2];
      out->rx[i] = b.rcp[0], out->ry[i] = b.rcp[1], out->rz[i] = b.rcp[2];
      out->tnear[i] = b.tnear;
      other_octant |= uint32_t(b.octant ^ octant);
    }
  }
  if (other_octant) return false;
  const float* org[3] = {out->ox, out->oy, out->oz};
  const float* rcp[3] = {out->rx, out->ry, out->rz};
  const VP big = VP::splat(FLT_MAX);
  for (int a = 0; a < 3; ++a) {
    VP omin = VP::load(org[a]), omax = omin, rmin = VP::load(rcp[a]), rmax = rmin;
    uint32_t finite = (vabs(rmin) <= big).bits();
    for (int off = VP::kLanes; off < P; off += VP::kLanes) {
      const VP o = VP::load(org[a] + off), r = VP::load(rcp[a] + off);
      omin = vmin(o, omin), omax = vmax(o, omax), rmin = vmin(r, rmin), rmax = vmax(r, rmax);
      finite |= (vabs(r) <= big).bits() << off;
    }
    const float lo = hmin(rmin), hi = hmax(rmax);
    const uint32_t all = P == 32 ? ~0u : (1u << P) - 1;
    // All finite, or all the same infinity (then rmin == rmax == it).
    if (finite != all && (finite != 0 || lo != hi)) return false;
    const bool neg = (octant >> a) & 1u;
    const float o_lo = hmin(omin), o_hi = hmax(omax);
    out->o_near[a] = neg ? o_lo : o_hi;
    out->o_far[a] = neg ? o_hi : o_lo;
    out->rmin[a] = lo, out->rmax[a] = hi;
  }
  out->tnear_min = hmin([&] {
    VP t = VP::load(out->tnear);
    for (int off = VP::kLanes; off < P; off += VP::kLanes) t = vmin(VP::load(out->tnear + off), t);
    return t;
  }());
  out->octant = octant;
  return true;
}

// Wu 2016 §2.2 frustum culling, by interval arithmetic over the packet's origins and reciprocal
// directions: per child, a lower bound of every ray's entry and an upper bound of every ray's (padded)
// exit distance. Rounding is monotone, so each bound computed from the interval's ends in the same
// float operations as the ray's own test bounds that test's value: a child any ray of the packet
// enters (packet_child_test) is in the mask.
template <class VW, int W, int P>
inline uint32_t packet_frustum_test(const fmt::WideNode<W>& node, const PacketRays<P>& pr, float tfar_max) {
  const float* planes = &node.lo[0][0];
  const VW up = VW::splat(detail::kFarPadUp), down = VW::splat(detail::kFarPadDown);
  uint32_t mask = 0;
  for (int off = 0; off < W; off += VW::kLanes) {
    VW tn = VW::splat(pr.tnear_min), tf = VW::splat(tfar_max);
    for (int a = 0; a < 3; ++a) {
      const bool neg = (pr.octant >> a) & 1u;
      const VW dn = VW::load(planes + (neg ? 3 * W : 0) + a * W + off) - VW::splat(pr.o_near[a]);
      const VW df = VW::load(planes + (neg ? 0 : 3 * W) + a * W + off) - VW::splat(pr.o_far[a]);
      const VW r0 = VW::splat(pr.rmin[a]), r1 = VW::splat(pr.rmax[a]);
      tn = vmax(vmin(dn * r0, dn * r1), tn);
      tf = vmin(vmax(df * r0, df * r1), tf);
    }
    tf = vmax(tf * up, tf * down);
    mask |= (tn <= tf).bits() << off;
  }
  return mask;
}

// Ize 2013 §3 slab test of child `j` for every ray of the packet, one lane per ray: the same float
// operations in the same order as box_test_simd does for one ray and W children, so each lane's mask
// bit and entry distance equal that ray's own.
template <class VP, int W, int P>
inline uint32_t packet_child_test(const fmt::WideNode<W>& node, int j, const PacketRays<P>& pr, const float* tfar, float* dist) {
  const float* planes = &node.lo[0][0];
  float np[3], fp[3];
  for (int a = 0; a < 3; ++a) {
    const bool neg = (pr.octant >> a) & 1u;
    np[a] = planes[(neg ? 3 * W : 0) + a * W + j];
    fp[a] = planes[(neg ? 0 : 3 * W) + a * W + j];
  }
  const VP up = VP::splat(detail::kFarPadUp), down = VP::splat(detail::kFarPadDown);
  uint32_t mask = 0;
  for (int off = 0; off < P; off += VP::kLanes) {
    const VP ox = VP::load(pr.ox + off), oy = VP::load(pr.oy + off), oz = VP::load(pr.oz + off);
    const VP rx = VP::load(pr.rx + off), ry = VP::load(pr.ry + off), rz = VP::load(pr.rz + off);
    VP tn = vmax((VP::splat(np[0]) - ox) * rx, VP::load(pr.tnear + off));
    VP tf = vmin((VP::splat(fp[0]) - ox) * rx, VP::load(tfar + off));
    tn = vmax((VP::splat(np[1]) - oy) * ry, tn);
    tf = vmin((VP::splat(fp[1]) - oy) * ry, tf);
    tn = vmax((VP::splat(np[2]) - oz) * rz, tn);
    tf = vmin((VP::splat(fp[2]) - oz) * rz, tf);
    tf = vmax(tf * up, tf * down);
    tn.store(dist + off);
    mask |= (tn <= tf).bits() << off;
  }
  return mask;
}

// Depth-first packet walk of one level from `root` for the rays of `mask`: children in the node's
// octant order, nearest on top, each stack entry with its rays and their entry distances; a popped
// entry keeps only the rays whose distance is within their (padded) live tfar. `live` is shared with
// the callbacks: a ray they finish (any hit, overflow) leaves every walk of the packet.
// leaf(ref, rays) tests a leaf for those rays; single(ref, lane) walks subtree `ref` for one ray.
// Returns kOverflow when the stack would overflow (a tree deeper than kMaxDepth), else kDone.
template <class K, int W, int P, class LeafFn, class SingleFn>
inline Walk walk_packet(const fmt::WideNode<W>* nodes, uint32_t root, uint32_t mask, const PacketRays<P>& pr, const float* tfar,
                        const uint32_t& live, LeafFn&& leaf, SingleFn&& single, PacketCounters& pc) {
  using VW = typename K::template Vec<W>;
  using VP = typename K::template Vec<P>;
  struct Entry {
    uint32_t ref, rays;
    float dist[P];
  };
  constexpr int kCapacity = (W - 1) * detail::kMaxDepth + W + 1;
  Entry stack[kCapacity];
  int sp = 0;
  uint32_t cur = root;
  for (;;) {
    mask &= live;
    if (mask && fmt::ChildRef::is_leaf(cur)) {
      leaf(cur, mask);
    } else if (mask && !fmt::ChildRef::is_empty(cur)) {
      if (bit_count(mask) < kPacketMinActive) {
        for (uint32_t m = mask; m; m &= m - 1) single(cur, lowest_bit(m)), ++pc.single_walks;
      } else {
        const fmt::WideNode<W>& node = nodes[fmt::ChildRef::node_index(cur)];
        ++pc.node_tests;
        pc.active_lanes += uint64_t(bit_count(mask));
        float tfar_max = -INFINITY;
        for (uint32_t m = mask; m; m &= m - 1) tfar_max = max_keep(tfar[lowest_bit(m)], tfar_max);
        const uint32_t cand = packet_frustum_test<VW, W, P>(node, pr, tfar_max);
        const uint8_t* order = node.order[pr.octant];
        // Far to near, so the nearest child ends on top of the stack.
        for (uint32_t om = cand ? K::template ordered<W>(cand, order) : 0u; om;) {
          const int i = highest_bit(om);
          om &= ~(1u << i);
          const int j = order[i] & 15;
          if (sp == kCapacity) return Walk::kOverflow;
          Entry& e = stack[sp];
          e.rays = packet_child_test<VP, W, P>(node, j, pr, tfar, e.dist) & mask;
          if (e.rays) e.ref = node.child[j], ++sp;
        }
      }
    }
    for (;;) {
      if (sp == 0) return Walk::kDone;
      const Entry& e = stack[--sp];
      uint32_t rays = e.rays & live;
      if (!rays) continue;
      uint32_t within = 0;
      for (int off = 0; off < P; off += VP::kLanes) {
        const VP t = VP::load(tfar + off);
        within |= (VP::load(e.dist + off) <= vmax(t * VP::splat(detail::kFarPadUp), t * VP::splat(detail::kFarPadDown))).bits()
                  << off;
      }
      rays &= within;
      if (rays) {
        cur = e.ref;
        mask = rays;
        break;
      }
    }
  }
}

}  // namespace rtp::RTP_ISA_NS
