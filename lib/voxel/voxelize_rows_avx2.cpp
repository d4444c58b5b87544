// Schwarz & Seidel 2010 §3.1 cell tests of one triangle over a small box, four cells of a row along x
// per AVX2 register: the x-dependent products once per box, the y/z-only tests once per row (a row
// failing its yz edge or box test is skipped whole), the rest per lane. Every value is the product or
// sum voxelize_triangle's scalar loop forms, grouped the same way (no FMA: -ffp-contract=off), so the
// cells set are bit for bit the same. Intrinsics only: no inline function shared with baseline code.
#include <immintrin.h>

#include "voxel/voxelize_rows.h"

namespace rtp::voxel::detail {

void row_masks_avx2(const CellTests& t, uint8_t* masks) {
  const int nx = t.l[0] - t.f[0] + 1, ny = t.l[1] - t.f[1] + 1;
  const int chunks = nx > 4 ? 2 : 1;
  // Per chunk of four x lanes: the corner, its box test, and every product with p0.
  __m256d n0p0[2], e_xy[2][3], e_zx[2][3];
  int lane_ok[2];
  for (int c = 0; c < chunks; ++c) {
    const int x0 = t.f[0] + 4 * c;
    const __m256d xi = _mm256_set_pd(double(x0 + 3), double(x0 + 2), double(x0 + 1), double(x0));
    const __m256d p0 = _mm256_sub_pd(_mm256_add_pd(_mm256_set1_pd(t.org[0]), _mm256_mul_pd(xi, _mm256_set1_pd(t.cell))),
                                     _mm256_set1_pd(t.margin));
    const __m256d skip =
        _mm256_or_pd(_mm256_cmp_pd(p0, _mm256_set1_pd(t.box_hi[0]), _CMP_GT_OQ),
                     _mm256_cmp_pd(_mm256_add_pd(p0, _mm256_set1_pd(t.dp)), _mm256_set1_pd(t.box_lo[0]), _CMP_LT_OQ));
    const int lanes = nx - 4 * c >= 4 ? 4 : nx - 4 * c;
    lane_ok[c] = ~_mm256_movemask_pd(skip) & ((1 << lanes) - 1);
    n0p0[c] = _mm256_mul_pd(_mm256_set1_pd(t.n[0]), p0);
    for (int i = 0; i < 3; ++i) {
      e_xy[c][i] = _mm256_mul_pd(_mm256_set1_pd(t.ex[0][i]), p0);  // plane xy: p0 is its first coordinate
      e_zx[c][i] = _mm256_mul_pd(_mm256_set1_pd(t.ey[2][i]), p0);  // plane zx: p0 is its second
    }
  }
  const __m256d zero = _mm256_setzero_pd(), d1 = _mm256_set1_pd(t.d1), d2 = _mm256_set1_pd(t.d2);
  for (int z = t.f[2]; z <= t.l[2]; ++z) {
    const double p2 = t.org[2] + z * t.cell - t.margin;
    const bool z_ok = !(p2 > t.box_hi[2] || p2 + t.dp < t.box_lo[2]);
    for (int y = t.f[1]; y <= t.l[1]; ++y) {
      uint8_t& out = masks[(z - t.f[2]) * ny + (y - t.f[1])];
      out = 0;
      const double p1 = t.org[1] + y * t.cell - t.margin;
      bool row = z_ok && !(p1 > t.box_hi[1] || p1 + t.dp < t.box_lo[1]);
      for (int i = 0; i < 3; ++i) row = row && t.ex[1][i] * p1 + t.ey[1][i] * p2 + t.ed[1][i] >= 0;  // plane yz
      if (!row) continue;
      const __m256d n1p1 = _mm256_set1_pd(t.n[1] * p1), n2p2 = _mm256_set1_pd(t.n[2] * p2);
      __m256d xy_b[3], zx_a[3], ed_xy[3], ed_zx[3];
      for (int i = 0; i < 3; ++i) {
        xy_b[i] = _mm256_set1_pd(t.ey[0][i] * p1);
        zx_a[i] = _mm256_set1_pd(t.ex[2][i] * p2);
        ed_xy[i] = _mm256_set1_pd(t.ed[0][i]);
        ed_zx[i] = _mm256_set1_pd(t.ed[2][i]);
      }
      for (int c = 0; c < chunks; ++c) {
        if (!lane_ok[c]) continue;
        const __m256d np = _mm256_add_pd(_mm256_add_pd(n0p0[c], n1p1), n2p2);
        __m256d skip = _mm256_cmp_pd(_mm256_mul_pd(_mm256_add_pd(np, d1), _mm256_add_pd(np, d2)), zero, _CMP_GT_OQ);
        for (int i = 0; i < 3; ++i) {
          const __m256d exy = _mm256_add_pd(_mm256_add_pd(e_xy[c][i], xy_b[i]), ed_xy[i]);
          const __m256d ezx = _mm256_add_pd(_mm256_add_pd(zx_a[i], e_zx[c][i]), ed_zx[i]);
          // Inside is ">= 0" (false for NaN): a lane fails unless both compare true.
          skip = _mm256_or_pd(skip, _mm256_cmp_pd(exy, zero, _CMP_NGE_UQ));
          skip = _mm256_or_pd(skip, _mm256_cmp_pd(ezx, zero, _CMP_NGE_UQ));
        }
        out = uint8_t(out | ((~_mm256_movemask_pd(skip) & lane_ok[c]) << (4 * c)));
      }
    }
  }
}

}  // namespace rtp::voxel::detail
