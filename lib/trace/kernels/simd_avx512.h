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

struct Push16;
struct F16 {
  using Mask = M16;
  using Push = Push16;  // W = 16 walks push with it (kernels_simd.h)
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
// Molenaar 2019 §4.1's push of the hit children but the nearest, for W = 16 without a loop (issue 11: the
// loop runs ~8 instructions per child and its exit is a branch the predictor misses; AVX-512 packs the
// marked lanes with one compress): `rest` marks positions in the node's octant order `order`; their
// (child, entry distance) pairs are written to `dst` from the farthest to the nearest, exactly as the
// loop pushes them, plus garbage up to 16 pairs (dst has room for 16). `dist`: the box test's distances.
// (Any-hit walks, whose stack keeps references only, push in the loop: a compress there measured the same.)
struct Push16 {
  // (The all-ones maskz forms: GCC 12's unmasked ones read an "undefined" register, see vmin.)
  static void pairs(void* dst, const uint32_t* child, const float* dist, const uint8_t* order, uint32_t rest) {
    // The node lane of each octant position, then the marked positions' children and distances, near to
    // far, in lanes 0..k-1 (k = popcount(rest)).
    const __m128i ord = _mm_loadu_si128(reinterpret_cast<const __m128i*>(order));
    const __m512i lanes = _mm512_and_si512(_mm512_maskz_cvtepu8_epi32(0xFFFF, ord), _mm512_set1_epi32(15));
    const __mmask16 m = static_cast<__mmask16>(rest);
    const __m512i refs = _mm512_maskz_compress_epi32(m, _mm512_maskz_permutexvar_epi32(0xFFFF, lanes, _mm512_loadu_si512(child)));
    const __m512i ds = _mm512_maskz_compress_epi32(m, _mm512_maskz_permutexvar_epi32(0xFFFF, lanes, _mm512_loadu_si512(dist)));
    // Pair j (j < k) is (refs[k-1-j], ds[k-1-j]): one two-source permutation per 8 pairs reverses and
    // interleaves (index k-1-j picks refs, 16 + k-1-j picks ds; lanes past k get garbage).
    const __m512i last = _mm512_set1_epi32(static_cast<int>(__builtin_popcount(rest)) - 1);
    const __m512i lo = _mm512_add_epi32(last, _mm512_setr_epi32(0, 16, -1, 15, -2, 14, -3, 13, -4, 12, -5, 11, -6, 10, -7, 9));
    const __m512i hi = _mm512_add_epi32(last, _mm512_setr_epi32(-8, 8, -9, 7, -10, 6, -11, 5, -12, 4, -13, 3, -14, 2, -15, 1));
    _mm512_storeu_si512(dst, _mm512_permutex2var_epi32(refs, lo, ds));
    _mm512_storeu_si512(static_cast<char*>(dst) + 64, _mm512_permutex2var_epi32(refs, hi, ds));
  }
};

inline F16 vabs(F16 a) {
  return {_mm512_castsi512_ps(_mm512_and_si512(_mm512_castps_si512(a.v), _mm512_set1_epi32(0x7FFFFFFF)))};
}

}  // namespace rtp::RTP_ISA_NS
