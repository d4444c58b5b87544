#pragma once
// 4- and 8-lane float vectors (SSE/AVX2) with just what the kernels need. Compiled inside the ISA
// namespace of the including translation unit (trace_avx2.cpp, trace_avx512.cpp).
// min/max keep the x86 semantics the scalar reference copies: (a < b) ? a : b, second operand on NaN.
#include <immintrin.h>

#include <cstdint>

#ifndef RTP_ISA_NS
#error "define RTP_ISA_NS before including lib/trace kernel headers"
#endif

namespace rtp::RTP_ISA_NS {

struct M4 {
  __m128 v;
  uint32_t bits() const { return static_cast<uint32_t>(_mm_movemask_ps(v)); }
};
inline M4 operator&(M4 a, M4 b) { return {_mm_and_ps(a.v, b.v)}; }
inline M4 operator|(M4 a, M4 b) { return {_mm_or_ps(a.v, b.v)}; }

struct F4 {
  using Mask = M4;
  static constexpr int kLanes = 4;
  __m128 v;
  static F4 load(const float* p) { return {_mm_loadu_ps(p)}; }
  static F4 splat(float x) { return {_mm_set1_ps(x)}; }
  void store(float* p) const { _mm_storeu_ps(p, v); }
};
inline F4 operator+(F4 a, F4 b) { return {_mm_add_ps(a.v, b.v)}; }
inline F4 operator-(F4 a, F4 b) { return {_mm_sub_ps(a.v, b.v)}; }
inline F4 operator*(F4 a, F4 b) { return {_mm_mul_ps(a.v, b.v)}; }
inline F4 operator/(F4 a, F4 b) { return {_mm_div_ps(a.v, b.v)}; }
inline M4 operator<(F4 a, F4 b) { return {_mm_cmp_ps(a.v, b.v, _CMP_LT_OQ)}; }
inline M4 operator<=(F4 a, F4 b) { return {_mm_cmp_ps(a.v, b.v, _CMP_LE_OQ)}; }
inline M4 operator>=(F4 a, F4 b) { return {_mm_cmp_ps(a.v, b.v, _CMP_GE_OQ)}; }
inline M4 operator==(F4 a, F4 b) { return {_mm_cmp_ps(a.v, b.v, _CMP_EQ_OQ)}; }
inline M4 operator!=(F4 a, F4 b) { return {_mm_cmp_ps(a.v, b.v, _CMP_NEQ_OQ)}; }
inline F4 vmin(F4 a, F4 b) { return {_mm_min_ps(a.v, b.v)}; }
inline F4 vmax(F4 a, F4 b) { return {_mm_max_ps(a.v, b.v)}; }
inline F4 vabs(F4 a) { return {_mm_andnot_ps(_mm_set1_ps(-0.0f), a.v)}; }
inline F4 vselect(M4 m, F4 a, F4 b) { return {_mm_blendv_ps(b.v, a.v, m.v)}; }  // m ? a : b
// The least / greatest lane (vminps/vmaxps pairwise; lanes without NaN, as the packet set-up has).
inline float hmin(F4 a) {
  const __m128 m = _mm_min_ps(a.v, _mm_movehl_ps(a.v, a.v));
  return _mm_cvtss_f32(_mm_min_ss(m, _mm_shuffle_ps(m, m, 1)));
}
inline float hmax(F4 a) {
  const __m128 m = _mm_max_ps(a.v, _mm_movehl_ps(a.v, a.v));
  return _mm_cvtss_f32(_mm_max_ss(m, _mm_shuffle_ps(m, m, 1)));
}

struct M8 {
  __m256 v;
  uint32_t bits() const { return static_cast<uint32_t>(_mm256_movemask_ps(v)); }
};
inline M8 operator&(M8 a, M8 b) { return {_mm256_and_ps(a.v, b.v)}; }
inline M8 operator|(M8 a, M8 b) { return {_mm256_or_ps(a.v, b.v)}; }

struct F8 {
  using Mask = M8;
  using Push = void;  // no one-instruction compress: W = 16 walks push in a loop
  static constexpr int kLanes = 8;
  __m256 v;
  static F8 load(const float* p) { return {_mm256_loadu_ps(p)}; }
  static F8 splat(float x) { return {_mm256_set1_ps(x)}; }
  void store(float* p) const { _mm256_storeu_ps(p, v); }
};
inline F8 operator+(F8 a, F8 b) { return {_mm256_add_ps(a.v, b.v)}; }
inline F8 operator-(F8 a, F8 b) { return {_mm256_sub_ps(a.v, b.v)}; }
inline F8 operator*(F8 a, F8 b) { return {_mm256_mul_ps(a.v, b.v)}; }
inline F8 operator/(F8 a, F8 b) { return {_mm256_div_ps(a.v, b.v)}; }
inline M8 operator<(F8 a, F8 b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_LT_OQ)}; }
inline M8 operator<=(F8 a, F8 b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_LE_OQ)}; }
inline M8 operator>=(F8 a, F8 b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_GE_OQ)}; }
inline M8 operator==(F8 a, F8 b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_EQ_OQ)}; }
inline M8 operator!=(F8 a, F8 b) { return {_mm256_cmp_ps(a.v, b.v, _CMP_NEQ_OQ)}; }
inline F8 vmin(F8 a, F8 b) { return {_mm256_min_ps(a.v, b.v)}; }
inline F8 vmax(F8 a, F8 b) { return {_mm256_max_ps(a.v, b.v)}; }
inline F8 vabs(F8 a) { return {_mm256_andnot_ps(_mm256_set1_ps(-0.0f), a.v)}; }
inline F8 vselect(M8 m, F8 a, F8 b) { return {_mm256_blendv_ps(b.v, a.v, m.v)}; }  // m ? a : b
inline float hmin(F8 a) { return hmin(F4{_mm_min_ps(_mm256_castps256_ps128(a.v), _mm256_extractf128_ps(a.v, 1))}); }
inline float hmax(F8 a) { return hmax(F4{_mm_max_ps(_mm256_castps256_ps128(a.v), _mm256_extractf128_ps(a.v, 1))}); }

