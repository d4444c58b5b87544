#pragma once
// 16-lane float vector (AVX-512F) with the interface of simd_avx2.h; masks are k-registers.
// Compiled only in trace_avx512.cpp.
#include <immintrin.h>

#include <cstdint>

#ifndef RTP_ISA_NS
#error "define RTP_ISA_NS before including lib/trace kernel headers"
#endif

namespace rtp::RTP_ISA_NS {

struct M16 {
  __mmask16 k;
  uint32_t bits() const { return static_cast<uint32_t>(k); }
};
inline M16 operator&(M16 a, M16 b) { return {static_cast<__mmask16>(a.k & b.k)}; }
inline M16 operator|(M16 a, M16 b) { return {static_cast<__mmask16>(a.k | b.k)}; }

struct F16 {
  using Mask = M16;
  static constexpr int kLanes = 16;
  __m512 v;
  static F16 load(const float* p) { return {_mm512_loadu_ps(p)}; }
  static F16 splat(float x) { return {_mm512_set1_ps(x)}; }
  void store(float* p) const { _mm512_storeu_ps(p, v); }
};
inline F16 operator+(F16 a, F16 b) { return {_mm512_add_ps(a.v, b.v)}; }
inline F16 operator-(F16 a, F16 b) { return {_mm512_sub_ps(a.v, b.v)}; }
inline F16 operator*(F16 a, F16 b) { return {_mm512_mul_ps(a.v, b.v)}; }
inline F16 operator/(F16 a, F16 b) { return {_mm512_div_ps(a.v, b.v)}; }
inline M16 operator<(F16 a, F16 b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_LT_OQ)}; }
inline M16 operator<=(F16 a, F16 b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_LE_OQ)}; }
inline M16 operator>=(F16 a, F16 b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_GE_OQ)}; }
inline M16 operator==(F16 a, F16 b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_EQ_OQ)}; }
inline M16 operator!=(F16 a, F16 b) { return {_mm512_cmp_ps_mask(a.v, b.v, _CMP_NEQ_OQ)}; }
// vminps/vmaxps: (a < b) ? a : b and (a > b) ? a : b, the second operand on NaN, as in AVX2.
// The all-ones maskz forms are the same instruction; GCC 12's unmasked forms read an "undefined"
// register that -Wuninitialized reports under the fp-contract pragma.
inline F16 vmin(F16 a, F16 b) { return {_mm512_maskz_min_ps(0xFFFF, a.v, b.v)}; }
inline F16 vmax(F16 a, F16 b) { return {_mm512_maskz_max_ps(0xFFFF, a.v, b.v)}; }
inline F16 vselect(M16 m, F16 a, F16 b) { return {_mm512_mask_blend_ps(m.k, b.v, a.v)}; }  // m ? a : b
// The two 8-lane halves by the zero-masked extract with all lanes kept (as vmin/vmax: GCC 12's
// unmasked extract, which _mm512_castps512_ps256 also uses, reads an "undefined" register that
// -Wmaybe-uninitialized reports). AVX-512DQ, which this ISA requires.
inline __m256 lower_half(__m512 v) { return _mm512_maskz_extractf32x8_ps(0xFF, v, 0); }
inline __m256 upper_half(__m512 v) { return _mm512_maskz_extractf32x8_ps(0xFF, v, 1); }
inline float hmin(F16 a) { return hmin(F8{_mm256_min_ps(lower_half(a.v), upper_half(a.v))}); }
inline float hmax(F16 a) { return hmax(F8{_mm256_max_ps(lower_half(a.v), upper_half(a.v))}); }
inline F16 vabs(F16 a) {
  return {_mm512_castsi512_ps(_mm512_and_si512(_mm512_castps_si512(a.v), _mm512_set1_epi32(0x7FFFFFFF)))};
}

}  // namespace rtp::RTP_ISA_NS
