#pragma once
// One triangle against the rays of a packet, one lane per ray (Wu 2016 §2.3: a leaf tested by the
// packet rather than ray by ray). The arithmetic is triangle_test_simd's, lane for lane in the same
// order (the per-triangle terms once, in scalar float, which are the same IEEE operations), so each
// lane's hit, t, u and v equal that ray's own test of that triangle bit for bit. SIMD only.
#include <cfloat>
#include <cmath>

#include "formats/bvh_layout.h"
#include "trace/kernels/kernel_common.h"
#include "trace/kernels/ray_setup.h"
#include "trace/kernels/triangle_simd.h"

namespace rtp::RTP_ISA_NS {

// The packet's rays in the watertight test's sheared frame (TriRay, SoA). Every ray of the packet
// shares (kx, ky, kz): the vertex components each lane reads are then the same scalars.
template <int P>
struct PacketTriRays {
  int kx = 0, ky = 1, kz = 2;
  alignas(64) float ox[P], oy[P], oz[P], dx[P], dy[P], dz[P], sx[P], sy[P], tnear[P];
};

// False when the rays of `lanes` do not share their shear axes (they then test leaves one by one).
// Lanes outside `lanes` copy the first ray.
template <int P>
inline bool make_packet_tri(const detail::TriRay* tri, uint32_t lanes, PacketTriRays<P>* out) {
  const detail::TriRay& f = tri[lowest_bit(lanes)];
  for (uint32_t m = lanes; m; m &= m - 1) {
    const detail::TriRay& t = tri[lowest_bit(m)];
    if (t.kx != f.kx || t.ky != f.ky || t.kz != f.kz) return false;
  }
  out->kx = f.kx, out->ky = f.ky, out->kz = f.kz;
  for (int i = 0; i < P; ++i) {
    const detail::TriRay& t = tri[(lanes >> i) & 1u ? i : lowest_bit(lanes)];
    out->ox[i] = t.org_k[0], out->oy[i] = t.org_k[1], out->oz[i] = t.org_k[2];
    out->dx[i] = t.dir_k[0], out->dy[i] = t.dir_k[1], out->dz[i] = t.dir_k[2];
    out->sx[i] = t.sx, out->sy[i] = t.sy, out->tnear[i] = t.tnear;
  }
  return true;
}

// Lane j of a block is lane j - 1 again (a short block is padded by repeating its last triangle,
// SPEC §2.3): testing it could only report the same hit.
template <int B>
inline bool repeats_previous(const fmt::LeafBlock<B>& blk, int j) {
  if (blk.prim[j] != blk.prim[j - 1]) return false;
  for (int a = 0; a < 3; ++a)
    if (blk.v0[a][j] != blk.v0[a][j - 1] || blk.v1[a][j] != blk.v1[a][j - 1] || blk.v2[a][j] != blk.v2[a][j - 1]) return false;
  return true;
}

// Woop, Benthin, Wald 2013 §3 for triangle `j` of `blk` and the rays of `lanes` (live tfar per lane in
// `tfar`): the mask of rays that hit it, with their t, u, v in t_out/u_out/v_out.
template <class VP, int P, int B>
RTP_KERNEL_INLINE uint32_t packet_triangle_test(const fmt::LeafBlock<B>& blk, int j, const PacketTriRays<P>& r, const float* tfar,
                                                uint32_t lanes, float* t_out, float* u_out, float* v_out) {
  const int kx = r.kx, ky = r.ky, kz = r.kz;
  const float q0[3] = {blk.v0[kx][j], blk.v0[ky][j], blk.v0[kz][j]};
  const float q1[3] = {blk.v1[kx][j], blk.v1[ky][j], blk.v1[kz][j]};
  const float q2[3] = {blk.v2[kx][j], blk.v2[ky][j], blk.v2[kz][j]};
  // The per-triangle terms of triangle_test_simd (edges, the two shorter ones, the plane normal).
  const float d01x = q1[0] - q0[0], d01y = q1[1] - q0[1], d01z = q1[2] - q0[2];
  const float d12x = q2[0] - q1[0], d12y = q2[1] - q1[1], d12z = q2[2] - q1[2];
  const float d20x = q0[0] - q2[0], d20y = q0[1] - q2[1], d20z = q0[2] - q2[2];
  const float l01 = (d01x * d01x + d01y * d01y) + d01z * d01z;
  const float l12 = (d12x * d12x + d12y * d12y) + d12z * d12z;
  const float l20 = (d20x * d20x + d20y * d20y) + d20z * d20z;
  const bool skip12 = l12 >= l01 && l12 >= l20, skip20 = l20 >= l01;
  const float eax = skip12 ? d01x : skip20 ? d12x : d20x, eay = skip12 ? d01y : skip20 ? d12y : d20y;
  const float eaz = skip12 ? d01z : skip20 ? d12z : d20z, ebx = skip12 ? d20x : skip20 ? d01x : d12x;
  const float eby = skip12 ? d20y : skip20 ? d01y : d12y, ebz = skip12 ? d20z : skip20 ? d01z : d12z;
  const int base = skip12 ? 0 : skip20 ? 1 : 2;  // the vertex the plane equation starts from
  const float nx = eay * ebz - eaz * eby, ny = eaz * ebx - eax * ebz, nz = eax * eby - eay * ebx;
  const float gx = std::fabs(eay * ebz) + std::fabs(eaz * eby), gy = std::fabs(eaz * ebx) + std::fabs(eax * ebz),
              gz = std::fabs(eax * eby) + std::fabs(eay * ebx);
  const VP p0x = VP::splat(q0[0]), p0y = VP::splat(q0[1]), p0z = VP::splat(q0[2]);
  const VP p1x = VP::splat(q1[0]), p1y = VP::splat(q1[1]), p1z = VP::splat(q1[2]);
  const VP p2x = VP::splat(q2[0]), p2y = VP::splat(q2[1]), p2z = VP::splat(q2[2]);
  const VP zero = VP::splat(0.0f);
  uint32_t mask = 0;
  for (int off = 0; off < P; off += VP::kLanes) {
    const uint32_t here = (lanes >> off) & ((1u << VP::kLanes) - 1u);  // kLanes <= 16
    if (!here) continue;
    const VP ox = VP::load(r.ox + off), oy = VP::load(r.oy + off), oz = VP::load(r.oz + off);
    const VP sx = VP::load(r.sx + off), sy = VP::load(r.sy + off);
    const Sheared<VP> e = shear(p0x, p0y, p0z, p1x, p1y, p1z, p2x, p2y, p2z, ox, oy, oz, sx, sy);
    const VP &ax0 = e.ax0, &ay0 = e.ay0, &az = e.az, &bz = e.bz, &cz = e.cz;
    const VP &ax = e.ax, &ay = e.ay, &bx = e.bx, &by = e.by, &cx = e.cx, &cy = e.cy, &u = e.u, &v = e.v, &w = e.w;
    const uint32_t slow = e.slow & here;
    const auto inside = ((u >= zero) & (v >= zero) & (w >= zero)) | ((u <= zero) & (v <= zero) & (w <= zero));
    if (!(inside.bits() & here) && !slow) continue;
    const VP det = (u + v) + w;
    const VP rx = base == 0 ? ax0 : base == 1 ? p1x - ox : p2x - ox;
    const VP ry = base == 0 ? ay0 : base == 1 ? p1y - oy : p2y - oy;
    const VP rz = base == 0 ? az : base == 1 ? bz : cz;
    const VP ddx = VP::load(r.dx + off), ddy = VP::load(r.dy + off), ddz = VP::load(r.dz + off);
    const VP den = (VP::splat(nx) * ddx + VP::splat(ny) * ddy) + VP::splat(nz) * ddz;
    const VP num = (VP::splat(nx) * rx + VP::splat(ny) * ry) + VP::splat(nz) * rz;
    const VP dsum = VP::splat(gx) * vabs(ddx) + VP::splat(gy) * vabs(ddy) + VP::splat(gz) * vabs(ddz);
    const uint32_t grazing = (vabs(den) <= VP::splat(kDenBound) * dsum).bits() & (inside & (det != zero)).bits();
    const uint32_t slow_all = slow | (grazing & here);
    uint32_t slow_hit = 0;
    alignas(64) float st[VP::kLanes], su[VP::kLanes], sv[VP::kLanes];
    if (slow_all) [[unlikely]] {
      alignas(64) float s6[6][VP::kLanes];
      ax.store(s6[0]), ay.store(s6[1]), bx.store(s6[2]), by.store(s6[3]), cx.store(s6[4]), cy.store(s6[5]);
      for (uint32_t m = slow_all; m; m &= m - 1) {
        const int i = lowest_bit(m), k = off + i;
        const float org_k[3] = {r.ox[k], r.oy[k], r.oz[k]}, dir_k[3] = {r.dx[k], r.dy[k], r.dz[k]};
        if (triangle_double(s6[0][i], s6[1][i], s6[2][i], s6[3][i], s6[4][i], s6[5][i], q0, q1, q2, org_k, dir_k, r.tnear[k],
                            tfar[k], &st[i], &su[i], &sv[i]))
          slow_hit |= 1u << i;
      }
    }
    const VP t = num / den;
    const uint32_t hit =
        (inside & (det != zero) & (t >= VP::load(r.tnear + off)) & (t <= VP::load(tfar + off)) & (vabs(t) <= VP::splat(FLT_MAX)))
            .bits();
    const uint32_t fast_hit = hit & here & ~slow_all;
    if (!fast_hit && !slow_hit) continue;
    mask |= (fast_hit | slow_hit) << off;
    t.store(t_out + off);
    (v / det).store(u_out + off);
    (w / det).store(v_out + off);
    for (uint32_t m = slow_hit; m; m &= m - 1) {
      const int i = lowest_bit(m);
      t_out[off + i] = st[i], u_out[off + i] = su[i], v_out[off + i] = sv[i];
    }
  }
  return mask;
}

}  // namespace rtp::RTP_ISA_NS