// Octant order as a byte shuffle: bit i of the result = bit (order[i] & 15) of `mask`, 0 when
// order[i] has bit 7 set (pshufb semantics, matched by ordered_mask_scalar).
template <int W>
inline uint32_t ordered_mask_sse(uint32_t mask, const uint8_t* order) {
  const __m128i spread =
      _mm_shuffle_epi8(_mm_cvtsi32_si128(static_cast<int>(mask)), _mm_setr_epi8(0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 1, 1, 1));
  const __m128i bit = _mm_setr_epi8(1, 2, 4, 8, 16, 32, 64, -128, 1, 2, 4, 8, 16, 32, 64, -128);
  const __m128i hit = _mm_cmpeq_epi8(_mm_and_si128(spread, bit), bit);
  __m128i ord;
  if constexpr (W == 4) {
    int32_t o4;
    __builtin_memcpy(&o4, order, 4);
    ord = _mm_cvtsi32_si128(o4);
  } else if constexpr (W == 8) {
    ord = _mm_loadl_epi64(reinterpret_cast<const __m128i*>(order));
  } else {
    ord = _mm_loadu_si128(reinterpret_cast<const __m128i*>(order));
  }
  const uint32_t om = static_cast<uint32_t>(_mm_movemask_epi8(_mm_shuffle_epi8(hit, ord)));
  return W == 16 ? om : om & ((1u << W) - 1u);
}

// For each 8-bit mask, its set bit positions from the highest down, padded with 0: the permutation that
// packs the marked lanes of a vector, far to near (push_ordered8).
struct PushOrder {
  uint8_t lanes[256][8];
  constexpr PushOrder() : lanes{} {
    for (int m = 0; m < 256; ++m) {
      int k = 0;
      for (int i = 7; i >= 0; --i)
        if ((m >> i) & 1) lanes[m][k++] = uint8_t(i);
    }
  }
};
inline constexpr PushOrder kPushOrder{};

// Molenaar 2019 §4.1's push of the hit children but the nearest, for W = 8 without a loop (issue 11: the
// loop ran ~8 instructions per child and its exit was a branch the predictor missed): `rest` marks
// positions in the node's octant order `order`; their (child, entry distance) pairs are written to
// `dst` from the farthest to the nearest, exactly as the loop pushed them, plus garbage up to 8 pairs
// (dst has room for 8). `dist` is the box test's per-lane entry distances.
// The node lanes of the positions marked in `rest` (of the octant order `order`), far to near.
RTP_KERNEL_INLINE __m256i pushed_lanes8(const uint8_t* order, uint32_t rest) {
  const __m256i ord =
      _mm256_and_si256(_mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(order))), _mm256_set1_epi32(15));
  const __m256i pick = _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(kPushOrder.lanes[rest & 0xFF])));
  return _mm256_permutevar8x32_epi32(ord, pick);
}

RTP_KERNEL_INLINE void push_ordered8(void* dst, const uint32_t* child, const float* dist, const uint8_t* order, uint32_t rest) {
  const __m256i lanes = pushed_lanes8(order, rest);
  const __m256i refs = _mm256_permutevar8x32_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(child)), lanes);
  const __m256i ds = _mm256_permutevar8x32_epi32(_mm256_castps_si256(_mm256_loadu_ps(dist)), lanes);
  const __m256i lo = _mm256_unpacklo_epi32(refs, ds), hi = _mm256_unpackhi_epi32(refs, ds);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(dst), _mm256_permute2x128_si256(lo, hi, 0x20));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(dst) + 1, _mm256_permute2x128_si256(lo, hi, 0x31));
}

// The same push for a walk whose stack keeps references only (walk_octant_stack's kFixedFar): the
// children far to near, plus garbage up to 8 references (dst has room for 8).
RTP_KERNEL_INLINE void push_ordered8_refs(uint32_t* dst, const uint32_t* child, const uint8_t* order, uint32_t rest) {
  const __m256i lanes = pushed_lanes8(order, rest);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(dst),
                      _mm256_permutevar8x32_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(child)), lanes));
}

}  // namespace rtp::RTP_ISA_NS
